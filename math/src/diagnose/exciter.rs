//! What the kinematic identity says of the exciter. The mass displacement is the base
//! displacement plus the relative one, x_o = x_i + x, whatever the element does; so on each
//! step's first harmonic the ratio r = (X_o - X) / X_i (X_o from the mass acceleration,
//! -A_1 / w^2) is the transfer from the base the base channel records to the base the rig
//! receives: 1 for an ideal exciter, e^{-j w d} for a delay d, a gain below 1 for a lag. A
//! gain above 1 is neither (an exciter with its own resonance amplifies below it, a mount or
//! fixture that rings): the exciter_delay candidate does not describe it.

use std::f64::consts::TAU;

use num_complex::Complex64;

use crate::phasor::HarmonicAnalysis;
use crate::record::Channel;

/// The kinematic ratio of one step.
#[derive(Debug, Clone, Copy)]
pub struct KinematicRatio {
    pub frequency_hz: f64,
    /// (X_o - X) / X_i on the first harmonic.
    pub ratio: Complex64,
    /// Standard deviation of `ratio` from the three channels' noise.
    pub noise: f64,
}

/// The kinematic ratio of every step with the base, relative-displacement and mass-acceleration
/// channels and a moving base; None when a channel is missing.
pub fn kinematic_ratios(analyses: &[HarmonicAnalysis]) -> Option<Vec<KinematicRatio>> {
    let mut out = Vec::new();
    for an in analyses {
        let w = TAU * an.frequency_hz;
        let xi = an.channel(Channel::BaseDisplacementM)?;
        let rel = an.channel(Channel::RelativeDisplacementM)?;
        let acc = an.channel(Channel::MassAccelerationMps2)?;
        let (xi1, rel1, a1) = (xi.phasors[1], rel.phasors[1], acc.phasors[1]);
        if xi1.norm() == 0.0 {
            continue;
        }
        let xo1 = -a1 / (w * w);
        out.push(KinematicRatio {
            frequency_hz: an.frequency_hz,
            ratio: (xo1 - rel1) / xi1,
            noise: (acc.noise_std[1] / (w * w))
                .hypot(rel.noise_std[1])
                .hypot(xi.noise_std[1])
                / xi1.norm(),
        });
    }
    Some(out)
}

/// Exciter delay estimated from the kinematic identity: the element sees the base as
/// X_i e^{-j w d}. Returns (delay [s], standard deviation [s]) from a weighted least-squares
/// fit of the ratios' phases, or None without the channels.
pub fn estimate_exciter_delay(ratios: &[KinematicRatio]) -> Option<(f64, f64)> {
    let (mut swx, mut sww) = (0.0, 0.0);
    let mut terms = Vec::new();
    for k in ratios {
        let w = TAU * k.frequency_hz;
        // phase noise ~ noise / |r|; d = -arg(r) / w
        let sd = (k.noise / k.ratio.norm().max(1e-12)).max(1e-9) / w;
        let d = -k.ratio.arg() / w;
        let wt = 1.0 / (sd * sd);
        swx += wt * d;
        sww += wt;
        terms.push((d, wt));
    }
    let count = terms.len();
    if count == 0 || sww <= 0.0 {
        return None;
    }
    let d = swx / sww;
    // Scatter-based standard deviation when it exceeds the noise-based one (other effects).
    let chi2: f64 = terms.iter().map(|(di, wt)| wt * (di - d).powi(2)).sum();
    let scale = if count > 1 {
        (chi2 / (count - 1) as f64).max(1.0)
    } else {
        1.0
    };
    Some((d, (scale / sww).sqrt()))
}

/// A gain above 1 counts when it exceeds 1 by this many noise standard deviations...
pub const AMPLIFIED_SIGMAS: f64 = 4.0;
/// ... and by this fraction (calibrations agree to about 1 %).
pub const AMPLIFIED_FRACTION: f64 = 0.02;

/// The step where the base the rig receives is most amplified over the recorded one, when some
/// step's gain exceeds 1 by [`AMPLIFIED_SIGMAS`] and [`AMPLIFIED_FRACTION`]: (frequency [Hz],
/// gain). A delay or a lag never amplifies.
pub fn amplified_base(ratios: &[KinematicRatio]) -> Option<(f64, f64)> {
    ratios
        .iter()
        .filter(|k| {
            let excess = k.ratio.norm() - 1.0;
            excess > AMPLIFIED_SIGMAS * k.noise && excess > AMPLIFIED_FRACTION
        })
        .map(|k| (k.frequency_hz, k.ratio.norm()))
        .max_by(|a, b| a.1.total_cmp(&b.1))
}

/// Whether the kinematic identity shows an exciter delay `delay_s` with standard deviation
/// `std_s`: beyond 4 standard deviations and 0.5 ms (the live diagnosis names it only then; the
/// pair search takes it as a second effect only then).
pub fn delay_shown(delay_s: f64, std_s: f64) -> bool {
    delay_s > 4.0 * std_s && delay_s > 5e-4
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ratios(h: impl Fn(f64) -> Complex64) -> Vec<KinematicRatio> {
        (1..=10)
            .map(|k| {
                let f = 0.4 * k as f64;
                KinematicRatio {
                    frequency_hz: f,
                    ratio: h(f),
                    noise: 0.003,
                }
            })
            .collect()
    }

    #[test]
    fn a_delay_is_estimated_and_a_delay_or_lag_never_amplifies() {
        let d = 0.02;
        let delay = ratios(|f| Complex64::from_polar(1.0, -TAU * f * d));
        let (est, sd) = estimate_exciter_delay(&delay).unwrap();
        assert!((est - d).abs() < 1e-12 && sd > 0.0, "{est} {sd}");
        assert_eq!(amplified_base(&delay), None);
        let tau = 0.025;
        let lag = ratios(|f| Complex64::new(1.0, TAU * f * tau).inv());
        assert_eq!(amplified_base(&lag), None);
    }

    #[test]
    fn an_exciter_resonance_amplifies_below_it() {
        // 2nd order at 10 Hz, damping 0.2: gain 1/|1 - r^2 + 2 j z r| = 1.19 at 4 Hz.
        let (fn_hz, z) = (10.0, 0.2);
        let res = ratios(|f| {
            let r = f / fn_hz;
            Complex64::new(1.0 - r * r, 2.0 * z * r).inv()
        });
        let (f, g) = amplified_base(&res).unwrap();
        assert_eq!(f, 4.0);
        assert!(
            (g - 1.0 / Complex64::new(1.0 - 0.16, 0.16).norm()).abs() < 1e-12,
            "{g}"
        );
        // Within the 2 % a calibration allows: not counted.
        let flat = ratios(|_| Complex64::new(1.015, 0.0));
        assert_eq!(amplified_base(&flat), None);
    }
}
