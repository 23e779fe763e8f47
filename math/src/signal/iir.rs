//! IIR low-pass filters as cascades of biquads: design (Butterworth and Chebyshev type I from
//! their analog prototypes, and the second-order Butterworth biquad of the validation
//! prefilter), filtering forwards ([`LowPass::apply`]) and zero-phase filtering forwards and
//! backwards ([`LowPass::filtfilt`]).

use std::f64::consts::PI;

/// A low-pass filter as a cascade of biquads (transposed direct form II), each section started
/// from the steady state of the first value. Every section has unit gain at DC (for the
/// Chebyshev filter that puts the ripple above 1 instead of below; a common scale of every
/// column and the force changes no fit and no relative error).
#[derive(Debug, Clone)]
pub struct LowPass {
    /// (b0, b1, b2, a1, a2) of each section, a0 = 1.
    sections: Vec<[f64; 5]>,
    /// Odd-reflection padding of [`LowPass::filtfilt`]: three periods of the cut-off.
    pad: usize,
}

impl LowPass {
    /// Butterworth of even `order`: prototype poles on the unit circle. A cut-off outside
    /// (0, Nyquist) gives the identity (nothing to remove below the Nyquist frequency).
    pub fn butterworth(order: usize, cutoff_hz: f64, sample_rate_hz: f64) -> LowPass {
        Self::from_prototype(order, 1.0, 1.0, cutoff_hz, sample_rate_hz)
    }

    /// Chebyshev type I of even `order` with `ripple_db` in the pass band, which ends at
    /// `cutoff_hz`.
    pub fn chebyshev1(
        order: usize,
        ripple_db: f64,
        cutoff_hz: f64,
        sample_rate_hz: f64,
    ) -> LowPass {
        let eps = (10f64.powf(ripple_db / 10.0) - 1.0).sqrt();
        let mu = (1.0 / eps).asinh() / order as f64;
        Self::from_prototype(order, mu.sinh(), mu.cosh(), cutoff_hz, sample_rate_hz)
    }

    /// Second-order Butterworth by the textbook biquad formula (Q = 1/sqrt 2, bilinear
    /// transform, cut-off pre-warped); no cut-off check (the caller's).
    ///
    /// Why it exists beside [`LowPass::butterworth`]`(2, ..)`: it is the same filter, but its
    /// coefficients are computed in another order and differ in the last bits. It is the
    /// design the rig validation's prefilter ([`super::lowpass::zero_phase_lowpass`]) has
    /// always used; keeping it keeps the validation and the rig diagnosis bit-identical.
    pub fn butterworth_biquad(cutoff_hz: f64, sample_rate_hz: f64) -> LowPass {
        let k = (PI * cutoff_hz / sample_rate_hz).tan();
        let q = std::f64::consts::FRAC_1_SQRT_2;
        let norm = 1.0 / (1.0 + k / q + k * k);
        let b0 = k * k * norm;
        let (b1, b2) = (2.0 * b0, b0);
        let a1 = 2.0 * (k * k - 1.0) * norm;
        let a2 = (1.0 - k / q + k * k) * norm;
        LowPass {
            sections: vec![[b0, b1, b2, a1, a2]],
            pad: (3.0 * sample_rate_hz / cutoff_hz).ceil() as usize,
        }
    }

    /// Prototype poles `-a sin(theta_k) +- j b cos(theta_k)`, theta_k = (2k - 1) pi / (2 n).
    fn from_prototype(order: usize, a: f64, b: f64, cutoff_hz: f64, fs: f64) -> LowPass {
        debug_assert!(order.is_multiple_of(2), "even orders only");
        if !(cutoff_hz > 0.0 && cutoff_hz < 0.5 * fs) {
            // Nothing to remove below the Nyquist frequency.
            return LowPass {
                sections: Vec::new(),
                pad: 0,
            };
        }
        let k = (PI * cutoff_hz / fs).tan();
        let sections = (1..=order / 2)
            .map(|m| {
                let theta = (2 * m - 1) as f64 * PI / (2 * order) as f64;
                let (re, im) = (-a * theta.sin(), b * theta.cos());
                // s^2 + d s + w0^2 with s = (1 - z^-1) / (k (1 + z^-1)), multiplied by k^2.
                let w2 = (re * re + im * im) * k * k;
                let d = -2.0 * re * k;
                let a0 = 1.0 + d + w2;
                let b0 = w2 / a0;
                [b0, 2.0 * b0, b0, 2.0 * (w2 - 1.0) / a0, (1.0 - d + w2) / a0]
            })
            .collect();
        LowPass {
            sections,
            pad: (3.0 * fs / cutoff_hz).ceil() as usize,
        }
    }

    /// One pass forwards, in place, each section started from the steady state of the first
    /// value.
    pub fn apply(&self, x: &mut [f64]) {
        for &[b0, b1, b2, a1, a2] in &self.sections {
            let Some(&x0) = x.first() else { return };
            let z2 = (b2 - a2) * x0;
            let (mut z1, mut z2) = ((b1 - a1) * x0 + z2, z2);
            for v in x.iter_mut() {
                let input = *v;
                let y = b0 * input + z1;
                z1 = b1 * input - a1 * y + z2;
                z2 = b2 * input - a2 * y;
                *v = y;
            }
        }
    }

    /// Zero-phase filtering (forwards, then backwards) with odd-reflection padding of three
    /// periods of the cut-off (at most the record's length less one).
    pub fn filtfilt(&self, x: &[f64]) -> Vec<f64> {
        let n = x.len();
        if n < 2 || self.sections.is_empty() {
            return x.to_vec();
        }
        let pad = self.pad.min(n - 1);
        let mut v = Vec::with_capacity(n + 2 * pad);
        v.extend((1..=pad).rev().map(|k| 2.0 * x[0] - x[k]));
        v.extend_from_slice(x);
        v.extend((1..=pad).map(|k| 2.0 * x[n - 1] - x[n - 1 - k]));
        self.apply(&mut v);
        v.reverse();
        self.apply(&mut v);
        v.reverse();
        v[pad..pad + n].to_vec()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sine(f_hz: f64, fs: f64, n: usize) -> Vec<f64> {
        (0..n)
            .map(|i| (2.0 * PI * f_hz * i as f64 / fs).sin())
            .collect()
    }

    fn peak(x: &[f64]) -> f64 {
        x.iter().fold(0.0f64, |m, v| m.max(v.abs()))
    }

    #[test]
    fn butterworth_passes_dc_and_is_minus_6_db_at_the_cutoff_forwards_and_back() {
        let f = LowPass::butterworth(4, 25.0, 1000.0);
        let dc = f.filtfilt(&[3.0; 500]);
        assert!(dc.iter().all(|v| (v - 3.0).abs() < 1e-9));
        let out = f.filtfilt(&sine(200.0, 1000.0, 2000));
        assert!(peak(&out[500..1500]) < 1e-4);
        let out = f.filtfilt(&sine(25.0, 1000.0, 4000));
        assert!((peak(&out[1000..3000]) - 0.5).abs() < 0.01);
    }

    #[test]
    fn chebyshev_is_flat_to_its_band_edge_and_steep_beyond() {
        // The anti-alias filter of decimation by 10 at 1 kHz: pass band to 40 Hz.
        let f = LowPass::chebyshev1(8, 0.05, 40.0, 1000.0);
        for (f_hz, lo, hi) in [(5.0, 0.99, 1.012), (39.0, 0.99, 1.012), (50.0, 0.0, 0.05)] {
            let out = f.filtfilt(&sine(f_hz, 1000.0, 6000));
            let p = peak(&out[2000..4000]);
            assert!(p > lo && p < hi, "{f_hz} Hz: gain {p}");
        }
    }
}
