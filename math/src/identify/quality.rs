//! The fit against the noise: how far each band of harmonics misses, in units of what its
//! noise alone would leave, and the warning when the model explains the data far worse than
//! its noise allows.
//!
//! Every row of a block knows the factor turning its weighted residual into units of its noise
//! and what the noise alone leaves of its square ([`RowNoise`]). The accumulator keeps, per
//! band of harmonics (0, 1, 2-3, 4-7, ...: octaves, a few numbers each whatever the harmonics),
//! the quadratic form of those residuals in theta (`sum g^2 (b - a theta)^2`, expanded), so
//! that the quality of any theta, the newest after every step live, comes from constant
//! memory.

use serde::{Deserialize, Serialize};

use super::{IdentifyWarning, RowNoise, StepEquations};

/// Above this ratio of the residual's RMS to the noise's the model's form is called wrong (a
/// residual variance 9 times what the noise leaves: a noise estimate from few periods
/// scatters, but not so far).
pub const FORM_WARNING_RATIO: f64 = 3.0;

/// The band of harmonic `n`: 0 for DC, `k` for harmonics `2^(k-1)..2^k - 1`.
fn band_of(n: usize) -> usize {
    (usize::BITS - n.leading_zeros()) as usize
}

/// The lowest harmonic of band `k`.
fn band_start(k: usize) -> usize {
    if k == 0 { 0 } else { 1 << (k - 1) }
}

/// One band's sums: `sum g^2 a a^T` (row-major), `sum g^2 a b`, `sum g^2 b^2`, what the noise
/// leaves, the rows and the highest harmonic seen.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct BandSums {
    aa: Vec<f64>,
    ab: Vec<f64>,
    bb: f64,
    expected: f64,
    rows: f64,
    highest: usize,
}

/// The residual sums of every band, as the accumulator keeps them.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub(super) struct QualitySums {
    bands: Vec<BandSums>,
    /// Blocks weighted for a form error, of those with rows.
    form_error_blocks: usize,
    blocks: usize,
}

impl QualitySums {
    /// Adds the rows of `blk` that have a noise to compare with.
    pub fn add(&mut self, blk: &StepEquations) {
        if blk.a.nrows() > 0 {
            self.blocks += 1;
            if blk.form_variance > 0.0 {
                self.form_error_blocks += 1;
            }
        }
        let p = blk.a.ncols();
        for (
            r,
            RowNoise {
                harmonic,
                gain,
                expected,
            },
        ) in blk.row_noise.iter().enumerate()
        {
            if gain.is_nan() || *gain <= 0.0 || r >= blk.a.nrows() {
                continue;
            }
            let k = band_of(*harmonic);
            if self.bands.len() <= k {
                self.bands.resize(
                    k + 1,
                    BandSums {
                        aa: vec![0.0; p * p],
                        ab: vec![0.0; p],
                        bb: 0.0,
                        expected: 0.0,
                        rows: 0.0,
                        highest: 0,
                    },
                );
            }
            let band = &mut self.bands[k];
            let g2 = gain * gain;
            let row = blk.a.row(r);
            let b = blk.b[r];
            for i in 0..p {
                for j in 0..p {
                    band.aa[i * p + j] += g2 * row[i] * row[j];
                }
                band.ab[i] += g2 * row[i] * b;
            }
            band.bb += g2 * b * b;
            band.expected += expected;
            band.rows += 1.0;
            band.highest = band.highest.max(*harmonic);
        }
    }

    /// Weighs everything so far by `factor` (exponential forgetting).
    pub fn forget(&mut self, factor: f64) {
        for band in &mut self.bands {
            band.aa.iter_mut().for_each(|v| *v *= factor);
            band.ab.iter_mut().for_each(|v| *v *= factor);
            band.bb *= factor;
            band.expected *= factor;
            band.rows *= factor;
        }
    }

    /// The quality of `theta`; `None` when no row had a noise to compare with.
    pub fn quality(&self, theta: &[f64]) -> Option<FitQuality> {
        let p = theta.len();
        let mut bands = Vec::new();
        let (mut residual, mut expected) = (0.0, 0.0);
        for (k, band) in self.bands.iter().enumerate() {
            if band.expected.is_nan() || band.expected <= 0.0 || band.ab.len() != p {
                continue;
            }
            let mut r = band.bb;
            for i in 0..p {
                r -= 2.0 * theta[i] * band.ab[i];
                for j in 0..p {
                    r += theta[i] * band.aa[i * p + j] * theta[j];
                }
            }
            let r = r.max(0.0);
            residual += r;
            expected += band.expected;
            bands.push(HarmonicBand {
                first_harmonic: band_start(k),
                last_harmonic: band.highest,
                residual_to_noise: (r / band.expected).sqrt(),
            });
        }
        (expected > 0.0).then(|| FitQuality {
            residual_to_noise: (residual / expected).sqrt(),
            bands,
            form_error_steps: self.form_error_blocks,
            steps: self.blocks,
        })
    }
}

/// The residual of a fit against its noise.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FitQuality {
    /// RMS of the residual over the RMS the noise alone leaves, all rows: about 1 when the
    /// model explains the data within their noise.
    pub residual_to_noise: f64,
    /// The same by band of harmonics.
    pub bands: Vec<HarmonicBand>,
    /// Steps whose rows were weighted for a form error ([`super::Weighting::Robust`]), of the
    /// steps that gave equations.
    pub form_error_steps: usize,
    pub steps: usize,
}

/// A band of harmonics and how far the fit misses there.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HarmonicBand {
    pub first_harmonic: usize,
    pub last_harmonic: usize,
    /// RMS of the residual over the RMS the noise alone leaves in the band.
    pub residual_to_noise: f64,
}

impl FitQuality {
    /// One line: the ratio over all rows, then by band (`0: 1.1, 1: 35, 2-3: 4.2, ...`).
    pub fn summary(&self) -> String {
        let bands: Vec<String> = self
            .bands
            .iter()
            .map(|b| {
                let which = if b.first_harmonic == b.last_harmonic {
                    b.first_harmonic.to_string()
                } else {
                    format!("{}-{}", b.first_harmonic, b.last_harmonic)
                };
                format!("{which}: {}", ratio(b.residual_to_noise))
            })
            .collect();
        let weighted = if self.form_error_steps > 0 {
            format!(
                "; {} of {} steps weighted for a form error",
                self.form_error_steps, self.steps
            )
        } else {
            String::new()
        };
        format!(
            "residual {} times the noise (by harmonic {}){weighted}",
            ratio(self.residual_to_noise),
            bands.join(", ")
        )
    }

    /// The warning of a residual far beyond the noise ([`FORM_WARNING_RATIO`]).
    pub fn warning(&self) -> Option<IdentifyWarning> {
        (self.residual_to_noise > FORM_WARNING_RATIO).then(|| IdentifyWarning::WrongForm {
            residual_to_noise: self.residual_to_noise,
            text: format!(
                "the model explains the data far worse than its noise allows: {}; the form is wrong: try `forcemap diagnose`",
                self.summary()
            ),
        })
    }
}

/// A ratio with two significant digits (`1.1`, `35`, `1200`).
fn ratio(r: f64) -> String {
    if r < 10.0 {
        format!("{r:.1}")
    } else {
        format!("{r:.0}")
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{DMatrix, DVector};

    use super::*;

    #[test]
    fn bands_are_octaves_of_harmonics() {
        let bands: Vec<usize> = (0..9).map(band_of).collect();
        assert_eq!(bands, [0, 1, 2, 2, 3, 3, 3, 3, 4]);
        assert_eq!((band_start(0), band_start(1), band_start(4)), (0, 1, 8));
    }

    /// The sums give the residual of any theta: rows whose residual is twice their noise give
    /// a ratio of 2 in their band.
    #[test]
    fn the_ratio_is_the_residual_over_the_noise_by_band() {
        let a = DMatrix::from_row_slice(3, 1, &[1.0, 2.0, 4.0]);
        let b = DVector::from_column_slice(&[1.0, 2.0, 4.0]);
        let blk = StepEquations {
            step: 0,
            a,
            b,
            independent_equations: 3.0,
            term_rms: vec![1.0],
            notes: vec![],
            row_noise: vec![
                RowNoise {
                    harmonic: 1,
                    gain: 0.5,
                    expected: 1.0,
                },
                RowNoise {
                    harmonic: 2,
                    gain: 0.25,
                    expected: 1.0,
                },
                RowNoise {
                    harmonic: 3,
                    gain: 0.125,
                    expected: 1.0,
                },
            ],
            form_variance: 0.0,
        };
        let mut sums = QualitySums::default();
        sums.add(&blk);
        // theta 1 fits exactly; theta 0 leaves b: residual in noise units 0.5, 0.5, 0.5.
        let q = sums.quality(&[1.0]).unwrap();
        assert!(q.residual_to_noise < 1e-12, "{q:?}");
        let q = sums.quality(&[0.0]).unwrap();
        assert_eq!(q.bands.len(), 2);
        assert_eq!(
            (q.bands[1].first_harmonic, q.bands[1].last_harmonic),
            (2, 3)
        );
        assert!((q.residual_to_noise - 0.5).abs() < 1e-12, "{q:?}");
        assert!(q.warning().is_none());
        let q = sums.quality(&[-6.0]).unwrap();
        assert!((q.residual_to_noise - 3.5).abs() < 1e-12, "{q:?}");
        let w = q.warning().unwrap().to_string();
        assert!(w.contains("try `forcemap diagnose`"), "{w}");
    }
}
