//! Step 1 and 2 of the segmentation: overlapping windows, each fitted with one sine and
//! classed, then grouped into runs of agreeing windows (see the module docs of `segment`).

use super::SegmentOptions;
use super::sine_fit::{SineFit, SineFitter};
use num_complex::Complex64;

/// Gauss-Newton iterations of a window's fit: from the interpolated DFT peak, enough for
/// the features to be exact to rounding.
const WINDOW_ITERATIONS: usize = 6;
/// Fewest windows a run needs to be a step (a window entirely inside a step, with a
/// neighbour on each side to show it is not a transition).
pub(super) const MIN_RUN_WINDOWS: usize = 3;
/// A strong line of the whole series' spectrum has at least this fraction of the peak power.
const STRONG_LINE_FRACTION: f64 = 0.1;
/// Rounding floor of the agreement and cleanness tests (relative): noise-free data.
pub(super) const ROUNDING_REL: f64 = 1e-9;
/// A window shows a sine only when it holds at least this many periods of it. Less of a
/// period is fitted by sines of many frequencies and amplitudes whose standard deviations
/// understate how far apart neighbouring windows' fits fall, so they disagree and cut a step
/// in two: a series too short for `window_periods` periods per window (its window is clamped
/// to a third of it), as the live step finder's buffer is early in a long low step.
pub(super) const MIN_WINDOW_PERIODS: f64 = 2.0;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Class {
    Rest,
    Broadband,
    Sine,
    /// A sine window that leaves more than noise: it straddles a change.
    Transition,
}

#[derive(Debug, Clone)]
pub(super) struct Window {
    pub start: usize,
    pub class: Class,
    pub fit: Option<SineFit>,
}

pub(super) struct Analysis {
    pub window: usize,
    pub windows: Vec<Window>,
    pub noise_rms: f64,
}

/// Windows `first..=last` (indices into `Analysis::windows`) of one class that agree.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Run {
    pub class: Class,
    pub first: usize,
    pub last: usize,
}

/// Window length: `window_periods` periods of the lowest strong line of the spectrum of the
/// whole series (clamped to 16 samples .. a third of the series).
fn window_length(x: &[f64], periods: f64) -> usize {
    let n = x.len();
    let upper = (n / 3).max(16);
    match lowest_line_period(x) {
        Some(samples_per_period) => {
            ((periods * samples_per_period).round() as usize).clamp(16, upper)
        }
        None => (n / 8).clamp(16, upper),
    }
}

/// Samples per period of the lowest strong line of the spectrum of the whole series, if it
/// has one.
pub(super) fn lowest_line_period(x: &[f64]) -> Option<f64> {
    let n = x.len();
    let m = n.next_power_of_two();
    let mean = x.iter().sum::<f64>() / n as f64;
    // The real-input transform: half the memory of a complex one over the whole series (the
    // series is a whole file's drive channel, millions of samples).
    let fft = realfft::RealFftPlanner::<f64>::new().plan_fft_forward(m);
    let mut input = fft.make_input_vec();
    for (slot, v) in input.iter_mut().zip(x) {
        *slot = v - mean;
    }
    let mut spectrum = fft.make_output_vec();
    fft.process(&mut input, &mut spectrum)
        .expect("buffers made by the plan");
    drop(input);
    let power: Vec<f64> = spectrum.iter().map(Complex64::norm_sqr).collect();
    // Bins below 2 hold what is left of a trend, not a line.
    let first = 2.min(m / 2);
    let peak = power[first..].iter().copied().fold(0.0, f64::max);
    let lowest = (first..power.len()).find(|&k| {
        let p = power[k];
        p >= STRONG_LINE_FRACTION * peak
            && p >= power[k - 1]
            && power.get(k + 1).is_none_or(|&q| p >= q)
    });
    match lowest {
        Some(k) if peak > 0.0 => Some(m as f64 / k as f64),
        _ => None,
    }
}

/// Cuts `x` into windows (hop a quarter window, the last one ending at the end) and classes
/// each.
pub(super) fn analyse(x: &[f64], options: &SegmentOptions, fitter: &mut SineFitter) -> Analysis {
    analyse_in_windows(x, window_length(x, options.window_periods), options, fitter)
}

/// [`analyse`] with windows of `window` samples (at most the series' length).
pub(super) fn analyse_in_windows(
    x: &[f64],
    window: usize,
    options: &SegmentOptions,
    fitter: &mut SineFitter,
) -> Analysis {
    let n = x.len();
    let window = window.min(n);
    let hop = (window / 4).max(1);
    let mut starts: Vec<usize> = (0..=n - window).step_by(hop).collect();
    if starts.last().is_some_and(|&s| s + window < n) {
        starts.push(n - window);
    }
    let fits = fit_windows(crate::parallel::threads(), x, &starts, window, fitter);
    let largest = fits
        .iter()
        .filter_map(|(_, f)| f.map(|f| f.total_rms))
        .fold(0.0, f64::max);
    let is_rest = |f: &Option<SineFit>| {
        f.is_none_or(|f| f.total_rms <= options.rest_fraction * largest || largest == 0.0)
    };
    let periods = |f: &SineFit| f.omega * window as f64 / (2.0 * std::f64::consts::PI);
    let is_sine = |f: &SineFit| {
        f.unexplained() < options.sine_max_unexplained && periods(f) >= MIN_WINDOW_PERIODS
    };
    let mut residuals: Vec<f64> = fits
        .iter()
        .filter(|(_, f)| !is_rest(f))
        .filter_map(|(_, f)| f.filter(is_sine).map(|f| f.residual_rms))
        .collect();
    residuals.sort_by(f64::total_cmp);
    let noise_rms = residuals.get(residuals.len() / 2).copied().unwrap_or(0.0);
    let windows = fits
        .into_iter()
        .map(|(start, fit)| {
            let class = match fit {
                _ if is_rest(&fit) => Class::Rest,
                Some(f) if is_sine(&f) => {
                    let limit =
                        (options.clean_residual_factor * noise_rms).max(ROUNDING_REL * f.total_rms);
                    if f.residual_rms <= limit {
                        Class::Sine
                    } else {
                        Class::Transition
                    }
                }
                _ => Class::Broadband,
            };
            Window { start, class, fit }
        })
        .collect();
    Analysis {
        window,
        windows,
        noise_rms,
    }
}

/// Each window's sine fit (windows of `window` samples at `starts`), the windows of a long
/// series split over `threads` threads: the fits are independent of each other, so they are
/// the fits of one loop.
pub(super) fn fit_windows(
    threads: usize,
    x: &[f64],
    starts: &[usize],
    window: usize,
    fitter: &mut SineFitter,
) -> Vec<(usize, Option<SineFit>)> {
    let fit = |fitter: &mut SineFitter, part: &[usize]| -> Vec<(usize, Option<SineFit>)> {
        part.iter()
            .map(|&s| (s, fitter.fit(&x[s..s + window], s, WINDOW_ITERATIONS)))
            .collect()
    };
    let min_part = crate::parallel::min_part_of(x.len(), starts.len());
    if threads < 2 || starts.len() < 2 * min_part {
        return fit(fitter, starts);
    }
    crate::parallel::in_parts_on(threads, starts, min_part, |part| {
        fit(&mut SineFitter::new(), part)
    })
}

/// Two sine fits agree: frequency and amplitude within `sigmas` standard deviations (plus a
/// rounding floor).
pub(super) fn agree(a: &SineFit, b: &SineFit, sigmas: f64) -> bool {
    let w_tol = sigmas * a.omega_std.hypot(b.omega_std) + ROUNDING_REL * a.omega.abs();
    let (aa, ab) = (a.amplitude(), b.amplitude());
    let a_tol = sigmas * a.amplitude_std().hypot(b.amplitude_std()) + ROUNDING_REL * aa;
    (a.omega - b.omega).abs() <= w_tol && (aa - ab).abs() <= a_tol
}

pub(super) fn windows_agree(analysis: &Analysis, i: usize, j: usize, sigmas: f64) -> bool {
    match (&analysis.windows[i].fit, &analysis.windows[j].fit) {
        (Some(a), Some(b)) => agree(a, b, sigmas),
        _ => false,
    }
}

/// The runs of agreeing windows, joined where neighbouring runs agree.
pub(super) fn runs(analysis: &Analysis, options: &SegmentOptions) -> Vec<Run> {
    let k = options.consistency_sigmas;
    let mut found: Vec<Run> = Vec::new();
    let mut current: Option<Run> = None;
    let close = |run: Option<Run>, found: &mut Vec<Run>| {
        if let Some(r) = run
            && r.last + 1 - r.first >= MIN_RUN_WINDOWS
        {
            found.push(r);
        }
    };
    for (i, w) in analysis.windows.iter().enumerate() {
        if w.class == Class::Transition {
            close(current.take(), &mut found);
            continue;
        }
        let extends = current.is_some_and(|r| {
            r.class == w.class
                && (w.class != Class::Sine
                    || (windows_agree(analysis, r.first, i, k)
                        && windows_agree(analysis, r.last, i, k)))
        });
        if extends {
            if let Some(r) = current.as_mut() {
                r.last = i;
            }
        } else {
            close(current.take(), &mut found);
            current = Some(Run {
                class: w.class,
                first: i,
                last: i,
            });
        }
    }
    close(current.take(), &mut found);
    // Join neighbours that agree (a transition window inside a step, e.g. a spike).
    let mut joined: Vec<Run> = Vec::new();
    for r in found {
        if let Some(prev) = joined.last_mut()
            && prev.class == r.class
            && (r.class != Class::Sine || windows_agree(analysis, middle(prev), middle(&r), k))
        {
            prev.last = r.last;
            continue;
        }
        joined.push(r);
    }
    joined
}

/// The middle window of a run (its representative).
pub(super) fn middle(r: &Run) -> usize {
    (r.first + r.last) / 2
}

/// The mean frequency [rad/sample] of a sine run's windows.
pub(super) fn run_omega(analysis: &Analysis, r: &Run) -> Option<f64> {
    let omegas: Vec<f64> = analysis.windows[r.first..=r.last]
        .iter()
        .filter_map(|w| w.fit.map(|f| f.omega))
        .collect();
    (!omegas.is_empty()).then(|| omegas.iter().sum::<f64>() / omegas.len() as f64)
}
