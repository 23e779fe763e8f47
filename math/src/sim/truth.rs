//! The "true" nonlinear element of the simulators: a sum of optional terms.

use serde::{Deserialize, Serialize};

use crate::element::{Element, Friction};
pub use crate::signal::bouc_wen::BoucWen;

/// Serde mirror of [`Friction`] (which lives in `element.rs` without serde derives).
#[derive(Serialize, Deserialize)]
#[serde(remote = "Friction")]
struct FrictionDef {
    breakaway_n: f64,
    kinetic_n: f64,
    stribeck_velocity_mps: f64,
    #[serde(
        default = "gaussian_stribeck_exponent",
        skip_serializing_if = "is_gaussian_stribeck_exponent"
    )]
    stribeck_exponent: f64,
    asymmetry: f64,
}

/// Truth files written before the exponent was a parameter hold the Gaussian law.
fn gaussian_stribeck_exponent() -> f64 {
    crate::element::GAUSSIAN_STRIBECK_EXPONENT
}

fn is_gaussian_stribeck_exponent(e: &f64) -> bool {
    crate::element::is_gaussian_stribeck(*e)
}

mod opt_friction {
    use super::{Friction, FrictionDef};
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(v: &Option<Friction>, s: S) -> Result<S::Ok, S::Error> {
        #[derive(Serialize)]
        struct W<'a>(#[serde(with = "FrictionDef")] &'a Friction);
        v.as_ref().map(W).serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Friction>, D::Error> {
        #[derive(Deserialize)]
        struct W(#[serde(with = "FrictionDef")] Friction);
        Ok(Option::<W>::deserialize(d)?.map(|W(f)| f))
    }
}

/// Extra damping that differs between rebound (v > 0) and compression (v < 0); added to the
/// symmetric `damping_n_s_per_m`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AsymmetricDamping {
    pub rebound_n_s_per_m: f64,
    pub compression_n_s_per_m: f64,
}

/// Free-play: a spring of `stiffness_n_per_m` with a gap of total width `gap_m`; force zero
/// for |x| <= gap/2, `k (x - sgn(x) gap/2)` outside (continuous). Added to the other terms.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FreePlay {
    pub gap_m: f64,
    pub stiffness_n_per_m: f64,
}

/// A truth element: `g = f0 + k x + c v + S x^3 + q x|x| + d v|v| + asym(v) + freeplay(x)
/// + alpha z + friction`, each term optional (zero or `None` switches it off).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TruthElement {
    pub stiffness_n_per_m: f64,
    pub damping_n_s_per_m: f64,
    #[serde(with = "opt_friction")]
    pub friction: Option<Friction>,
    /// S in S x^3 [N/m^3].
    pub cubic_stiffness_n_per_m3: f64,
    /// q in q x|x| [N/m^2] (asymmetric about nothing, odd but not polynomial).
    pub quadratic_stiffness_n_per_m2: f64,
    /// d in d v|v| [N s^2/m^2].
    pub quadratic_damping_n_s2_per_m2: f64,
    pub asymmetric_damping: Option<AsymmetricDamping>,
    pub free_play: Option<FreePlay>,
    pub bouc_wen: Option<BoucWen>,
    /// A state-independent force [N]: a damper's gas-spring preload.
    pub preload_n: f64,
}

impl Default for TruthElement {
    fn default() -> Self {
        TruthElement {
            stiffness_n_per_m: 0.0,
            damping_n_s_per_m: 0.0,
            friction: None,
            cubic_stiffness_n_per_m3: 0.0,
            quadratic_stiffness_n_per_m2: 0.0,
            quadratic_damping_n_s2_per_m2: 0.0,
            asymmetric_damping: None,
            free_play: None,
            bouc_wen: None,
            preload_n: 0.0,
        }
    }
}

impl TruthElement {
    /// Linear spring and damper.
    pub fn linear(stiffness_n_per_m: f64, damping_n_s_per_m: f64) -> TruthElement {
        TruthElement {
            stiffness_n_per_m,
            damping_n_s_per_m,
            ..TruthElement::default()
        }
    }

    /// The paper's identified rig (Table 2, Coulomb model): k 6380 N/m, c 184 N s/m,
    /// F_d 12.3 N (plain Coulomb: breakaway = kinetic).
    pub fn rig_coulomb() -> TruthElement {
        TruthElement {
            friction: Some(Friction::coulomb(12.3)),
            ..TruthElement::linear(6380.0, 184.0)
        }
    }

    /// The paper's 3-DOF element (eq. 18): k 8000 N/m, c 20 N s/m, F_d 5 N, S 3e8 N/m^3.
    pub fn three_dof_element() -> TruthElement {
        TruthElement {
            friction: Some(Friction::coulomb(5.0)),
            cubic_stiffness_n_per_m3: 3e8,
            ..TruthElement::linear(8000.0, 20.0)
        }
    }
}

impl Element for TruthElement {
    fn smooth_force(&self, x: f64, v: f64, z: &[f64]) -> f64 {
        let mut f = self.preload_n
            + self.stiffness_n_per_m * x
            + self.damping_n_s_per_m * v
            + self.cubic_stiffness_n_per_m3 * x * x * x
            + self.quadratic_stiffness_n_per_m2 * x * x.abs()
            + self.quadratic_damping_n_s2_per_m2 * v * v.abs();
        if let Some(a) = self.asymmetric_damping {
            f += if v > 0.0 {
                a.rebound_n_s_per_m * v
            } else {
                a.compression_n_s_per_m * v
            };
        }
        if let Some(fp) = self.free_play {
            let half = 0.5 * fp.gap_m;
            if x > half {
                f += fp.stiffness_n_per_m * (x - half);
            } else if x < -half {
                f += fp.stiffness_n_per_m * (x + half);
            }
        }
        if let (Some(bw), Some(&zz)) = (self.bouc_wen, z.first()) {
            f += bw.alpha_n_per_m * zz;
        }
        f
    }

    fn friction(&self) -> Option<Friction> {
        self.friction
    }

    fn internal_states(&self) -> usize {
        usize::from(self.bouc_wen.is_some())
    }

    fn internal_rates(&self, _x: f64, v: f64, z: &[f64], dz: &mut [f64]) {
        if let (Some(bw), Some(&zz), Some(d)) = (self.bouc_wen, z.first(), dz.first_mut()) {
            *d = bw.rate(zz, v);
        }
    }

    fn linear_coefficients(&self) -> Option<(f64, f64)> {
        let linear = self.preload_n == 0.0
            && self.cubic_stiffness_n_per_m3 == 0.0
            && self.quadratic_stiffness_n_per_m2 == 0.0
            && self.quadratic_damping_n_s2_per_m2 == 0.0
            && self.asymmetric_damping.is_none()
            && self.free_play.is_none()
            && self.bouc_wen.is_none();
        linear.then_some((self.stiffness_n_per_m, self.damping_n_s_per_m))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_coefficients_are_the_smooth_force() {
        let e = TruthElement::rig_coulomb();
        let (k, c) = e.linear_coefficients().unwrap();
        for (x, v) in [(0.003, -0.2), (-0.01, 0.05), (0.0, 1.0)] {
            assert_eq!(e.smooth_force(x, v, &[]), k * x + c * v);
        }
        // Any nonlinear term: none.
        assert_eq!(
            TruthElement::three_dof_element().linear_coefficients(),
            None
        );
        let fp = TruthElement {
            free_play: Some(FreePlay {
                gap_m: 0.002,
                stiffness_n_per_m: 1000.0,
            }),
            ..TruthElement::rig_coulomb()
        };
        assert_eq!(fp.linear_coefficients(), None);
        // A preload is no k x + c v either.
        let preloaded = TruthElement {
            preload_n: 150.0,
            ..TruthElement::rig_coulomb()
        };
        assert_eq!(preloaded.linear_coefficients(), None);
    }

    #[test]
    fn terms() {
        let mut e = TruthElement::three_dof_element();
        assert!((e.smooth_force(0.001, 0.1, &[]) - (8.0 + 2.0 + 0.3)).abs() < 1e-12);
        e.free_play = Some(FreePlay {
            gap_m: 0.002,
            stiffness_n_per_m: 1000.0,
        });
        assert!((e.smooth_force(0.0005, 0.0, &[]) - (4.0 + 3e8 * 1.25e-10)).abs() < 1e-12);
        assert!((e.smooth_force(-0.002, 0.0, &[]) - (-16.0 - 2.4 - 1.0)).abs() < 1e-12);
        e.asymmetric_damping = Some(AsymmetricDamping {
            rebound_n_s_per_m: 100.0,
            compression_n_s_per_m: 50.0,
        });
        e.bouc_wen = Some(BoucWen {
            alpha_n_per_m: 10.0,
            a: 1.0,
            beta: 0.5,
            gamma: 0.5,
            n: 1.0,
        });
        assert_eq!(e.internal_states(), 1);
        let mut dz = [0.0];
        e.internal_rates(0.0, 2.0, &[0.5], &mut dz);
        assert!((dz[0] - (2.0 - 0.5 * 2.0 * 0.5 - 0.5 * 2.0 * 0.5)).abs() < 1e-12);
    }
}
