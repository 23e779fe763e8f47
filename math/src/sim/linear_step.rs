//! The RK4 sub-step of a system that is linear between events, as a linear map.
//!
//! Between stick-slip events the rig with a linear element (`k x + c v`, friction of constant
//! level or none) is `x' = v, v' = -a x - b v + u(t)`. One classic RK4 step of length h from
//! y is then exactly `P y + q0 u(t) + qh u(t + h/2) + q1 u(t + h)`, with P and the q's
//! polynomials of `M = hA` (expand the four stages): the same step as the generic RK4 up to
//! rounding, without evaluating the element four times, and `u(t + h)` is the next step's
//! `u(t)`, so a sub-step costs two evaluations of the input instead of four of everything.

/// `x' = v, v' = -stiffness_per_kg x - damping_per_kg v + u(t)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Linear2 {
    pub stiffness_per_kg: f64,
    pub damping_per_kg: f64,
}

/// One RK4 step of a fixed length of a [`Linear2`] system.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LinearStep {
    p: [[f64; 2]; 2],
    q0: [f64; 2],
    qh: [f64; 2],
    q1: [f64; 2],
}

fn mul(a: [[f64; 2]; 2], b: [[f64; 2]; 2]) -> [[f64; 2]; 2] {
    let mut c = [[0.0; 2]; 2];
    for i in 0..2 {
        for j in 0..2 {
            c[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j];
        }
    }
    c
}

impl LinearStep {
    pub fn new(sys: Linear2, h: f64) -> LinearStep {
        let m = [
            [0.0, h],
            [-sys.stiffness_per_kg * h, -sys.damping_per_kg * h],
        ];
        let m2 = mul(m, m);
        let m3 = mul(m2, m);
        let m4 = mul(m3, m);
        let id = |i: usize, j: usize| if i == j { 1.0 } else { 0.0 };
        let mut p = [[0.0; 2]; 2];
        for i in 0..2 {
            for j in 0..2 {
                p[i][j] = id(i, j) + m[i][j] + m2[i][j] / 2.0 + m3[i][j] / 6.0 + m4[i][j] / 24.0;
            }
        }
        // The forcing enters v' only: column 1 of the stage polynomials.
        let mut q0 = [0.0; 2];
        let mut qh = [0.0; 2];
        let mut q1 = [0.0; 2];
        for i in 0..2 {
            q0[i] = h * (id(i, 1) / 6.0 + m[i][1] / 6.0 + m2[i][1] / 12.0 + m3[i][1] / 24.0);
            qh[i] = h * (2.0 * id(i, 1) / 3.0 + m[i][1] / 3.0 + m2[i][1] / 12.0);
            q1[i] = h * id(i, 1) / 6.0;
        }
        LinearStep { p, q0, qh, q1 }
    }

    /// The state after the step from `y`, with the forcing at the start, the middle and the
    /// end of the step.
    #[inline]
    pub fn apply(&self, y: [f64; 2], u0: f64, uh: f64, u1: f64) -> [f64; 2] {
        let mut out = [0.0; 2];
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.p[i][0] * y[0]
                + self.p[i][1] * y[1]
                + self.q0[i] * u0
                + self.qh[i] * uh
                + self.q1[i] * u1;
        }
        out
    }
}

/// The [`LinearStep`]s of one system for every sub-step length met: at 10 kHz the sample
/// intervals `(i + 1) / fs - i / fs` take a few dozen lengths that differ in their last bits,
/// and one remembered step was rebuilt every few samples. Direct-mapped on a hash of the
/// length.
#[derive(Debug, Clone)]
pub(crate) struct LinearSteps {
    sys: Option<Linear2>,
    slots: Vec<Option<(f64, LinearStep)>>,
}

impl Default for LinearSteps {
    fn default() -> Self {
        LinearSteps {
            sys: None,
            slots: vec![None; Self::SLOTS],
        }
    }
}

impl LinearSteps {
    const SLOTS: usize = 64;

    /// The step of `sys` of length `h`, built if not met before.
    #[inline]
    pub fn get(&mut self, sys: Linear2, h: f64) -> &LinearStep {
        if self.sys != Some(sys) {
            self.sys = Some(sys);
            self.slots.fill(None);
        }
        // Fibonacci hashing of all the bits: the lengths differ by multiples of the sample
        // times' ulp, about 2^16 of the length's own, so its lowest bits are all alike.
        let slot = (h.to_bits().wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 58) as usize;
        let slot = &mut self.slots[slot];
        if !matches!(slot, Some((hh, _)) if *hh == h) {
            *slot = Some((h, LinearStep::new(sys, h)));
        }
        let (_, step) = slot.as_ref().expect("the slot holds the step of length h");
        step
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The classic RK4 step, written out stage by stage.
    fn rk4(sys: Linear2, u: impl Fn(f64) -> f64, t: f64, y: [f64; 2], h: f64) -> [f64; 2] {
        let f = |t: f64, y: [f64; 2]| {
            [
                y[1],
                -sys.stiffness_per_kg * y[0] - sys.damping_per_kg * y[1] + u(t),
            ]
        };
        let k1 = f(t, y);
        let k2 = f(
            t + h / 2.0,
            [y[0] + h / 2.0 * k1[0], y[1] + h / 2.0 * k1[1]],
        );
        let k3 = f(
            t + h / 2.0,
            [y[0] + h / 2.0 * k2[0], y[1] + h / 2.0 * k2[1]],
        );
        let k4 = f(t + h, [y[0] + h * k3[0], y[1] + h * k3[1]]);
        [
            y[0] + h / 6.0 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]),
            y[1] + h / 6.0 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]),
        ]
    }

    /// The remembered steps are those built afresh, to the bit, for every length and after a
    /// change of system.
    #[test]
    fn a_remembered_step_is_the_step_of_its_length() {
        let a = Linear2 {
            stiffness_per_kg: 6380.0 / 36.0,
            damping_per_kg: 184.0 / 36.0,
        };
        let b = Linear2 {
            stiffness_per_kg: 2.0 * a.stiffness_per_kg,
            ..a
        };
        let mut steps = LinearSteps::default();
        for round in 0..3 {
            for sys in [a, b] {
                for i in 0..200_u32 {
                    let h = f64::from(i + 1) / 10_000.0 - f64::from(i) / 10_000.0
                        + f64::from(round) * 1e-6;
                    assert_eq!(*steps.get(sys, h), LinearStep::new(sys, h), "{h:e}");
                }
            }
        }
    }

    #[test]
    fn the_linear_map_is_the_rk4_step() {
        let sys = Linear2 {
            stiffness_per_kg: 6380.0 / 36.0,
            damping_per_kg: 184.0 / 36.0,
        };
        let u = |t: f64| -0.3417 - 2.1 * (17.0 * t + 0.4).sin();
        // Large steps too, where the higher powers of hA matter.
        for h in [1e-4, 1e-2, 0.1] {
            let step = LinearStep::new(sys, h);
            let mut a = [0.004, -0.07];
            let mut b = a;
            let mut t = 0.3;
            for _ in 0..50 {
                a = rk4(sys, u, t, a, h);
                b = step.apply(b, u(t), u(t + h / 2.0), u(t + h));
                t += h;
            }
            for i in 0..2 {
                assert!(
                    (a[i] - b[i]).abs() <= 1e-13 * a[i].abs().max(1e-3),
                    "h {h}: {a:?} vs {b:?}"
                );
            }
        }
    }
}
