//! Steps 3-5 of the segmentation: each boundary between two runs placed by maximum
//! likelihood, then each step's frequency and settled part (see the module docs of `segment`).

use std::f64::consts::PI;

use super::sine_fit::{SineFit, fit_from};
use super::windows::{Analysis, Class, ROUNDING_REL, Run, middle, run_omega, windows_agree};
use super::{DetectedKind, DetectedStep, SegmentOptions, decimals, roundest_in};
use crate::parallel;

/// Gauss-Newton iterations of the model fits and the final frequency fits.
const FIT_ITERATIONS: usize = 50;
/// A model is fitted on at most this many windows of its run next to the boundary (the
/// sine is extrapolated over the stretch between runs only; nearby samples fit it best).
const MODEL_WINDOWS: usize = 4;
/// The frequency snaps only when its tolerance is below this fraction of it.
const SNAP_MAX_REL: f64 = 1e-3;
/// A step's tail is cut where its periods leave this many times the cleanness limit of the
/// step's sine (a taper), never for noise.
const TAIL_RESIDUAL_FACTOR: f64 = 3.0;
/// The end of a tapered step is looked for in this fraction of a period.
const TAIL_HOPS_PER_PERIOD: f64 = 16.0;
/// Floor of a model's noise variance, relative to the series' largest magnitude squared:
/// noise-free data still have a finite likelihood.
const VARIANCE_FLOOR_REL: f64 = 1e-28;

/// What one side of a boundary looks like.
enum Model {
    Sine { fit: SineFit, var: f64 },
    Level { mean: f64, var: f64 },
}

impl Model {
    /// Negative log-likelihood of sample `x` at index `n` (up to a constant).
    fn nll(&self, n: usize, x: f64) -> f64 {
        match self {
            Model::Sine { fit, var } => {
                (x - fit.eval(n as f64)).powi(2) / (2.0 * var) + 0.5 * var.ln()
            }
            Model::Level { mean, var } => (x - mean).powi(2) / (2.0 * var) + 0.5 * var.ln(),
        }
    }
}

/// Two sines share the drive's noise: one variance for both (their own estimates differ by
/// chance, and the difference of their log-variances would tilt the likelihood).
fn pool_noise(a: &mut Model, b: &mut Model) {
    if let (Model::Sine { fit: fa, var: va }, Model::Sine { fit: fb, var: vb }) = (&mut *a, &mut *b)
    {
        let (na, nb) = (fa.samples as f64, fb.samples as f64);
        let pooled = (*va * na + *vb * nb) / (na + nb);
        *va = pooled;
        *vb = pooled;
    }
}

/// A boundary: the start of the next step and its likelihood interval.
struct Boundary {
    at: usize,
    lo: usize,
    hi: usize,
    /// Both sides are sines and, changing at `at`, they leave no more than noise over the
    /// stretch searched (see [`Ctx::explains`]).
    explained: bool,
}

struct Ctx<'a> {
    x: &'a [f64],
    fs: f64,
    t0: f64,
    analysis: &'a Analysis,
    options: &'a SegmentOptions,
    var_floor: f64,
}

impl Ctx<'_> {
    /// The RMS below which a stretch is at rest: `rest_fraction` of the largest window's.
    fn rest_rms(&self) -> f64 {
        let largest = self
            .analysis
            .windows
            .iter()
            .filter_map(|w| w.fit.map(|f| f.total_rms))
            .fold(0.0, f64::max);
        self.options.rest_fraction * largest
    }

    fn model(&self, run: &Run, from: usize, to: usize) -> Model {
        let (from, to) = if to >= from + 8 {
            (from, to)
        } else {
            // Too little next to the boundary: the whole run.
            let w = &self.analysis.windows;
            (w[run.first].start, w[run.last].start + self.analysis.window)
        };
        let seg = &self.x[from..to];
        if run.class == Class::Sine
            && let Some(omega) = run_omega(self.analysis, run)
            && let Some(fit) = fit_from(seg, from, omega, FIT_ITERATIONS)
        {
            return Model::Sine {
                fit,
                var: fit.residual_rms.powi(2).max(self.var_floor),
            };
        }
        let mean = seg.iter().sum::<f64>() / seg.len() as f64;
        let var = seg.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / seg.len() as f64;
        Model::Level {
            mean,
            var: var.max(self.var_floor),
        }
    }

    /// The boundary between runs `a` and `b` (`a` before `b`).
    fn boundary(&self, a: &Run, b: &Run, a_is_first: bool, b_is_last: bool) -> Boundary {
        let (w, len) = (&self.analysis.windows, self.analysis.window);
        let half = len / 2;
        let n = self.x.len();
        // A sine window is in its step up to a few samples; a rest or broadband window may
        // hold much of a sine step (it is classed by its variance), so the search spans it.
        let lo = (w[a.last].start + if a.class == Class::Sine { half } else { 0 }).min(n);
        let hi = (w[b.first].start + if b.class == Class::Sine { half } else { len }).clamp(lo, n);
        let a_from = if a_is_first {
            w[a.first].start
        } else {
            w[a.first].start + half
        };
        let a_from = a_from.max(lo.saturating_sub(MODEL_WINDOWS * len)).min(lo);
        // The last run's model ends with its last window, not the series: windows after it
        // that form no run (a change too recent to show) are not its step's.
        let b_to = if b_is_last {
            w[b.last].start + len
        } else {
            w[b.last].start + half
        };
        let b_to = b_to.min(hi + MODEL_WINDOWS * len).max(hi);
        let (mut ma, mut mb) = (self.model(a, a_from, lo), self.model(b, hi, b_to));
        pool_noise(&mut ma, &mut mb);
        // cost[j]: the change at lo + j (samples lo..lo+j under a, the rest under b).
        let mut cost = Vec::with_capacity(hi - lo + 1);
        let tail_b: f64 = (lo..hi).map(|i| mb.nll(i, self.x[i])).sum();
        let mut c = tail_b;
        cost.push(c);
        for i in lo..hi {
            c += ma.nll(i, self.x[i]) - mb.nll(i, self.x[i]);
            cost.push(c);
        }
        let (best, &min) = cost
            .iter()
            .enumerate()
            .min_by(|p, q| p.1.total_cmp(q.1))
            .unwrap_or((0, &0.0));
        let near: Vec<usize> = (0..cost.len())
            .filter(|&j| cost[j] - min <= self.options.boundary_interval_nll)
            .collect();
        let (first, last) = (
            near.first().copied().unwrap_or(best),
            near.last().copied().unwrap_or(best),
        );
        let at = if self.options.snap {
            // The roundest time among the likely samples; the likeliest of equally round ones.
            near.iter()
                .copied()
                .min_by(|&p, &q| {
                    let (tp, tq) = (self.time(lo + p), self.time(lo + q));
                    decimals(tp)
                        .cmp(&decimals(tq))
                        .then(cost[p].total_cmp(&cost[q]))
                })
                .unwrap_or(best)
        } else {
            best
        };
        let at = lo + at;
        Boundary {
            at,
            lo: lo + first,
            hi: lo + last,
            explained: self.explains(&ma, &mb, lo, at, hi),
        }
    }

    /// Two sines changing at `at` explain `lo..hi`: their residual RMS there is within the
    /// cleanness factor of the noise (their pooled residual, or a rounding floor).
    fn explains(&self, a: &Model, b: &Model, lo: usize, at: usize, hi: usize) -> bool {
        let (Model::Sine { fit: fa, var }, Model::Sine { fit: fb, .. }) = (a, b) else {
            return false;
        };
        if hi <= lo {
            return true;
        }
        let ss: f64 = (lo..at)
            .map(|i| (self.x[i] - fa.eval(i as f64)).powi(2))
            .chain((at..hi).map(|i| (self.x[i] - fb.eval(i as f64)).powi(2)))
            .sum();
        let rms = (ss / (hi - lo) as f64).sqrt();
        let floor = ROUNDING_REL * fa.amplitude().max(fb.amplitude());
        rms <= (self.options.clean_residual_factor * var.sqrt()).max(floor)
    }

    /// `runs` less the broadband runs that only straddle a change between two sines: windows
    /// across a large change of amplitude or frequency leave most of their variance to one
    /// sine and are classed broadband, and three of them make a run. Such a run is dropped
    /// when the sines either side, changing at one sample, explain the stretch between them;
    /// sines that then agree are one step.
    fn drop_straddles(&self, mut runs: Vec<Run>) -> Vec<Run> {
        let mut i = 1;
        while i + 1 < runs.len() {
            let (a, m, b) = (runs[i - 1], runs[i], runs[i + 1]);
            let straddle = a.class == Class::Sine
                && m.class == Class::Broadband
                && b.class == Class::Sine
                && self.boundary(&a, &b, i == 1, i + 2 == runs.len()).explained;
            if !straddle {
                i += 1;
                continue;
            }
            runs.remove(i);
            if windows_agree(
                self.analysis,
                middle(&a),
                middle(&b),
                self.options.consistency_sigmas,
            ) {
                runs[i - 1].last = b.last;
                runs.remove(i);
            }
        }
        runs
    }

    fn time(&self, i: usize) -> f64 {
        self.t0 + i as f64 / self.fs
    }

    /// The step of run `r` over `start..end`; `guard` samples at each end are left out of the
    /// frequency fit (the boundaries' uncertainty).
    fn step(
        &self,
        r: &Run,
        start: usize,
        end: usize,
        guard: (usize, usize),
        start_interval: (usize, usize),
    ) -> DetectedStep {
        let seg = &self.x[start..end];
        let mean = seg.iter().sum::<f64>() / seg.len().max(1) as f64;
        let rms =
            (seg.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / seg.len().max(1) as f64).sqrt();
        let mut settled_start = start;
        let mut settled_end = end;
        let kind = match r.class {
            Class::Sine => {
                let (from, to) = if end > start + guard.0 + guard.1 + 8 {
                    (start + guard.0, end - guard.1)
                } else {
                    (start, end)
                };
                let omega0 = run_omega(self.analysis, r)
                    .or_else(|| self.analysis.windows[middle(r)].fit.map(|f| f.omega));
                let first =
                    omega0.and_then(|w| fit_from(&self.x[from..to], from, w, FIT_ITERATIONS));
                // The frequency from the settled part: a start-up transient (a machine ramping
                // up from rest) left in the fit pulls it.
                settled_end = self.settled_end(r, start, end);
                let fit = first.and_then(|fit| {
                    settled_start = self.settled(&fit, start, settled_end);
                    let to = to.min(settled_end);
                    if (settled_start > from || settled_end < end) && to > settled_start + 8 {
                        fit_from(
                            &self.x[settled_start..to],
                            settled_start,
                            fit.omega,
                            FIT_ITERATIONS,
                        )
                        .or(Some(fit))
                    } else {
                        Some(fit)
                    }
                });
                match fit {
                    Some(fit) => {
                        let f = fit.frequency_hz(self.fs);
                        let std = fit.omega_std * self.fs / (2.0 * PI);
                        let tol = self.options.snap_sigmas * std + 1e-12 * f;
                        // Snapping needs an estimate worth the name (not one from a handful
                        // of samples or a singular fit).
                        let frequency_hz = if self.options.snap && tol < SNAP_MAX_REL * f {
                            roundest_in(f - tol, f + tol, f)
                        } else {
                            f
                        };
                        DetectedKind::Sine {
                            frequency_hz,
                            estimated_frequency_hz: f,
                            frequency_std_hz: std,
                            amplitude: fit.amplitude(),
                        }
                    }
                    None => DetectedKind::Broadband { rms },
                }
            }
            Class::Rest => DetectedKind::Rest { rms },
            // A stretch between windows that barely moves (a machine standing still before it
            // starts, a quantised sensor reading one value) is rest, whatever its windows said.
            Class::Broadband | Class::Transition if rms <= self.rest_rms() => {
                DetectedKind::Rest { rms }
            }
            Class::Broadband | Class::Transition => DetectedKind::Broadband { rms },
        };
        DetectedStep {
            start,
            end,
            settled_start,
            settled_end,
            start_interval,
            kind,
        }
    }

    /// The end of the step's steady part: where a period-long stretch before it stops being far
    /// off the sine of the run's last window (the steady state nearest the end). A test that
    /// ramps its amplitude down at its end (a test machine's taper) ends there; only a stretch
    /// far off (residual above `TAIL_RESIDUAL_FACTOR` times the cleanness limit of that
    /// window's own residual) is cut, so that noise never shortens a step.
    fn settled_end(&self, r: &Run, start: usize, end: usize) -> usize {
        let Some(reference) = self.analysis.windows[r.last].fit else {
            return end;
        };
        let period = 2.0 * PI / reference.omega;
        let limit = TAIL_RESIDUAL_FACTOR
            * self.options.clean_residual_factor
            * reference.residual_rms.max(self.var_floor.sqrt());
        let width = period.ceil() as usize;
        let hop = ((period / TAIL_HOPS_PER_PERIOD) as usize).max(1);
        let mut b = end;
        while b >= start + 2 * width {
            let rms = ((b - width..b)
                .map(|i| (self.x[i] - reference.eval(i as f64)).powi(2))
                .sum::<f64>()
                / width as f64)
                .sqrt();
            if rms <= limit {
                return b;
            }
            b -= hop;
        }
        end
    }

    /// The first whole period from `start` whose residual against `fit` is within the
    /// cleanness factor of the fit's residual.
    fn settled(&self, fit: &SineFit, start: usize, end: usize) -> usize {
        let period = 2.0 * PI / fit.omega;
        let limit =
            self.options.clean_residual_factor * fit.residual_rms.max(self.var_floor.sqrt());
        let mut p = 0usize;
        loop {
            let a = start + (p as f64 * period).ceil() as usize;
            let b = start + ((p + 1) as f64 * period).ceil() as usize;
            if b > end || a >= b {
                return start;
            }
            let rms = ((a..b)
                .map(|i| (self.x[i] - fit.eval(i as f64)).powi(2))
                .sum::<f64>()
                / (b - a) as f64)
                .sqrt();
            if rms <= limit {
                return a;
            }
            p += 1;
        }
    }
}

/// The steps of `x` from its runs: one per run, boundaries between them.
pub(super) fn steps(
    x: &[f64],
    fs: f64,
    t0: f64,
    analysis: &Analysis,
    runs: &[Run],
    options: &SegmentOptions,
) -> Vec<DetectedStep> {
    let scale = x.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let ctx = Ctx {
        x,
        fs,
        t0,
        analysis,
        options,
        var_floor: (VARIANCE_FLOOR_REL * scale * scale).max(f64::MIN_POSITIVE),
    };
    if runs.is_empty() {
        // Nothing steady anywhere: one step of what the series is.
        let whole = Run {
            class: Class::Broadband,
            first: 0,
            last: analysis.windows.len().saturating_sub(1),
        };
        return vec![ctx.step(&whole, 0, x.len(), (0, 0), (0, 0))];
    }
    let runs = ctx.drop_straddles(runs.to_vec());
    let last = runs.len() - 1;
    // Each boundary and each step is fitted on its own: a long series' are split over the
    // cores (the fits of one loop, in order).
    let indices: Vec<usize> = (0..runs.len()).collect();
    let min_part = parallel::min_part_of(x.len(), runs.len());
    let mut bounds: Vec<Boundary> = parallel::in_parts(&indices[..last], min_part, |part| {
        part.iter()
            .map(|&i| ctx.boundary(&runs[i], &runs[i + 1], i == 0, i + 1 == last))
            .collect()
    });
    // Steps do not overlap: a boundary is never before the previous one.
    for i in 1..bounds.len() {
        let prev = bounds[i - 1].at;
        let b = &mut bounds[i];
        b.at = b.at.max(prev);
        b.lo = b.lo.max(prev);
        b.hi = b.hi.max(b.at);
    }
    let step = |i: usize| {
        let r = &runs[i];
        let start = if i == 0 { 0 } else { bounds[i - 1].at };
        let end = if i == last { x.len() } else { bounds[i].at };
        let guard_start = if i == 0 {
            0
        } else {
            bounds[i - 1].hi - start + 1
        };
        let guard_end = if i == last { 0 } else { end - bounds[i].lo + 1 };
        let interval = if i == 0 {
            (0, 0)
        } else {
            (bounds[i - 1].lo, bounds[i - 1].hi)
        };
        ctx.step(r, start, end.max(start), (guard_start, guard_end), interval)
    };
    parallel::in_parts(&indices, min_part, |part| {
        part.iter().map(|&i| step(i)).collect()
    })
}
