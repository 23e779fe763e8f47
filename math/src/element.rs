//! The nonlinear element as the truth simulators and the model simulators see it.
//!
//! The force splits into a single-valued part `smooth_force(x, v, z)` (z: internal states such
//! as Bouc-Wen's) and an optional set-valued Coulomb-type friction: while the relative velocity
//! is zero the friction is whatever keeps it zero, up to `breakaway_n`; while slipping it is
//! `sgn(v) * slip_force_n(|v|)`. Simulators treat the stick phase exactly, with no
//! regularisation.

use std::sync::Arc;

use crate::basis::{StribeckVelocity, Term};

/// The exponent of the Gaussian Stribeck law exp(-(v/vs)^2).
pub const GAUSSIAN_STRIBECK_EXPONENT: f64 = 2.0;

/// How a Stribeck excess has decayed at speed `v`: exp(-|v / velocity_mps|^exponent), 1 at
/// v = 0 and e^-1 at |v| = velocity_mps whatever the exponent. The Gaussian exponent squares
/// (bit for bit the law before the exponent was a parameter); the diagnosis's other exponents,
/// 1 and 0.5, take the absolute value and the square root: `powf` was a third of the CPU of an
/// output-error refit with exponent 0.5 (perf, wide seed 1 case 88).
#[allow(
    clippy::float_cmp,
    reason = "exponents 1 and 0.5 exactly are the laws with a cheaper form"
)]
pub fn stribeck_decay(v: f64, velocity_mps: f64, exponent: f64) -> f64 {
    let u = (v / velocity_mps).abs();
    let power = if is_gaussian_stribeck(exponent) {
        u * u
    } else if exponent == 1.0 {
        u
    } else if exponent == 0.5 {
        u.sqrt()
    } else {
        u.powf(exponent)
    };
    (-power).exp()
}

/// Whether a Stribeck shape exponent is the Gaussian law's, exactly: only then is the decay
/// squared (and written, and stored, as before the exponent was a parameter).
#[allow(
    clippy::float_cmp_const,
    reason = "the Gaussian law is the exponent 2 exactly; any other value is another law"
)]
pub fn is_gaussian_stribeck(exponent: f64) -> bool {
    exponent == GAUSSIAN_STRIBECK_EXPONENT
}

/// Coulomb-type friction law with a stick phase.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Friction {
    /// Largest friction force the element can hold while stuck [N].
    pub breakaway_n: f64,
    /// Kinetic (Coulomb) level at high speed [N].
    pub kinetic_n: f64,
    /// Stribeck: extra force at low speed decays as
    /// exp(-(|v|/stribeck_velocity)^stribeck_exponent) ([`stribeck_decay`]); with
    /// `breakaway_n == kinetic_n` this is plain Coulomb friction.
    pub stribeck_velocity_mps: f64,
    /// The Stribeck curve's shape exponent ([`GAUSSIAN_STRIBECK_EXPONENT`] for the Gaussian law).
    pub stribeck_exponent: f64,
    /// Asymmetry: the kinetic level for v > 0 is `kinetic_n * (1 + asymmetry)`, for v < 0
    /// `kinetic_n * (1 - asymmetry)`.
    pub asymmetry: f64,
}

impl Friction {
    pub fn coulomb(level_n: f64) -> Friction {
        Friction {
            breakaway_n: level_n,
            kinetic_n: level_n,
            stribeck_velocity_mps: 1.0,
            stribeck_exponent: GAUSSIAN_STRIBECK_EXPONENT,
            asymmetry: 0.0,
        }
    }

    /// Friction force while slipping at relative velocity `v` (v != 0) [N].
    pub fn slip_force_n(&self, v: f64) -> f64 {
        self.slip_force_toward_n(v, v.signum())
    }

    /// Slip friction with its direction frozen to `dir` (+1 or -1; equal to
    /// [`Friction::slip_force_n`] whenever `sgn(v) == dir`): the simulators hold the direction
    /// of a slip phase while a step brackets its end.
    pub fn slip_force_toward_n(&self, v: f64, dir: f64) -> f64 {
        let level = self.kinetic_n * (1.0 + dir * self.asymmetry);
        let stribeck = if self.breakaway_n > self.kinetic_n {
            (self.breakaway_n - self.kinetic_n)
                * stribeck_decay(v, self.stribeck_velocity_mps, self.stribeck_exponent)
        } else {
            0.0
        };
        dir * (level + stribeck)
    }

    /// The friction law of a fitted model's terms at `theta`: the kinetic level from the
    /// terms that jump at zero speed but the Stribeck excess (a negative level is no friction,
    /// held at zero), the breakaway above it by the Stribeck term's coefficient with its own
    /// law (velocity and exponent). None when no term jumps at zero speed.
    pub fn from_terms(terms: &[Arc<dyn Term>], theta: &[f64]) -> Option<Friction> {
        let mut kinetic = 0.0;
        let mut excess = 0.0;
        let mut law = StribeckVelocity::gaussian(1.0);
        let mut any = false;
        for (t, th) in terms.iter().zip(theta) {
            if !t.jumps_at_zero_velocity() {
                continue;
            }
            any = true;
            match t.stribeck() {
                Some(l) => {
                    excess += th;
                    law = l;
                }
                None => kinetic += th,
            }
        }
        any.then(|| {
            let kinetic_n = f64::max(kinetic, 0.0);
            Friction {
                breakaway_n: kinetic_n + f64::max(excess, 0.0),
                kinetic_n,
                stribeck_velocity_mps: law.velocity_mps,
                stribeck_exponent: law.exponent,
                asymmetry: 0.0,
            }
        })
    }
}

/// A nonlinear element: truth models and identified models implement this.
pub trait Element: Send + Sync {
    /// Single-valued part of the element force [N] at relative displacement `x` [m], relative
    /// velocity `v` [m/s] and internal states `z`.
    fn smooth_force(&self, x: f64, v: f64, z: &[f64]) -> f64;

    /// Set-valued friction, if any.
    fn friction(&self) -> Option<Friction> {
        None
    }

    /// Number of internal states (e.g. 1 for Bouc-Wen hysteresis).
    fn internal_states(&self) -> usize {
        0
    }

    /// Time derivatives of the internal states.
    fn internal_rates(&self, _x: f64, _v: f64, _z: &[f64], _dz: &mut [f64]) {}

    /// `Some((k, c))` when `smooth_force(x, v, z) == k x + c v` for every `x`, `v` and there are
    /// no internal states: the simulators then step the element as a linear map between events
    /// (the same RK4 step, without evaluating the element). None: unknown or nonlinear.
    fn linear_coefficients(&self) -> Option<(f64, f64)> {
        None
    }
}
