//! The exact step of a [`Linear2`] system over an interval where its forcing is affine in time.
//!
//! A replay drives the rig with the second derivative of a cubic spline, which is linear in
//! time between two samples; with a linear element and friction of constant level the forcing
//! `u` of `x' = v, v' = -a x - b v + u(t)` is then affine over a whole sample interval, and the
//! state after the interval is exactly `Phi y + g0 u(t0) + g1 (u(t1) - u(t0))`. With scaled time
//! `s = (t - t0) / h`, `z = (x, v, u, u(t1) - u(t0))` obeys `z' = M z`, `M = [[0, h, 0, 0],
//! [-a h, -b h, h, 0], [0, 0, 0, 1], [0, 0, 0, 0]]`, so the first two rows of `exp(M)` are
//! `[Phi, g0, g1]`. One such step replaces the `h / 0.1 ms` RK4 sub-steps of the interval
//! (whose own error, about 1e-13 of the signal, is what separates the two).

use nalgebra::Matrix4;

use super::linear_step::Linear2;

/// The step over an interval of one length of one [`Linear2`] system.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ExactStep {
    phi: [[f64; 2]; 2],
    g0: [f64; 2],
    g1: [f64; 2],
}

impl ExactStep {
    pub fn new(sys: Linear2, h: f64) -> ExactStep {
        let (a, b) = (sys.stiffness_per_kg, sys.damping_per_kg);
        #[rustfmt::skip]
        let m = Matrix4::new(
            0.0, h, 0.0, 0.0,
            -a * h, -b * h, h, 0.0,
            0.0, 0.0, 0.0, 1.0,
            0.0, 0.0, 0.0, 0.0,
        );
        let e = m.exp();
        ExactStep {
            phi: [[e[(0, 0)], e[(0, 1)]], [e[(1, 0)], e[(1, 1)]]],
            g0: [e[(0, 2)], e[(1, 2)]],
            g1: [e[(0, 3)], e[(1, 3)]],
        }
    }

    /// The state after the interval from `y`, with the forcing at its start and its end.
    #[inline]
    pub fn apply(&self, y: [f64; 2], u0: f64, u1: f64) -> [f64; 2] {
        let du = u1 - u0;
        std::array::from_fn(|i| {
            self.phi[i][0] * y[0] + self.phi[i][1] * y[1] + self.g0[i] * u0 + self.g1[i] * du
        })
    }
}

/// True when `dir * v` stays positive over an interval of length `h` of `x' = v,
/// v' = -a x - b v + u(t)` that starts at `(x0, v0)` and ends at `(x1, v1)` with forcing
/// `u0`, `u1` (affine between): both ends positive by more than `h^2 / 8` times twice a bound
/// on `|v''|` (a function dips below the chord between its ends by at most `h^2 / 8` times
/// the largest `|f''|`). Otherwise the interval is sub-stepped with event location.
pub(crate) fn slip_holds(
    sys: Linear2,
    h: f64,
    dir: f64,
    [x0, v0]: [f64; 2],
    [x1, v1]: [f64; 2],
    [u0, u1]: [f64; 2],
) -> bool {
    let (a, b) = (sys.stiffness_per_kg, sys.damping_per_kg);
    let low = (dir * v0).min(dir * v1);
    if low.is_nan() || low <= 0.0 {
        return false;
    }
    let acc0 = -a * x0 - b * v0 + u0;
    let acc1 = -a * x1 - b * v1 + u1;
    // Bounds over the interval: each end's value doubled, plus what the ends' jerk moves.
    let du = (u1 - u0).abs() / h;
    let vel_end = v0.abs().max(v1.abs());
    let acc = 2.0 * acc0.abs().max(acc1.abs()) + h * (a * vel_end + du);
    let vel = vel_end + h * acc;
    let jerk = a * vel + b * acc + du;
    low > 2.0 * jerk * h * h / 8.0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The exact response of an underdamped `x'' + b x' + a x = u0 + r t` from (x0, v0): the
    /// particular solution `p + q t` plus the free response of the difference.
    fn closed_form(sys: Linear2, y0: [f64; 2], u0: f64, r: f64, t: f64) -> [f64; 2] {
        let (a, b) = (sys.stiffness_per_kg, sys.damping_per_kg);
        let q = r / a;
        let p = (u0 - b * q) / a;
        let (c0, d0) = (y0[0] - p, y0[1] - q);
        let sigma = -b / 2.0;
        let wd = (a - sigma * sigma).sqrt();
        let (s, c) = (wd * t).sin_cos();
        let e = (sigma * t).exp();
        let k2 = (d0 - sigma * c0) / wd;
        let x = e * (c0 * c + k2 * s);
        let v = e * (sigma * (c0 * c + k2 * s) + wd * (-c0 * s + k2 * c));
        [p + q * t + x, q + v]
    }

    #[test]
    fn the_step_is_the_closed_form() {
        let sys = Linear2 {
            stiffness_per_kg: 6380.0 / 36.0,
            damping_per_kg: 184.0 / 36.0,
        };
        let y0 = [0.004, -0.07];
        let (u0, r) = (-0.3417, 21.0);
        for h in [1e-4, 1e-2, 0.1, 1.0] {
            let got = ExactStep::new(sys, h).apply(y0, u0, u0 + r * h);
            let want = closed_form(sys, y0, u0, r, h);
            for i in 0..2 {
                assert!(
                    (got[i] - want[i]).abs() <= 1e-13 * want[i].abs().max(0.01),
                    "h {h}: {got:?} vs {want:?}"
                );
            }
        }
    }

    #[test]
    fn a_velocity_near_zero_is_not_trusted() {
        let sys = Linear2 {
            stiffness_per_kg: 177.0,
            damping_per_kg: 5.0,
        };
        // Positive at both ends but small against what the acceleration can do in 10 ms.
        assert!(!slip_holds(
            sys,
            0.01,
            1.0,
            [0.0, 1e-4],
            [0.0, 1e-4],
            [3.0, 3.0]
        ));
        assert!(!slip_holds(
            sys,
            0.01,
            1.0,
            [0.0, 0.1],
            [0.0, -0.1],
            [0.0, 0.0]
        ));
        assert!(slip_holds(
            sys,
            0.01,
            1.0,
            [0.0, 0.1],
            [0.0, 0.1],
            [0.3, 0.3]
        ));
        assert!(slip_holds(
            sys,
            0.01,
            -1.0,
            [0.0, -0.1],
            [0.0, -0.1],
            [0.3, 0.3]
        ));
    }
}
