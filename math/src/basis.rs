//! Basis functions h_i(x, x') of the element force (eq. 4): g(x, x') = sum_i theta_i h_i(x, x').
//!
//! Each term is a `Term`; a model (see `model`) is a named list of terms. To add a term,
//! implement `Term` (a symbol, an evaluation, and whether it jumps where the velocity changes
//! sign) and use it in a `Model`.

use std::f64::consts::FRAC_2_PI;
use std::fmt::Debug;

/// One basis function of the element force.
pub trait Term: Debug + Send + Sync {
    /// The parameter symbol of this term's coefficient, in the paper's lower-case names
    /// (k, c, fd, s, ...).
    fn symbol(&self) -> String;
    /// A readable formula, e.g. "sgn(x')".
    fn formula(&self) -> String;
    /// h(x, v) at relative displacement `x` [m] and velocity `v` [m/s].
    fn eval(&self, x: f64, v: f64) -> f64;
    /// True when h jumps where v changes sign (sgn-like). Such a term stands for Coulomb
    /// friction: the truth force is set-valued while the element sticks, so equations taken
    /// near v = 0 cannot be trusted and the model simulator treats the stick phase exactly.
    fn jumps_at_zero_velocity(&self) -> bool {
        false
    }
    /// True for a friction term (sgn or a smoothed sgn): the element it describes can stick,
    /// and while it sticks its force is set-valued, whatever smooth law the model uses, so the
    /// improved method does not fit the model to the stick phase.
    fn describes_friction(&self) -> bool {
        self.jumps_at_zero_velocity()
    }
    /// `Some((a, b))` when h(x, v) = a x + b v exactly (lets a model that is linear between
    /// stick-slip events be simulated as a linear map).
    fn linear_coefficients(&self) -> Option<(f64, f64)> {
        None
    }
    /// `Some(law)` for the Stribeck excess `sgn(x') exp(-|x'/vs|^delta)` (so that a simulator
    /// can give it the friction law's exact stick phase, with breakaway above the kinetic level).
    fn stribeck(&self) -> Option<StribeckVelocity> {
        None
    }
}

/// x: linear stiffness, coefficient k [N/m].
#[derive(Debug, Clone, Copy)]
pub struct Displacement;
/// x': viscous damping, coefficient c [N s/m].
#[derive(Debug, Clone, Copy)]
pub struct Velocity;
/// sgn(x'): Coulomb friction, coefficient fd [N].
#[derive(Debug, Clone, Copy)]
pub struct SignVelocity;
/// (2/pi) atan(M x'): smoothed Coulomb friction of slope M [s/m] at x' = 0, coefficient fd [N].
#[derive(Debug, Clone, Copy)]
pub struct AtanVelocity {
    pub slope_s_per_m: f64,
}
/// x^3: cubic stiffness, coefficient s [N/m^3].
#[derive(Debug, Clone, Copy)]
pub struct Cubic;
/// x^i x'^j: the generic polynomial family of eq. 2, coefficient p{i}{j}.
#[derive(Debug, Clone, Copy)]
pub struct Polynomial {
    pub i: u32,
    pub j: u32,
}
/// 1: a constant force offset [N].
#[derive(Debug, Clone, Copy)]
pub struct Constant;
/// x|x|: asymmetric (quadratic) stiffness, coefficient k2 [N/m^2].
#[derive(Debug, Clone, Copy)]
pub struct SignedSquareDisplacement;
/// x'|x'|: quadratic damping, coefficient c2 [N s^2/m^2].
#[derive(Debug, Clone, Copy)]
pub struct SignedSquareVelocity;
/// |x'|: asymmetric damping with c x' (rebound and compression coefficients c +/- ca),
/// coefficient ca [N s/m].
#[derive(Debug, Clone, Copy)]
pub struct AbsVelocity;

/// x^2: the asymmetric part of a quadratic stiffness (stiffer in tension than in compression
/// or the reverse), coefficient k2a [N/m^2]. Even in x: it shows in DC and the even harmonics, in
/// phase with x^2.
#[derive(Debug, Clone, Copy)]
pub struct SquareDisplacement;
/// x - clamp(x, -neg, pos): a spring that engages only outside a free-play gap, in contact
/// beyond `contact_pos_m` (x > 0) and below `-contact_neg_m` (x < 0; a positive width), so the
/// gap is `contact_neg_m + contact_pos_m` wide and need not be centred; coefficient kfp [N/m].
#[derive(Debug, Clone, Copy)]
pub struct DeadZone {
    pub contact_neg_m: f64,
    pub contact_pos_m: f64,
}

impl DeadZone {
    /// A gap of total width `gap_m` centred on x = 0.
    pub fn symmetric(gap_m: f64) -> DeadZone {
        DeadZone {
            contact_neg_m: 0.5 * gap_m,
            contact_pos_m: 0.5 * gap_m,
        }
    }
}
/// sgn(x') exp(-|x'/vs|^delta): the Stribeck excess of static over kinetic friction, decaying
/// with speed (the law of `element::Friction`), coefficient fs [N] = breakaway - kinetic level.
/// The shape exponent delta is 2 in the Gaussian law ([`StribeckVelocity::gaussian`]); smaller
/// exponents fall faster near zero speed and leave a longer tail.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StribeckVelocity {
    pub velocity_mps: f64,
    pub exponent: f64,
}

impl StribeckVelocity {
    /// The Gaussian law exp(-(x'/vs)^2).
    pub fn gaussian(velocity_mps: f64) -> StribeckVelocity {
        StribeckVelocity {
            velocity_mps,
            exponent: crate::element::GAUSSIAN_STRIBECK_EXPONENT,
        }
    }
}

impl Term for Displacement {
    fn symbol(&self) -> String {
        "k".into()
    }
    fn formula(&self) -> String {
        "x".into()
    }
    fn eval(&self, x: f64, _v: f64) -> f64 {
        x
    }
    fn linear_coefficients(&self) -> Option<(f64, f64)> {
        Some((1.0, 0.0))
    }
}

impl Term for Velocity {
    fn symbol(&self) -> String {
        "c".into()
    }
    fn formula(&self) -> String {
        "x'".into()
    }
    fn eval(&self, _x: f64, v: f64) -> f64 {
        v
    }
    fn linear_coefficients(&self) -> Option<(f64, f64)> {
        Some((0.0, 1.0))
    }
}

impl Term for SignVelocity {
    fn symbol(&self) -> String {
        "fd".into()
    }
    fn formula(&self) -> String {
        "sgn(x')".into()
    }
    fn eval(&self, _x: f64, v: f64) -> f64 {
        if v > 0.0 {
            1.0
        } else if v < 0.0 {
            -1.0
        } else {
            0.0
        }
    }
    fn jumps_at_zero_velocity(&self) -> bool {
        true
    }
}

impl Term for AtanVelocity {
    fn symbol(&self) -> String {
        "fd".into()
    }
    fn formula(&self) -> String {
        format!("(2/pi) atan({} x')", self.slope_s_per_m)
    }
    fn eval(&self, _x: f64, v: f64) -> f64 {
        FRAC_2_PI * (self.slope_s_per_m * v).atan()
    }
    fn describes_friction(&self) -> bool {
        true
    }
}

impl Term for Cubic {
    fn symbol(&self) -> String {
        "s".into()
    }
    fn formula(&self) -> String {
        "x^3".into()
    }
    fn eval(&self, x: f64, _v: f64) -> f64 {
        x * x * x
    }
}

impl Term for Polynomial {
    fn symbol(&self) -> String {
        format!("p{}{}", self.i, self.j)
    }
    fn formula(&self) -> String {
        format!("x^{} x'^{}", self.i, self.j)
    }
    fn eval(&self, x: f64, v: f64) -> f64 {
        x.powi(self.i as i32) * v.powi(self.j as i32)
    }
    fn linear_coefficients(&self) -> Option<(f64, f64)> {
        match (self.i, self.j) {
            (1, 0) => Some((1.0, 0.0)),
            (0, 1) => Some((0.0, 1.0)),
            _ => None,
        }
    }
}

impl Term for Constant {
    fn symbol(&self) -> String {
        "offset".into()
    }
    fn formula(&self) -> String {
        "1".into()
    }
    fn eval(&self, _x: f64, _v: f64) -> f64 {
        1.0
    }
}

impl Term for SignedSquareDisplacement {
    fn symbol(&self) -> String {
        "k2".into()
    }
    fn formula(&self) -> String {
        "x|x|".into()
    }
    fn eval(&self, x: f64, _v: f64) -> f64 {
        x * x.abs()
    }
}

impl Term for SignedSquareVelocity {
    fn symbol(&self) -> String {
        "c2".into()
    }
    fn formula(&self) -> String {
        "x'|x'|".into()
    }
    fn eval(&self, _x: f64, v: f64) -> f64 {
        v * v.abs()
    }
}

impl Term for AbsVelocity {
    fn symbol(&self) -> String {
        "ca".into()
    }
    fn formula(&self) -> String {
        "|x'|".into()
    }
    fn eval(&self, _x: f64, v: f64) -> f64 {
        v.abs()
    }
}

impl Term for SquareDisplacement {
    fn symbol(&self) -> String {
        "k2a".into()
    }
    fn formula(&self) -> String {
        "x^2".into()
    }
    fn eval(&self, x: f64, _v: f64) -> f64 {
        x * x
    }
}

impl Term for DeadZone {
    fn symbol(&self) -> String {
        "kfp".into()
    }
    fn formula(&self) -> String {
        format!(
            "x - clamp(x, -{}, {})",
            self.contact_neg_m, self.contact_pos_m
        )
    }
    fn eval(&self, x: f64, _v: f64) -> f64 {
        x - x.clamp(-self.contact_neg_m, self.contact_pos_m)
    }
}

impl Term for StribeckVelocity {
    fn symbol(&self) -> String {
        "fs".into()
    }
    fn formula(&self) -> String {
        if crate::element::is_gaussian_stribeck(self.exponent) {
            format!("sgn(x') exp(-(x'/{})^2)", self.velocity_mps)
        } else {
            format!("sgn(x') exp(-|x'/{}|^{})", self.velocity_mps, self.exponent)
        }
    }
    fn eval(&self, _x: f64, v: f64) -> f64 {
        if v == 0.0 {
            0.0
        } else {
            v.signum() * crate::element::stribeck_decay(v, self.velocity_mps, self.exponent)
        }
    }
    fn jumps_at_zero_velocity(&self) -> bool {
        true
    }
    fn stribeck(&self) -> Option<StribeckVelocity> {
        Some(*self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stribeck_term_decays_with_its_shape_exponent() {
        // sgn(v) exp(-|v/vs|^delta): e^-1 at |v| = vs whatever delta, exp(-2^delta) at 2 vs,
        // exp(-0.5^delta) at vs/2; odd in v, zero at v = 0.
        let vs = 0.02;
        for delta in [0.5, 0.7, 1.0, 2.0] {
            let t = StribeckVelocity {
                velocity_mps: vs,
                exponent: delta,
            };
            let e1 = (-1.0f64).exp();
            assert!((t.eval(0.0, vs) - e1).abs() < 1e-15, "{delta}");
            assert!((t.eval(0.0, -vs) + e1).abs() < 1e-15, "{delta}");
            let at2 = (-(2.0f64.powf(delta))).exp();
            assert!((t.eval(0.0, 2.0 * vs) - at2).abs() < 1e-15, "{delta}");
            let half = (-(0.5f64.powf(delta))).exp();
            assert!((t.eval(0.0, -0.5 * vs) + half).abs() < 1e-15, "{delta}");
            assert_eq!(t.eval(0.0, 0.0), 0.0);
            assert_eq!(t.stribeck(), Some(t));
        }
        // The Gaussian law is the exponent 2, written as before.
        let g = StribeckVelocity::gaussian(vs);
        assert_eq!(g.exponent, 2.0);
        assert_eq!(g.formula(), "sgn(x') exp(-(x'/0.02)^2)");
        let sharp = StribeckVelocity {
            velocity_mps: vs,
            exponent: 0.5,
        };
        assert_eq!(sharp.formula(), "sgn(x') exp(-|x'/0.02|^0.5)");
        // A sharper shape keeps more of the excess above vs and less below.
        assert!(sharp.eval(0.0, 3.0 * vs) > g.eval(0.0, 3.0 * vs));
        assert!(sharp.eval(0.0, 0.3 * vs) < g.eval(0.0, 0.3 * vs));
    }

    #[test]
    fn atan_tends_to_sgn_for_steep_slope() {
        let a = AtanVelocity { slope_s_per_m: 1e9 };
        for v in [-0.3, -1e-3, 1e-3, 0.2] {
            assert!(
                (a.eval(0.0, v) - SignVelocity.eval(0.0, v)).abs() < 1e-5,
                "v = {v}"
            );
        }
        // slope at the origin is (2/pi) M
        let m = 500.0;
        let a = AtanVelocity { slope_s_per_m: m };
        let d = 1e-9;
        assert!(((a.eval(0.0, d) - a.eval(0.0, -d)) / (2.0 * d) - FRAC_2_PI * m).abs() < 1e-3);
    }

    #[test]
    fn polynomial_matches_named_terms() {
        let (x, v) = (0.013, -0.21);
        assert_eq!(
            Polynomial { i: 1, j: 0 }.eval(x, v),
            Displacement.eval(x, v)
        );
        assert_eq!(Polynomial { i: 0, j: 1 }.eval(x, v), Velocity.eval(x, v));
        assert!((Polynomial { i: 3, j: 0 }.eval(x, v) - Cubic.eval(x, v)).abs() < 1e-20);
        assert!((Polynomial { i: 2, j: 1 }.eval(x, v) - x * x * v).abs() < 1e-18);
        assert_eq!(Polynomial { i: 2, j: 1 }.symbol(), "p21");
    }

    #[test]
    fn odd_and_even_terms() {
        let (x, v) = (0.02, 0.1);
        assert_eq!(
            SignedSquareDisplacement.eval(-x, v),
            -SignedSquareDisplacement.eval(x, v)
        );
        assert_eq!(
            SignedSquareVelocity.eval(x, -v),
            -SignedSquareVelocity.eval(x, v)
        );
        assert_eq!(AbsVelocity.eval(x, -v), AbsVelocity.eval(x, v));
        assert!(SignVelocity.jumps_at_zero_velocity());
        assert!(!AtanVelocity { slope_s_per_m: 1e5 }.jumps_at_zero_velocity());
        assert!(
            AtanVelocity {
                slope_s_per_m: 50.0
            }
            .describes_friction()
                && SignVelocity.describes_friction()
        );
        assert!(!Velocity.describes_friction() && !SignedSquareVelocity.describes_friction());
    }
}
