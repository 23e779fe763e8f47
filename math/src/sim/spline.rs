//! Interpolating cubic splines on uniformly sampled data, with exact first and second
//! derivatives: how a sampled input (a measured base motion or force) drives a simulator.

use serde::{Deserialize, Serialize};

use super::excitation::Derivs;

/// Natural or not-a-knot end conditions of a cubic spline.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum SplineEnds {
    /// Zero second derivative at both ends.
    Natural,
    /// Continuous third derivative at the second and the second-to-last knots.
    #[default]
    NotAKnot,
}

/// Interpolating cubic spline on uniformly spaced samples (knot `i` at `t0 + i / rate`).
#[derive(Debug, Clone, PartialEq)]
pub struct CubicSpline {
    pub t0: f64,
    pub sample_rate_hz: f64,
    pub y: Vec<f64>,
    /// Second derivatives at the knots.
    pub m: Vec<f64>,
}

impl CubicSpline {
    /// Interpolates `y` (at least 2 samples; not-a-knot needs 4, otherwise natural is used).
    pub fn new(y: &[f64], t0: f64, sample_rate_hz: f64, ends: SplineEnds) -> CubicSpline {
        let n = y.len();
        let h = 1.0 / sample_rate_hz;
        let mut m = vec![0.0; n];
        if n >= 3 {
            // Unknowns M_1..M_{n-2}: M_{i-1} + 4 M_i + M_{i+1} = 6 (y_{i+1} - 2 y_i + y_{i-1}) / h^2.
            let k = n - 2;
            let mut diag = vec![4.0; k];
            let mut lower = vec![1.0; k];
            let mut upper = vec![1.0; k];
            let mut rhs: Vec<f64> = (1..n - 1)
                .map(|i| 6.0 * (y[i + 1] - 2.0 * y[i] + y[i - 1]) / (h * h))
                .collect();
            let not_a_knot = ends == SplineEnds::NotAKnot && n >= 4;
            if not_a_knot {
                // M_0 = 2 M_1 - M_2 and M_{n-1} = 2 M_{n-2} - M_{n-3}: the first and last rows
                // become 6 M_1 = rhs_1 and 6 M_{n-2} = rhs_{n-2}.
                diag[0] = 6.0;
                upper[0] = 0.0;
                diag[k - 1] = 6.0;
                lower[k - 1] = 0.0;
            }
            // Thomas algorithm.
            for i in 1..k {
                let w = lower[i] / diag[i - 1];
                diag[i] -= w * upper[i - 1];
                rhs[i] -= w * rhs[i - 1];
            }
            let mut sol = vec![0.0; k];
            sol[k - 1] = rhs[k - 1] / diag[k - 1];
            for i in (0..k - 1).rev() {
                sol[i] = (rhs[i] - upper[i] * sol[i + 1]) / diag[i];
            }
            m[1..n - 1].copy_from_slice(&sol);
            if not_a_knot {
                m[0] = 2.0 * m[1] - m[2];
                m[n - 1] = 2.0 * m[n - 2] - m[n - 3];
            }
        }
        CubicSpline {
            t0,
            sample_rate_hz,
            y: y.to_vec(),
            m,
        }
    }

    /// Index of the interval that contains `t_ref` (clamped to the data).
    #[inline]
    pub(crate) fn interval(&self, t_ref: f64) -> usize {
        let n = self.y.len();
        if n < 2 {
            return 0;
        }
        // Truncation is the floor of a non-negative number (and NaN gives 0 as before); `floor`
        // is a libm call on x86-64, made four times per RK4 sub-step of a replay.
        let x = (t_ref - self.t0) * self.sample_rate_hz;
        if x < 0.0 { 0 } else { (x as usize).min(n - 2) }
    }

    /// Value and derivatives at `t`, using the cubic of the interval that contains `t_ref`.
    /// Inlined: a force input uses the value alone, and the derivatives are then not computed.
    #[inline]
    pub fn eval(&self, t: f64, t_ref: f64) -> Derivs {
        let n = self.y.len();
        if n == 0 {
            return Derivs::default();
        }
        if n == 1 {
            return Derivs {
                value: self.y[0],
                d1: 0.0,
                d2: 0.0,
            };
        }
        let i = self.interval(t_ref);
        let h = 1.0 / self.sample_rate_hz;
        let u = t - (self.t0 + i as f64 * h);
        let w = h - u;
        let (m0, m1, y0, y1) = (self.m[i], self.m[i + 1], self.y[i], self.y[i + 1]);
        let value = m0 * w * w * w / (6.0 * h)
            + m1 * u * u * u / (6.0 * h)
            + (y0 / h - m0 * h / 6.0) * w
            + (y1 / h - m1 * h / 6.0) * u;
        let d1 = -m0 * w * w / (2.0 * h) + m1 * u * u / (2.0 * h) - (y0 / h - m0 * h / 6.0)
            + (y1 / h - m1 * h / 6.0);
        let d2 = m0 * w / h + m1 * u / h;
        Derivs { value, d1, d2 }
    }
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;

    #[test]
    fn spline_interpolates_and_is_c2() {
        let y: Vec<f64> = (0..50).map(|i| (0.3 * i as f64).sin()).collect();
        for ends in [SplineEnds::Natural, SplineEnds::NotAKnot] {
            let s = CubicSpline::new(&y, 0.0, 10.0, ends);
            for i in 1..49 {
                let t = i as f64 / 10.0;
                let (l, r) = (s.eval(t, t - 0.05), s.eval(t, t + 0.05));
                assert!((l.value - y[i]).abs() < 1e-12 && (r.value - y[i]).abs() < 1e-12);
                assert!((l.d1 - r.d1).abs() < 1e-9 && (l.d2 - r.d2).abs() < 1e-9);
            }
        }
        // Not-a-knot reproduces a cubic exactly.
        let y: Vec<f64> = (0..20)
            .map(|i| (i as f64 * 0.1).powi(3) - 0.5 * i as f64 * 0.1)
            .collect();
        let s = CubicSpline::new(&y, 0.0, 10.0, SplineEnds::NotAKnot);
        let d = s.eval(0.05, 0.05);
        assert!((d.d2 - 6.0 * 0.05).abs() < 1e-9, "{}", d.d2);
    }
}
