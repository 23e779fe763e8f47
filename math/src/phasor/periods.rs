//! The per-period fits of a record and what is made of them: the noise level of the tail, the
//! settling walk, the joint fit over the used periods and the noise of its phasors (steps 2-5
//! of the method in the module docs). The batch analysis fits periods on demand from the
//! samples; the stream ([`super::stream`]) hands over the periods it fitted as they completed.

use super::fit::{self, Factor, FactorCache, Grid, phasors_of, rhs_matrix};
use super::{ChannelPhasors, HarmonicAnalysis, PhasorError, PhasorOptions};
use crate::record::Channel;
use num_complex::Complex64;

/// Per-period sums and fits of one record, computed on demand (the settling walk runs from
/// the end of the record and stops at the transient, so the transient periods are never fitted).
#[derive(Clone)]
pub(super) struct Periods<'a> {
    grid: Grid,
    /// The samples of each channel; empty when every period was fitted already (a stream).
    data: &'a [&'a [f64]],
    n_channels: usize,
    bounds: Vec<usize>,
    step: usize,
    cache: FactorCache,
    /// Per period: `X_n` sums (re, im; `[channel * (N+1) + n]`), `sum x^2` per channel, and
    /// the per-period phasors `[channel][n]`.
    done: Vec<Option<PeriodFit>>,
    /// Cholesky factors of joint windows (start, length), exact keys: the same window gives
    /// the same factor whether it was computed ahead ([`Periods::prefetch_joint`]) or now.
    joint_factors: Vec<(usize, usize, Factor)>,
}

/// Joint-window factors kept (each `(2N + 1)^2` twice: ~0.6 MB at N = 100).
const KEEP_JOINT_FACTORS: usize = 6;

#[derive(Clone)]
pub(super) struct PeriodFit {
    pub re: Vec<f64>,
    pub im: Vec<f64>,
    pub sumsq: Vec<f64>,
    pub phasors: Vec<Vec<Complex64>>,
}

impl PeriodFit {
    /// The per-period fit from the sums `X_n` (re, im) and `sum x^2` of each channel over one
    /// whole period `start..start + len` (the least-squares solution with `cache`'s factor).
    pub fn solve(
        grid: &Grid,
        cache: &mut FactorCache,
        step: usize,
        start: usize,
        len: usize,
        (re, im, sumsq): (Vec<f64>, Vec<f64>, Vec<f64>),
    ) -> Result<PeriodFit, PhasorError> {
        let nc = sumsq.len();
        let chol = cache
            .get(grid, start, len)
            .ok_or(PhasorError::IllConditioned { step, samples: len })?;
        let mut beta = rhs_matrix(grid.harmonics, nc, &re, &im);
        chol.solve(&mut beta);
        let phasors = (0..nc)
            .map(|c| phasors_of(&beta, c, grid.harmonics))
            .collect();
        Ok(PeriodFit {
            re,
            im,
            sumsq,
            phasors,
        })
    }
}

impl<'a> Periods<'a> {
    /// Periods `bounds[p]..bounds[p + 1]` of `data`, fitted on demand.
    pub fn new(grid: Grid, data: &'a [&'a [f64]], bounds: Vec<usize>, step: usize) -> Self {
        let n = bounds.len() - 1;
        Periods {
            grid,
            data,
            n_channels: data.len(),
            bounds,
            step,
            cache: FactorCache::new(),
            done: (0..n).map(|_| None).collect(),
            joint_factors: Vec::new(),
        }
    }

    /// No periods yet; a stream appends them with [`Periods::push_period`] as they complete.
    pub fn streamed(grid: Grid, n_channels: usize, step: usize) -> Periods<'static> {
        Periods {
            grid,
            data: &[],
            n_channels,
            bounds: vec![0],
            step,
            cache: FactorCache::new(),
            done: Vec::new(),
            joint_factors: Vec::new(),
        }
    }

    /// Fits the period from the last boundary to `end` from its sums and appends it. The
    /// diagonal of its factor's inverse (the noise of the last period's phasors, step 2) is
    /// computed now, once per kind of period, rather than after the step's last sample.
    pub fn push_period(
        &mut self,
        end: usize,
        sums: (Vec<f64>, Vec<f64>, Vec<f64>),
    ) -> Result<(), PhasorError> {
        let start = self.bounds[self.bounds.len() - 1];
        let f = PeriodFit::solve(
            &self.grid,
            &mut self.cache,
            self.step,
            start,
            end - start,
            sums,
        )?;
        self.cache.inverse_diagonal(&self.grid, start, end - start);
        self.bounds.push(end);
        self.done.push(Some(f));
        Ok(())
    }

    /// Periods held.
    pub fn count(&self) -> usize {
        self.done.len()
    }

    /// First sample of period `p` (`p = count()` gives the end of the last).
    pub fn bound(&self, p: usize) -> usize {
        self.bounds[p]
    }

    /// Keeps the first `periods` periods.
    pub fn truncate(&mut self, periods: usize) {
        self.done.truncate(periods);
        self.bounds.truncate(periods + 1);
    }

    /// The factor of the joint window `start..start + len`, computed now or found.
    fn joint_factor(&mut self, start: usize, len: usize) -> Result<&Factor, PhasorError> {
        let i = match self
            .joint_factors
            .iter()
            .position(|(s, l, _)| *s == start && *l == len)
        {
            Some(i) => i,
            None => {
                let f = Factor::new(&self.grid.normal_matrix(start, len), self.grid.params())
                    .ok_or(PhasorError::IllConditioned {
                        step: self.step,
                        samples: len,
                    })?;
                if self.joint_factors.len() >= KEEP_JOINT_FACTORS {
                    self.joint_factors.remove(0);
                }
                self.joint_factors.push((start, len, f));
                self.joint_factors.len() - 1
            }
        };
        Ok(&self.joint_factors[i].2)
    }

    /// Computes the factor of a joint window ahead of its use (`O(N^3)`, data-independent).
    pub fn prefetch_joint(&mut self, start: usize, len: usize) {
        // An ill-conditioned window fails again, with its error, when it is used.
        let _ = self.joint_factor(start, len);
    }

    fn fit(&mut self, p: usize) -> Result<&PeriodFit, PhasorError> {
        if self.done[p].is_none() {
            let (h, nc) = (self.grid.harmonics + 1, self.n_channels);
            let (start, end) = (self.bounds[p], self.bounds[p + 1]);
            let (mut re, mut im, mut sumsq) = (vec![0.0; nc * h], vec![0.0; nc * h], vec![0.0; nc]);
            self.grid
                .accumulate(self.data, start..end, &mut re, &mut im, &mut sumsq);
            let f = PeriodFit::solve(
                &self.grid,
                &mut self.cache,
                self.step,
                start,
                end - start,
                (re, im, sumsq),
            )?;
            self.done[p] = Some(f);
        }
        Ok(self.done[p].as_ref().expect("just computed"))
    }

    fn phasors(&mut self, p: usize) -> Result<&[Vec<Complex64>], PhasorError> {
        Ok(&self.fit(p)?.phasors)
    }

    /// `v_n`: complex variance of a per-period phasor per unit sample variance (diagonal of
    /// the inverse normal matrix of period `p`, `a_n` and `b_n` added).
    fn per_period_variance_factors(&mut self, p: usize) -> Result<Vec<f64>, PhasorError> {
        let (start, len) = (self.bounds[p], self.bounds[p + 1] - self.bounds[p]);
        let d = self.cache.inverse_diagonal(&self.grid, start, len).ok_or(
            PhasorError::IllConditioned {
                step: self.step,
                samples: len,
            },
        )?;
        Ok((0..=self.grid.harmonics)
            .map(|n| {
                if n == 0 {
                    d[0]
                } else {
                    d[fit::idx_a(n)] + d[fit::idx_b(n)]
                }
            })
            .collect())
    }

    /// Joint fit over whole periods `first..end`: the solution (channel-major) and the
    /// residual variance per sample of each channel, `RSS / (samples - (2N+1))`.
    fn joint(&mut self, first: usize, end: usize) -> Result<(Vec<f64>, Vec<f64>), PhasorError> {
        let periods = end;
        let (h, nc) = (self.grid.harmonics + 1, self.n_channels);
        let (mut re, mut im, mut sq) = (vec![0.0; nc * h], vec![0.0; nc * h], vec![0.0; nc]);
        for p in first..periods {
            let f = self.fit(p)?;
            re.iter_mut().zip(&f.re).for_each(|(a, b)| *a += b);
            im.iter_mut().zip(&f.im).for_each(|(a, b)| *a += b);
            sq.iter_mut().zip(&f.sumsq).for_each(|(a, b)| *a += b);
        }
        let (start, n) = (
            self.bounds[first],
            self.bounds[periods] - self.bounds[first],
        );
        let params = self.grid.params();
        let rhs = rhs_matrix(self.grid.harmonics, nc, &re, &im);
        let mut beta = rhs.clone();
        self.joint_factor(start, n)?.solve(&mut beta);
        let dof = n.saturating_sub(params).max(1) as f64;
        // RSS = sum x^2 - beta . rhs at the least-squares solution.
        let var = (0..nc)
            .map(|c| {
                let r = c * params..(c + 1) * params;
                let fitted: f64 = beta[r.clone()]
                    .iter()
                    .zip(&rhs[r])
                    .map(|(b, r)| b * r)
                    .sum();
                (sq[c] - fitted).max(0.0) / dof
            })
            .collect();
        Ok((beta, var))
    }
}

/// What the settling and the joint fit need to know of the record besides its periods.
pub(super) struct StepInfo<'a> {
    pub step: usize,
    pub frequency_hz: f64,
    pub amplitude: f64,
    pub start_time_s: f64,
    pub channels: &'a [Channel],
    pub harmonic_cap: usize,
}

/// Steps 2-5 of the method (module docs) over the whole periods of `work`: the tail's noise
/// level, the settling walk, the joint fit of the used periods and their noise.
pub(super) fn settle_and_fit(
    work: &mut Periods<'_>,
    info: &StepInfo<'_>,
    options: &PhasorOptions,
) -> Result<HarmonicAnalysis, PhasorError> {
    let StepInfo {
        step,
        frequency_hz,
        amplitude,
        start_time_s,
        channels: record_channels,
        harmonic_cap: cap,
    } = *info;
    let harmonics = work.grid.harmonics;
    let periods = work.done.len();
    let h = harmonics + 1;
    let n_ch = work.n_channels;

    // 2-3. The settled part: the walk from the last period. Where it finds none and the
    // record ends in periods that are not steady (a bench that ramps its drive down before it
    // stops), the walk from the last period before them; where that finds none either, the
    // periods it accepts within `UNSETTLED_RELATIVE_TOLERANCE` (a drift, as a damper's force
    // as it heats up, changes from period to period by more than the noise of a period).
    let min_periods = options.min_periods.max(2);
    let tol = options.settle_relative_tolerance;
    let walked = |work: &mut Periods<'_>, end: usize, tol: f64| {
        walk(work, end, n_ch, h, options, tol).map(|w| {
            (w.accepted >= min_periods)
                .then_some((w.first, end))
                .ok_or(w)
        })
    };
    let mut settled_part = None;
    let mut steadiest = None;
    match walked(work, periods, tol)? {
        Ok(part) => settled_part = Some(part),
        Err(stopped) => {
            let ramp = trailing_ramp(work, periods, n_ch, h, options)?;
            let end = periods - ramp;
            let stopped = if ramp > 0 {
                match walked(work, end, tol)? {
                    Ok(part) => {
                        settled_part = Some(part);
                        None
                    }
                    Err(stopped) => Some(stopped),
                }
            } else {
                Some(stopped)
            };
            if stopped.is_some() {
                steadiest = walked(work, end, tol.max(UNSETTLED_RELATIVE_TOLERANCE))?.ok();
            }
        }
    }
    let settled = settled_part.is_some();
    let (first_used, end_used) = settled_part
        .or(steadiest)
        .unwrap_or((periods - min_periods.min(periods), periods));

    // 4. Joint fit over the used periods; 5. standard error from the per-period scatter.
    let used = end_used - first_used;
    let (beta, var) = work.joint(first_used, end_used)?;
    let mut channels = Vec::with_capacity(n_ch);
    for (c, channel) in record_channels.iter().enumerate() {
        let mut noise_std = Vec::with_capacity(h);
        for n in 0..h {
            let mut mean = Complex64::new(0.0, 0.0);
            for p in first_used..end_used {
                mean += work.phasors(p)?[c][n];
            }
            mean /= used as f64;
            let mut ss = 0.0;
            for p in first_used..end_used {
                ss += (work.phasors(p)?[c][n] - mean).norm_sqr();
            }
            noise_std.push((ss / (used * (used - 1)) as f64).sqrt());
        }
        channels.push(ChannelPhasors {
            channel: *channel,
            phasors: phasors_of(&beta, c, harmonics),
            noise_std,
            residual_rms: var[c].sqrt(),
            rate_per_s: Vec::new(),
        });
    }
    let bounds = &work.bounds;

    Ok(HarmonicAnalysis {
        step,
        frequency_hz,
        amplitude,
        t_ref_s: start_time_s + first_used as f64 / frequency_hz,
        periods_used: used,
        periods_available: periods,
        first_settled_sample: bounds[first_used],
        samples_used: bounds[end_used] - bounds[first_used],
        settled,
        harmonics,
        harmonic_cap: cap,
        channels,
        frequency_rate_hz_per_s: 0.0,
    })
}

/// Relative tolerance of a ramp's periods and of the periods used when none are settled
/// (module docs, step 3).
pub(super) const UNSETTLED_RELATIVE_TOLERANCE: f64 = 0.05;

/// The periods at the end of the record that are a ramp: from the last, each that differs
/// from the `min_periods` periods before it by more than `UNSETTLED_RELATIVE_TOLERANCE` of a
/// channel's AC amplitude (and more than its noise allows), up to a quarter of the periods.
fn trailing_ramp(
    work: &mut Periods<'_>,
    periods: usize,
    n_ch: usize,
    h: usize,
    options: &PhasorOptions,
) -> Result<usize, PhasorError> {
    let m = options.min_periods.max(2);
    let k = options.settle_noise_factor;
    let mut ramp = 0;
    while ramp < periods / 4 && periods - ramp > m {
        let p = periods - 1 - ramp;
        let (_, var) = work.joint(p - m, p)?;
        let v = work.per_period_variance_factors(p - 1)?;
        let mut mean = vec![vec![Complex64::new(0.0, 0.0); h]; n_ch];
        for q in p - m..p {
            for (acc, c) in mean.iter_mut().zip(work.phasors(q)?) {
                for (a, c) in acc.iter_mut().zip(c) {
                    *a += c / m as f64;
                }
            }
        }
        let cp = work.phasors(p)?;
        let off = (0..n_ch).any(|c| {
            let scale = mean[c][1..]
                .iter()
                .map(Complex64::norm_sqr)
                .sum::<f64>()
                .sqrt();
            (0..h).any(|n| {
                let noise = k * (var[c] * v[n]).sqrt() * (1.0 + 1.0 / m as f64).sqrt();
                (cp[c][n] - mean[c][n]).norm() > (UNSETTLED_RELATIVE_TOLERANCE * scale).max(noise)
            })
        });
        if !off {
            break;
        }
        ramp += 1;
    }
    Ok(ramp)
}

/// Where a walk stopped.
struct Walk {
    accepted: usize,
    first: usize,
}

/// The settling walk over periods `..end` (step 3): from period `end - 1` backwards, each
/// period joins while it agrees with the mean of those accepted within the noise of the tail
/// (the joint fit of the last `min_periods` periods before `end`, step 2) or `tol` of the
/// channel's AC amplitude.
fn walk(
    work: &mut Periods<'_>,
    end: usize,
    n_ch: usize,
    h: usize,
    options: &PhasorOptions,
    tol: f64,
) -> Result<Walk, PhasorError> {
    let min_periods = options.min_periods.max(2);
    let tail_first = end - min_periods.min(end);
    let (_, tail_var) = work.joint(tail_first, end)?;
    let last = end - 1;
    let v = work.per_period_variance_factors(last)?;
    let k = options.settle_noise_factor;
    let mut sum: Vec<Vec<Complex64>> = work.phasors(last)?.to_vec();
    let mut accepted = 1usize;
    let mut first_accepted = last;
    for p in (0..last).rev() {
        let a = accepted as f64;
        let inflate = (1.0 + 1.0 / a).sqrt();
        let cp = work.phasors(p)?;
        let agrees = (0..n_ch).all(|c| {
            let mean: Vec<Complex64> = sum[c].iter().map(|s| s / a).collect();
            let scale_ac = mean[1..]
                .iter()
                .map(Complex64::norm_sqr)
                .sum::<f64>()
                .sqrt();
            let scale = if scale_ac > 0.0 {
                scale_ac
            } else {
                mean[0].norm()
            };
            let floor = 1e-10 * scale_ac.max(mean[0].norm());
            (0..h).all(|n| {
                let noise = k * (tail_var[c] * v[n]).sqrt() * inflate;
                let thr = noise.max(tol * scale).max(floor);
                (cp[c][n] - mean[n]).norm() <= thr
            })
        });
        if !agrees {
            break;
        }
        for (s, c) in sum.iter_mut().zip(cp) {
            for (s, c) in s.iter_mut().zip(c) {
                *s += c;
            }
        }
        accepted += 1;
        first_accepted = p;
    }
    Ok(Walk {
        accepted,
        first: first_accepted,
    })
}
