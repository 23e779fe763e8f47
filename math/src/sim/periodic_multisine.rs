//! Periodic multisines for identification: sines at lines `k f0` of a base frequency over a
//! band, equal amplitudes, random phases, repeated for whole periods. Each period gives every
//! line at once; the scatter between periods gives the noise per line, and the lines left out
//! (even lines of an odd design, one odd line in three of a random-odd design) show the
//! nonlinear distortion (best linear approximation practice).

use std::f64::consts::TAU;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::excitation::{Multisine, StepSpec};

/// Random phase draws per realisation; the one with the lowest crest factor is kept (the
/// crest factor of random phases varies from draw to draw; the kept one of the unit test's
/// 4-40 Hz random-odd design is 2.6).
const PHASE_TRIALS: u64 = 16;

/// Which lines of the band a multisine excites.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MultisineDesign {
    /// Every line `k f0` in the band.
    Full,
    /// Odd lines only: even-order distortion appears at the even lines, the odd-order one
    /// falls on the excited lines.
    Odd,
    /// Odd lines, one of each consecutive three left out at random: the left-out odd lines
    /// show the odd-order distortion, the even lines the even-order one.
    #[default]
    RandomOdd,
}

/// A multisine program of one record per realisation: what [`StepSpec::Multisine`] says,
/// plus how many whole periods each record holds (the first ones the transient).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MultisinePlan {
    pub base_frequency_hz: f64,
    pub band_hz: [f64; 2],
    /// RMS of the driven quantity over whole periods.
    pub rms: f64,
    pub design: MultisineDesign,
    /// Whole periods per record.
    pub periods: usize,
}

impl MultisinePlan {
    /// The step of one realisation (its phases come from the run seed and its index).
    pub fn step(&self) -> StepSpec {
        StepSpec::Multisine {
            base_frequency_hz: self.base_frequency_hz,
            low_hz: self.band_hz[0],
            high_hz: self.band_hz[1],
            rms: self.rms,
            design: self.design,
        }
    }

    /// Samples per record at `sample_rate_hz`: `periods` periods of `fs / f0` samples, rounded
    /// (an analysis refuses a period that is not a whole number of samples).
    pub fn samples_per_record(&self, sample_rate_hz: f64) -> usize {
        self.periods * (sample_rate_hz / self.base_frequency_hz).round().max(1.0) as usize
    }
}

/// The lines `k` (ascending) of `design` with `k f0` in `[low_hz, high_hz]`, for `seed`.
pub fn multisine_lines(
    base_frequency_hz: f64,
    low_hz: f64,
    high_hz: f64,
    design: MultisineDesign,
    seed: u64,
) -> Vec<usize> {
    if !(base_frequency_hz > 0.0 && high_hz >= low_hz) {
        return Vec::new();
    }
    // A line on a band edge (up to rounding) is in the band.
    let first = ((low_hz / base_frequency_hz) - 1e-9).ceil().max(1.0) as usize;
    let last = ((high_hz / base_frequency_hz) + 1e-9).floor() as usize;
    let all = first..=last;
    match design {
        MultisineDesign::Full => all.collect(),
        MultisineDesign::Odd => all.filter(|k| k % 2 == 1).collect(),
        MultisineDesign::RandomOdd => {
            let odd: Vec<usize> = all.filter(|k| k % 2 == 1).collect();
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let mut out = Vec::with_capacity(odd.len());
            for group in odd.chunks(3) {
                // A short last group keeps all its lines (nothing to compare it with).
                let drop = if group.len() == 3 {
                    rng.random_range(0..3)
                } else {
                    usize::MAX
                };
                out.extend(
                    group
                        .iter()
                        .enumerate()
                        .filter(|(i, _)| *i != drop)
                        .map(|(_, k)| *k),
                );
            }
            out
        }
    }
}

/// A periodic multisine on `lines` of `base_frequency_hz` with RMS `rms` (exact over whole
/// periods: the lines are orthogonal there, so each has amplitude `rms sqrt(2 / lines)`), its
/// phases the lowest-crest-factor draw of [`PHASE_TRIALS`] from `seed`, the crest factor
/// measured on the sampling grid of `sample_rate_hz`.
pub fn periodic_multisine(
    base_frequency_hz: f64,
    lines: &[usize],
    rms: f64,
    seed: u64,
    sample_rate_hz: f64,
) -> Multisine {
    let n = lines.len().max(1);
    let omegas: Vec<f64> = lines
        .iter()
        .map(|&k| TAU * k as f64 * base_frequency_hz)
        .collect();
    let samples = (sample_rate_hz / base_frequency_hz).round().max(1.0) as usize;
    let mut best: Option<(f64, Vec<f64>)> = None;
    for trial in 0..PHASE_TRIALS {
        let mut rng = ChaCha8Rng::seed_from_u64(super::excitation::derive_seed(seed, trial));
        let phases: Vec<f64> = lines.iter().map(|_| TAU * rng.random::<f64>()).collect();
        let peak = (0..samples)
            .map(|i| {
                let t = i as f64 / sample_rate_hz;
                omegas
                    .iter()
                    .zip(&phases)
                    .map(|(w, p)| (w * t + p).sin())
                    .sum::<f64>()
                    .abs()
            })
            .fold(0.0, f64::max);
        if best.as_ref().is_none_or(|(b, _)| peak < *b) {
            best = Some((peak, phases));
        }
    }
    let phases = best.map(|(_, p)| p).unwrap_or_default();
    let band = match (lines.first(), lines.last()) {
        (Some(lo), Some(hi)) => [
            *lo as f64 * base_frequency_hz,
            *hi as f64 * base_frequency_hz,
        ],
        _ => [0.0, 0.0],
    };
    Multisine {
        band_hz: band,
        component_amplitude: rms * (2.0 / n as f64).sqrt(),
        omegas,
        phases,
    }
}

/// Peak over RMS of `ms` over one period of `base_frequency_hz` sampled at `sample_rate_hz`.
pub fn crest_factor(ms: &Multisine, base_frequency_hz: f64, sample_rate_hz: f64) -> f64 {
    let samples = (sample_rate_hz / base_frequency_hz).round().max(1.0) as usize;
    let v: Vec<f64> = (0..samples)
        .map(|i| ms.eval(i as f64 / sample_rate_hz).value)
        .collect();
    let rms = (v.iter().map(|x| x * x).sum::<f64>() / samples as f64).sqrt();
    v.iter().fold(0.0f64, |m, x| m.max(x.abs())) / rms
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn designs_pick_their_lines() {
        assert_eq!(
            multisine_lines(0.5, 2.0, 5.0, MultisineDesign::Full, 0),
            (4..=10).collect::<Vec<_>>()
        );
        assert_eq!(
            multisine_lines(0.5, 2.0, 5.0, MultisineDesign::Odd, 0),
            [5, 7, 9]
        );
        let ro = multisine_lines(1.0, 1.0, 23.0, MultisineDesign::RandomOdd, 3);
        // 12 odd lines in 4 groups of 3, one left out of each.
        assert_eq!(ro.len(), 8);
        for g in [1usize, 7, 13, 19] {
            let kept = ro.iter().filter(|k| (g..g + 6).contains(k)).count();
            assert_eq!(kept, 2, "{ro:?}");
        }
        assert!(ro.iter().all(|k| k % 2 == 1));
    }

    #[test]
    fn rms_is_exact_over_a_period_and_the_crest_factor_sane() {
        let lines = multisine_lines(0.5, 4.0, 40.0, MultisineDesign::RandomOdd, 1);
        let ms = periodic_multisine(0.5, &lines, 30.0, 7, 2000.0);
        let v: Vec<f64> = (0..4000)
            .map(|i| ms.eval(i as f64 / 2000.0).value)
            .collect();
        let rms = (v.iter().map(|x| x * x).sum::<f64>() / 4000.0).sqrt();
        assert!((rms - 30.0).abs() < 1e-9 * 30.0, "{rms}");
        let cf = crest_factor(&ms, 0.5, 2000.0);
        eprintln!("crest factor {cf:.3}");
        assert!(cf > 1.0 && cf < 3.2, "crest factor {cf}");
        // Periodic: the next period repeats the first.
        let d = ms.eval(0.123).value - ms.eval(2.123).value;
        assert!(d.abs() < 1e-9 * 30.0);
    }
}
