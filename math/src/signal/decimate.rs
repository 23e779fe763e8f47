//! Decimation after MATLAB's `decimate`: an 8th-order Chebyshev type I anti-alias low-pass
//! (0.05 dB ripple, pass band up to 0.8 Nyquist / factor) run forwards and backwards, then one
//! sample in `factor` kept, the last one included.

use super::iir::LowPass;

/// Order and pass-band ripple of the anti-alias filter (MATLAB `decimate`'s Chebyshev type I).
pub const ANTI_ALIAS_ORDER: usize = 8;
pub const ANTI_ALIAS_RIPPLE_DB: f64 = 0.05;

/// Decimation by `factor` of signals sampled at one rate.
#[derive(Debug, Clone)]
pub struct Decimator {
    anti_alias: LowPass,
    factor: usize,
}

impl Decimator {
    /// Decimation by `factor` (at least 1) of signals sampled at `sample_rate_hz`.
    pub fn new(factor: usize, sample_rate_hz: f64) -> Decimator {
        assert!(factor > 0, "decimation by 0");
        let fs = sample_rate_hz;
        Decimator {
            anti_alias: LowPass::chebyshev1(
                ANTI_ALIAS_ORDER,
                ANTI_ALIAS_RIPPLE_DB,
                0.8 * fs / 2.0 / factor as f64,
                fs,
            ),
            factor,
        }
    }

    pub fn factor(&self) -> usize {
        self.factor
    }

    /// Indices kept of `n` samples: every `factor`-th, ending with the last sample (as
    /// MATLAB's `decimate`).
    pub fn kept(&self, n: usize) -> impl Iterator<Item = usize> + use<> {
        let start = n.saturating_sub(1) % self.factor;
        (start..n).step_by(self.factor)
    }

    /// `x` anti-alias filtered (zero phase) and decimated.
    pub fn decimate(&self, x: &[f64]) -> Vec<f64> {
        let f = self.anti_alias.filtfilt(x);
        self.kept(x.len()).map(|i| f[i]).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decimation_keeps_the_last_sample() {
        let d = Decimator::new(10, 1000.0);
        let kept: Vec<usize> = d.kept(902).collect();
        assert_eq!(*kept.last().unwrap(), 901);
        assert!(kept.windows(2).all(|w| w[1] - w[0] == 10));
        assert_eq!(d.decimate(&[2.0; 902]).len(), kept.len());
    }
}
