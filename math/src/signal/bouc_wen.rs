//! The Bouc-Wen hysteretic state z: its rate equation and its integration over a sampled
//! velocity.
//!
//! Three users: the truth simulator (`sim::truth`: the general law, z integrated as an ODE
//! state together with the mechanics by the simulator's own RK4 and events, so it uses the rate
//! only), the rig diagnosis (`diagnose::fit`: the one-parameter law over one period of steady
//! motion, [`steady_cycle`], of a member of the family [`HysteresisLaw`]) and the time-domain
//! diagnosis (`diagnose::time_domain`: the one-parameter law over a measured record,
//! [`integrate_record`]).

use serde::{Deserialize, Serialize};

/// Bouc-Wen hysteresis: force `alpha_n_per_m * z` with
/// `z' = a v - beta |v| |z|^(n-1) z - gamma v |z|^n` (z in m).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BoucWen {
    pub alpha_n_per_m: f64,
    pub a: f64,
    /// [1/m^n]
    pub beta: f64,
    /// [1/m^n]
    pub gamma: f64,
    pub n: f64,
}

impl BoucWen {
    /// The rate z' of the general law at state `z` and velocity `v`.
    pub fn rate(&self, z: f64, v: f64) -> f64 {
        let az = z.abs();
        let azn = az.powf(self.n);
        // |z|^(n-1) z = sgn(z) |z|^n.
        self.a * v - self.beta * v.abs() * z.signum() * azn - self.gamma * v * azn
    }
}

/// The rate of the one-parameter law the diagnoses fit: a = 1, n = 1,
/// beta = gamma = 1 / (2 zy), written `z' = v - (|v| z + v |z|) / (2 zy)`, so z rises like x
/// after a reversal and saturates at +/- zy (`yield_m`).
///
/// Why it exists beside [`BoucWen::rate`]: it is that law with those parameters, but rounded
/// differently (one division by 2 zy instead of multiplications by beta and gamma); the
/// diagnoses' results were computed with this form.
pub fn yield_rate(z: f64, v: f64, yield_m: f64) -> f64 {
    v - (v.abs() * z + v * z.abs()) / (2.0 * yield_m)
}

/// The largest RK4 sub-step of [`HysteresisLaw::integrate_record`], in distance travelled, as a
/// fraction of the yield displacement: the state's error stays below 1e-5 of the yield at the
/// sharpest shape searched (n = 2, r = 0.85, against its closed form: 1.6e-6 where z crosses
/// zero inside a sub-step), far below what the sampled velocity leaves.
pub const ARC_STEP_PER_YIELD: f64 = 1.0 / 16.0;

/// How close to the yield, as a fraction of it, the state counts as saturated (where the rest of
/// a stretch in one direction leaves it unchanged to rounding).
const SATURATED_WITHIN: f64 = 1e-13;

/// The names of a law's exponent n and share r among a fit's parameters.
pub const EXPONENT_NAME: &str = "bouc_wen_n";
pub const SHARE_NAME: &str = "bouc_wen_r";

/// A member of the Bouc-Wen family the diagnoses fit: a = 1, yield displacement zy
/// (`yield_m`), exponent n and r = beta / (beta + gamma), with beta = r / zy^n and
/// gamma = (1 - r) / zy^n so that z saturates at +/- zy whatever the shape. The one-parameter
/// law ([`yield_rate`]) is the member n = 1, r = 1/2 ([`HysteresisLaw::yield_law`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct HysteresisLaw {
    pub yield_m: f64,
    pub n: f64,
    pub r: f64,
}

impl HysteresisLaw {
    /// The shape (n, r) of the one-parameter law.
    pub const YIELD_LAW_SHAPE: (f64, f64) = (1.0, 0.5);

    /// The one-parameter law with yield displacement `yield_m`.
    pub fn yield_law(yield_m: f64) -> Self {
        let (n, r) = Self::YIELD_LAW_SHAPE;
        HysteresisLaw { yield_m, n, r }
    }

    /// The yield displacement when this is the one-parameter law; None for any other shape.
    /// The paths that integrate only that law ([`integrate_record`]) take their yield from
    /// here, so a shape is never silently dropped.
    pub fn one_parameter_yield_m(&self) -> Option<f64> {
        ((self.n, self.r) == Self::YIELD_LAW_SHAPE).then_some(self.yield_m)
    }

    /// The general law's parameters with force coefficient `alpha_n_per_m`.
    pub fn bouc_wen(&self, alpha_n_per_m: f64) -> BoucWen {
        let scale = self.yield_m.powf(-self.n);
        BoucWen {
            alpha_n_per_m,
            a: 1.0,
            beta: self.r * scale,
            gamma: (1.0 - self.r) * scale,
            n: self.n,
        }
    }

    /// The law's state at each sample of a record of velocity `velocity_mps` sampled at step
    /// `dt`, from z = 0 at the first sample ([`integrate_record`] for the one-parameter law).
    ///
    /// The velocity is taken linear between samples, so each interval moves the element by the
    /// trapezoid of its end velocities, split where the velocity changes sign. The law is rate
    /// independent (z' is v times a function of z and the sign of v), so over a stretch of one
    /// direction z follows the displacement alone: it is integrated in the distance travelled,
    /// by RK4 sub-steps of at most [`ARC_STEP_PER_YIELD`] of the yield, however coarse the
    /// sampling is against the yield (at a damper dyno's 200 Hz a 5 Hz stroke moves more than
    /// the yield between two samples). Once z has reached the yield in the direction of motion
    /// it stays there until the motion reverses, and the rest of the stretch is not stepped.
    pub fn integrate_record(&self, velocity_mps: &[f64], dt: f64) -> Vec<f64> {
        let mut z = 0.0;
        let mut out = Vec::with_capacity(velocity_mps.len());
        if !velocity_mps.is_empty() {
            out.push(z);
        }
        for w in velocity_mps.windows(2) {
            let (v0, v1) = (w[0], w[1]);
            if v0 * v1 < 0.0 {
                // The sign change at a fraction `at` of the interval.
                let at = v0 / (v0 - v1);
                z = self.travel(z, v0.signum(), 0.5 * v0.abs() * at * dt);
                z = self.travel(z, v1.signum(), 0.5 * v1.abs() * (1.0 - at) * dt);
            } else {
                let v = 0.5 * (v0 + v1);
                z = self.travel(z, v.signum(), v.abs() * dt);
            }
            out.push(z);
        }
        out
    }

    /// The state after travelling `distance_m` (>= 0) in `direction` (+1 or -1) from state
    /// `z`: dz/ds = rate(z, direction), the rate per unit of velocity.
    fn travel(&self, mut z: f64, direction: f64, distance_m: f64) -> f64 {
        if distance_m <= 0.0 || !distance_m.is_finite() {
            return z;
        }
        let sub_steps = (distance_m / (ARC_STEP_PER_YIELD * self.yield_m)).ceil();
        if !sub_steps.is_finite() {
            // No positive yield: the law has no state.
            return f64::NAN;
        }
        let h = distance_m / sub_steps;
        let saturated = direction * self.yield_m;
        let f = |z: f64| self.rate(z, direction);
        for _ in 0..sub_steps as usize {
            if (z - saturated).abs() <= SATURATED_WITHIN * self.yield_m {
                break;
            }
            let k1 = f(z);
            let k2 = f(z + 0.5 * h * k1);
            let k3 = f(z + 0.5 * h * k2);
            let k4 = f(z + h * k3);
            z += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
        }
        z
    }

    /// The rate z' at state `z` and velocity `v`: [`yield_rate`] for the one-parameter law
    /// (the diagnoses' results were computed with its rounding), else the general law.
    pub fn rate(&self, z: f64, v: f64) -> f64 {
        match self.one_parameter_yield_m() {
            Some(zy) => yield_rate(z, v, zy),
            None => {
                // |z|^n / zy^n, with the common exponents computed without powf (the rig
                // search integrates many cycles).
                let u = z.abs() / self.yield_m;
                let un = if self.n == 2.0 {
                    u * u
                } else if self.n == 1.0 {
                    u
                } else {
                    u.powf(self.n)
                };
                v - (self.r * v.abs() * z.signum() + (1.0 - self.r) * v) * un
            }
        }
    }
}

/// The state of `law` over one period of steady motion with velocity `velocity_mps` on a
/// uniform grid of period `period_s`. Three periods are integrated from z = 0 and the last one
/// returned (the cycle has settled by then): RK4 with 8 sub-steps per grid interval, the
/// velocity interpolated linearly over the interval (wrapping around the period).
///
/// Why it exists beside [`integrate_record`]: a rebuilt cycle of the rig path is short (a few
/// hundred points per period) and periodic, so it is integrated accurately and to its steady
/// state; the time-domain path's record is long and densely sampled and is integrated once.
pub fn steady_cycle(velocity_mps: &[f64], period_s: f64, law: &HysteresisLaw) -> Vec<f64> {
    let l = velocity_mps.len();
    let dt = period_s / l as f64;
    let sub = 8;
    let h = dt / sub as f64;
    let rate = |z: f64, v: f64| law.rate(z, v);
    let mut z = 0.0;
    let mut out = vec![0.0; l];
    for pass in 0..3 {
        for i in 0..l {
            if pass == 2 {
                out[i] = z;
            }
            let (v0, v1) = (velocity_mps[i], velocity_mps[(i + 1) % l]);
            for s in 0..sub {
                let a = s as f64 / sub as f64;
                let b = (s as f64 + 0.5) / sub as f64;
                let c = (s as f64 + 1.0) / sub as f64;
                let va = v0 + (v1 - v0) * a;
                let vb = v0 + (v1 - v0) * b;
                let vc = v0 + (v1 - v0) * c;
                // RK4 with the velocity interpolated linearly over the grid interval.
                let k1 = rate(z, va);
                let k2 = rate(z + 0.5 * h * k1, vb);
                let k3 = rate(z + 0.5 * h * k2, vb);
                let k4 = rate(z + h * k3, vc);
                z += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
            }
        }
    }
    out
}

/// [`yield_rate`]'s state over a sampled record of velocity `velocity_mps` at step `dt`, from
/// z = 0 ([`HysteresisLaw::integrate_record`] of the one-parameter law).
///
/// Why it exists beside [`steady_cycle`]: the time-domain path's records are not periodic and
/// start from rest, so they are integrated once from their start, not to a steady cycle.
pub fn integrate_record(velocity_mps: &[f64], dt: f64, yield_m: f64) -> Vec<f64> {
    HysteresisLaw::yield_law(yield_m).integrate_record(velocity_mps, dt)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// The one-parameter law in closed form along x = A sin(w t): after a reversal z moves
    /// with x until it crosses zero (rate v there, since |v| z + v |z| = 0 for z against the
    /// motion), then approaches the yield as zy (1 - exp(-s / zy)) in the distance s since.
    fn yield_law_closed_form(t: f64, amp_m: f64, w: f64, zy: f64) -> f64 {
        // Start at rest at x = 0 moving up: z = 0 at t = 0; reversals at w t = pi/2 + k pi.
        let phase = w * t;
        let x = |p: f64| amp_m * p.sin();
        let quarter = std::f64::consts::FRAC_PI_2;
        if phase <= quarter {
            return zy * (1.0 - (-x(phase) / zy).exp());
        }
        // z at the first reversal, then each half period from the reversal before.
        let mut z = zy * (1.0 - (-amp_m / zy).exp());
        let mut reversal = quarter;
        loop {
            let next = reversal + std::f64::consts::PI;
            let dir = -z.signum();
            let s_end = if phase <= next {
                (x(phase) - x(reversal)).abs()
            } else {
                2.0 * amp_m
            };
            // Back to zero with the motion, then the exponential rise in direction `dir`.
            let z_end = if s_end <= z.abs() {
                z + dir * s_end
            } else {
                dir * zy * (1.0 - (-(s_end - z.abs()) / zy).exp())
            };
            if phase <= next {
                return z_end;
            }
            z = z_end;
            reversal = next;
        }
    }

    #[test]
    fn travel_matches_the_closed_form_of_the_sharpest_shape() {
        // n = 2, r = 0.85 moving up: against the motion (z < 0) dz/ds = 1 + 0.7 (z/zy)^2, a
        // tangent; with it (z > 0) dz/ds = 1 - (z/zy)^2, a hyperbolic tangent.
        let zy = 0.001;
        let law = HysteresisLaw {
            yield_m: zy,
            n: 2.0,
            r: 0.85,
        };
        let q = 0.7f64.sqrt();
        let to_zero = zy / q * (q * 1.0f64).atan();
        let exact = |s: f64| {
            if s <= to_zero {
                zy / q * (q * (s - to_zero) / zy).tan()
            } else {
                zy * ((s - to_zero) / zy).tanh()
            }
        };
        for s in [0.3 * zy, to_zero, 1.5 * zy, 3.0 * zy] {
            let z = law.travel(-zy, 1.0, s);
            let e = (z - exact(s)).abs();
            assert!(
                e < 1e-5 * zy,
                "{s}: {z} vs {} ({:.2e} of the yield)",
                exact(s),
                e / zy
            );
        }
    }

    #[test]
    fn the_record_state_matches_the_closed_form_at_coarse_sampling() {
        // A damper dyno's 200 Hz sampling of a 5 Hz, 2 mm stroke: 0.3 mm between samples at
        // the peak velocity, beside a yield of 0.25 mm.
        let (fs, f, amp, zy) = (200.0, 5.0, 0.002, 0.00025);
        let w = TAU * f;
        let n = 200;
        let v: Vec<f64> = (0..n)
            .map(|i| amp * w * (w * i as f64 / fs).cos())
            .collect();
        let z = HysteresisLaw::yield_law(zy).integrate_record(&v, 1.0 / fs);
        let worst = (0..n)
            .map(|i| (z[i] - yield_law_closed_form(i as f64 / fs, amp, w, zy)).abs())
            .fold(0.0f64, f64::max);
        // The velocity is taken linear between samples: the trapezoid's error in the distance,
        // (w dt)^2 / 12 of it per interval, is the bound, not the sub-steps (0.19 % of the
        // yield here).
        assert!(worst < 0.004 * zy, "worst {:.3e} of the yield", worst / zy);
        // The sharpest shape searched against the same law stepped 64 times finer.
        let law = HysteresisLaw {
            yield_m: zy,
            n: 2.0,
            r: 0.85,
        };
        let coarse = law.integrate_record(&v, 1.0 / fs);
        let fine_v: Vec<f64> = (0..64 * n)
            .map(|i| amp * w * (w * i as f64 / (64.0 * fs)).cos())
            .collect();
        let fine = law.integrate_record(&fine_v, 1.0 / (64.0 * fs));
        let worst = (0..n)
            .map(|i| (coarse[i] - fine[64 * i]).abs())
            .fold(0.0f64, f64::max);
        assert!(worst < 0.004 * zy, "worst {:.3e} of the yield", worst / zy);
        // Forward Euler, one step per sample, misses by 64 % of the yield here.
        let mut euler = 0.0;
        let worst_euler = (0..n)
            .map(|i| {
                let e = (euler - yield_law_closed_form(i as f64 / fs, amp, w, zy)).abs();
                euler += law.rate(euler, v[i]) / fs;
                e
            })
            .fold(0.0f64, f64::max);
        assert!(worst_euler > 0.5 * zy, "{worst_euler}");
    }

    #[test]
    fn bouc_wen_saturates_at_the_yield_displacement() {
        let l = 512;
        let period = 0.5;
        let amp = 0.01;
        let w = TAU / period;
        let v: Vec<f64> = (0..l)
            .map(|i| -amp * w * (TAU * i as f64 / l as f64).sin())
            .collect();
        let z = steady_cycle(&v, period, &HysteresisLaw::yield_law(0.001));
        let zmax = z.iter().fold(0.0f64, |m, z| m.max(z.abs()));
        assert!((zmax - 0.001).abs() < 2e-5, "{zmax}");
        // far from saturation (yield >> amplitude) z follows x - mean
        let z = steady_cycle(&v, period, &HysteresisLaw::yield_law(10.0));
        let x0 = z[0] - z[l / 2];
        assert!((x0 - 2.0 * amp).abs() < 1e-4 * amp * 100.0, "{x0}");
    }

    #[test]
    fn the_general_rate_with_the_yield_parameters_is_the_yield_rate() {
        let zy = 0.002;
        let bw = BoucWen {
            alpha_n_per_m: 1.0,
            a: 1.0,
            beta: 1.0 / (2.0 * zy),
            gamma: 1.0 / (2.0 * zy),
            n: 1.0,
        };
        for (z, v) in [(0.001, 0.3), (-0.0015, 0.3), (0.0005, -1.2), (0.0, 2.0)] {
            let (g, y) = (bw.rate(z, v), yield_rate(z, v, zy));
            assert!((g - y).abs() <= 1e-12 * v.abs(), "{z} {v}: {g} vs {y}");
        }
    }

    #[test]
    fn the_family_member_at_the_yield_shape_is_the_yield_law() {
        let zy = 0.002;
        let law = HysteresisLaw::yield_law(zy);
        let general = HysteresisLaw {
            // Not the yield law's shape by one ulp: the general branch.
            n: 1.0 + f64::EPSILON,
            ..law
        };
        for (z, v) in [(0.001, 0.3), (-0.0015, 0.3), (0.0005, -1.2), (0.0, 2.0)] {
            let y = yield_rate(z, v, zy);
            assert_eq!(law.rate(z, v).to_bits(), y.to_bits());
            let g = general.rate(z, v);
            assert!((g - y).abs() <= 1e-12 * v.abs(), "{z} {v}: {g} vs {y}");
        }
    }

    #[test]
    fn every_shape_agrees_with_the_general_law_and_saturates_at_the_yield() {
        let zy = 0.003;
        for (n, r) in [(0.75, 0.5), (2.0, 0.85), (1.0, 0.85), (2.5, 0.6)] {
            let law = HysteresisLaw { yield_m: zy, n, r };
            let bw = law.bouc_wen(1.0);
            for (z, v) in [(0.001, 0.3), (-0.0025, 0.3), (0.0005, -1.2), (-0.002, -0.7)] {
                let (a, b) = (law.rate(z, v), bw.rate(z, v));
                assert!(
                    (a - b).abs() <= 1e-12 * v.abs(),
                    "{n} {r} {z} {v}: {a} vs {b}"
                );
            }
            // Rising past the yield the rate vanishes at z = zy (closed form of the family).
            assert!(law.rate(zy, 0.5).abs() < 1e-12, "{n} {r}");
            // And the steady cycle of a motion 10 zy in amplitude reaches it.
            let (l, period, amp) = (512, 0.5, 10.0 * zy);
            let w = TAU / period;
            let v: Vec<f64> = (0..l)
                .map(|i| -amp * w * (TAU * i as f64 / l as f64).sin())
                .collect();
            let z = steady_cycle(&v, period, &law);
            let zmax = z.iter().fold(0.0f64, |m, z| m.max(z.abs()));
            assert!(
                zmax < zy * (1.0 + 1e-6) && zmax > 0.95 * zy,
                "{n} {r}: {zmax}"
            );
        }
    }
}
