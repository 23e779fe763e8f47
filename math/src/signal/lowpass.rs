//! The low-passes of the rig path: the zero-phase prefilter of the validation (a measured base
//! displacement before it is replayed) and the first-order model of a sensor low-pass.

use std::f64::consts::TAU;

use serde::{Deserialize, Serialize};

use super::iir::LowPass;

/// Optional zero-phase low-pass applied to a sampled base displacement before it is
/// interpolated: a second-order Butterworth run forwards and backwards (4th-order magnitude,
/// no phase shift, so no delay is added to the input), with odd reflection padding at the ends.
/// Why: the spline's second derivative (the base acceleration that drives the model) amplifies
/// displacement noise by w^2, so broadband sensor noise above the excitation band would
/// otherwise dominate the predicted acceleration. See [`zero_phase_lowpass`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ZeroPhaseLowpass {
    pub cutoff_hz: f64,
}

/// Zero-phase low-pass: second-order Butterworth (bilinear, pre-warped;
/// [`LowPass::butterworth_biquad`]) applied forwards and backwards, odd-reflection padding of
/// up to 3 cutoff periods, steady-state initial conditions. Fewer than three samples, or a
/// cut-off that is not finite and positive or not below the Nyquist frequency, pass unchanged.
///
/// Why it exists beside the time-domain path's filters ([`LowPass::butterworth`] of order 4 on
/// the position, the anti-alias filter of [`super::decimate`]): it is the rig validation's
/// prefilter (`pipeline::validate_rig`, `diagnose::score`), of lower order and its own
/// coefficient formula; the validation figures are computed with exactly this filter.
pub fn zero_phase_lowpass(x: &[f64], sample_rate_hz: f64, cutoff_hz: f64) -> Vec<f64> {
    let n = x.len();
    if n < 3 || !(cutoff_hz.is_finite() && cutoff_hz > 0.0) || cutoff_hz >= 0.5 * sample_rate_hz {
        return x.to_vec();
    }
    LowPass::butterworth_biquad(cutoff_hz, sample_rate_hz).filtfilt(x)
}

/// First-order low-pass y' = wc (u - y), exact for input held linear between samples, starting
/// at rest on the first sample: the model of a sensor low-pass applied to a prediction.
pub fn first_order_lowpass(u: &[f64], sample_rate_hz: f64, cutoff_hz: f64) -> Vec<f64> {
    let a = (-TAU * cutoff_hz / sample_rate_hz).exp();
    // Exact discretisation for a piecewise-linear input (first-order hold).
    let wdt = TAU * cutoff_hz / sample_rate_hz;
    let b1 = 1.0 - (1.0 - a) / wdt;
    let b0 = (1.0 - a) / wdt - a;
    let mut y = Vec::with_capacity(u.len());
    let mut prev = u.first().copied().unwrap_or(0.0);
    let mut yi = prev;
    for &ui in u {
        yi = a * yi + b0 * prev + b1 * ui;
        prev = ui;
        y.push(yi);
    }
    y
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_order_lowpass_has_the_right_gain() {
        let fs = 1000.0;
        let f = 5.0;
        let fc = 5.0;
        let u: Vec<f64> = (0..20000)
            .map(|i| (TAU * f * i as f64 / fs).sin())
            .collect();
        let y = first_order_lowpass(&u, fs, fc);
        let amp = y[15000..].iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!((amp - 1.0 / 2f64.sqrt()).abs() < 2e-3, "{amp}");
    }
}
