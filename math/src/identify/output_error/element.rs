//! The element an output-error fit simulates: a model with its parameters, every smooth term as
//! it is and the friction terms (sgn, and the Stribeck excess) as the simulators' set-valued
//! friction law, so that the stick phase is exact.

use crate::element::{Element, Friction};
use crate::identify::IdentifyError;
use crate::model::{IdentifiedModel, Model};
use crate::signal::bouc_wen::HysteresisLaw;

/// `model` with parameters `theta`, as the simulators run it.
pub(crate) struct ModelElement {
    smooth: IdentifiedModel,
    friction: Option<Friction>,
    /// The element sees `x_offset_m + x` (an element test's stroke about its mid position).
    x_offset_m: f64,
    /// A constant force on the moving mass, taken off the element's (a force drive's static
    /// part).
    force_offset_n: f64,
    /// A Bouc-Wen state beside the terms: its force coefficient alpha [N/m] and law, the state
    /// z [m] the element's one internal state.
    hysteresis: Option<(f64, HysteresisLaw)>,
}

/// Checks that the simulators can run `model` exactly: every term that jumps where x' changes
/// sign must be sgn(x') (the Coulomb level) or the Stribeck excess.
pub(crate) fn check_model(model: &Model) -> Result<(), IdentifyError> {
    // The friction law has one Stribeck curve: excesses of two shapes cannot be simulated.
    let mut laws = model.terms.iter().filter_map(|t| t.stribeck());
    if let Some(first) = laws.next()
        && let Some(other) = laws.find(|l| *l != first)
    {
        return Err(IdentifyError::Step {
            step: 0,
            problem: format!(
                "output error simulates the friction exactly, with one Stribeck curve; model {} has Stribeck excesses at {} m/s (exponent {}) and {} m/s (exponent {})",
                model.name, first.velocity_mps, first.exponent, other.velocity_mps, other.exponent
            ),
        });
    }
    for t in model.terms.iter().filter(|t| t.jumps_at_zero_velocity()) {
        let sgn = t.formula() == "sgn(x')";
        if !sgn && t.stribeck().is_none() {
            return Err(IdentifyError::Step {
                step: 0,
                problem: format!(
                    "output error simulates the friction exactly; it supports sgn(x') and the Stribeck excess, not {} = {} of model {}",
                    t.symbol(),
                    t.formula(),
                    model.name
                ),
            });
        }
    }
    Ok(())
}

impl ModelElement {
    /// The element of `model` (checked by [`check_model`]) at `theta`.
    pub(crate) fn new(model: &Model, theta: &[f64]) -> ModelElement {
        // A negative level is no friction: the stick level is kept at zero, as the model
        // simulator does (`IdentifiedModel::friction`).
        let friction = Friction::from_terms(&model.terms, theta);
        ModelElement {
            smooth: IdentifiedModel::new(model.clone(), theta.to_vec()),
            friction,
            x_offset_m: 0.0,
            force_offset_n: 0.0,
            hysteresis: None,
        }
    }

    /// The element with a Bouc-Wen state beside its terms: force `alpha_n_per_m * z`, z
    /// following `law`.
    pub(crate) fn with_hysteresis(self, alpha_n_per_m: f64, law: HysteresisLaw) -> ModelElement {
        ModelElement {
            hysteresis: Some((alpha_n_per_m, law)),
            ..self
        }
    }

    /// The element at displacement `x_offset_m + x`, less the constant force `force_offset_n`:
    /// an element test whose drive has an offset, simulated with a drive without one.
    pub(crate) fn with_offsets(self, x_offset_m: f64, force_offset_n: f64) -> ModelElement {
        ModelElement {
            x_offset_m,
            force_offset_n,
            ..self
        }
    }
}

impl Element for ModelElement {
    fn smooth_force(&self, x: f64, v: f64, z: &[f64]) -> f64 {
        // IdentifiedModel's smooth force leaves every jumping term out.
        let hysteresis = match (self.hysteresis, z.first()) {
            (Some((alpha, _)), Some(z)) => alpha * z,
            _ => 0.0,
        };
        self.smooth.smooth_force(self.x_offset_m + x, v, z) - self.force_offset_n + hysteresis
    }

    fn friction(&self) -> Option<Friction> {
        self.friction
    }

    fn internal_states(&self) -> usize {
        usize::from(self.hysteresis.is_some())
    }

    fn internal_rates(&self, _x: f64, v: f64, z: &[f64], dz: &mut [f64]) {
        if let (Some((_, law)), Some(&z), Some(d)) = (self.hysteresis, z.first(), dz.first_mut()) {
            *d = law.rate(z, v);
        }
    }

    fn linear_coefficients(&self) -> Option<(f64, f64)> {
        // With an offset the force is affine in x, not linear; a state makes it dynamic.
        let offset = self.x_offset_m != 0.0 || self.force_offset_n != 0.0;
        self.smooth
            .linear_coefficients()
            .filter(|_| !offset && self.hysteresis.is_none())
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::basis::{AtanVelocity, SignVelocity, StribeckVelocity, Term};
    use crate::model::ModelOptions;

    #[test]
    fn friction_terms_become_the_friction_law() {
        let m = Model::by_name("coulomb", &ModelOptions::default())
            .unwrap()
            .with_terms(
                "stribeck",
                &[Arc::new(StribeckVelocity::gaussian(0.02)) as Arc<dyn Term>],
            );
        check_model(&m).unwrap();
        let e = ModelElement::new(&m, &[6000.0, 150.0, 10.0, 4.0]);
        let f = e.friction().unwrap();
        assert_eq!((f.kinetic_n, f.breakaway_n), (10.0, 14.0));
        assert_eq!(f.stribeck_velocity_mps, 0.02);
        // Slipping, the law is the model's force: 10 + 4 exp(-(v/vs)^2) at v = vs.
        let v = 0.02;
        let want = m.force(&[0.0, 0.0, 10.0, 4.0], 0.0, v);
        assert!((f.slip_force_n(v) - want).abs() < 1e-12, "{want}");
        assert_eq!(e.smooth_force(0.001, 0.1, &[]), 6.0 + 15.0);
        assert_eq!(e.linear_coefficients(), Some((6000.0, 150.0)));
        // A plain Coulomb model: no Stribeck excess.
        let c = Model::by_name("coulomb", &ModelOptions::default()).unwrap();
        let f = ModelElement::new(&c, &[1.0, 2.0, 3.0]).friction().unwrap();
        assert_eq!(f, Friction::coulomb(3.0));
        assert!(SignVelocity.formula() == "sgn(x')");
    }

    #[test]
    fn other_jumping_terms_are_refused_and_smooth_ones_kept() {
        #[derive(Debug)]
        struct Jumpy;
        impl Term for Jumpy {
            fn symbol(&self) -> String {
                "j".into()
            }
            fn formula(&self) -> String {
                "sgn(x') x".into()
            }
            fn eval(&self, x: f64, v: f64) -> f64 {
                v.signum() * x
            }
            fn jumps_at_zero_velocity(&self) -> bool {
                true
            }
        }
        let lin = Model::by_name("linear", &ModelOptions::default()).unwrap();
        let bad = lin.with_terms("jumpy", &[Arc::new(Jumpy) as Arc<dyn Term>]);
        let e = check_model(&bad).unwrap_err().to_string();
        assert!(e.contains("sgn(x') x"), "{e}");
        // atan friction is smooth: simulated as it is, no stick phase.
        let atan = lin.with_terms(
            "atan",
            &[Arc::new(AtanVelocity {
                slope_s_per_m: 100.0,
            }) as Arc<dyn Term>],
        );
        check_model(&atan).unwrap();
        assert!(
            ModelElement::new(&atan, &[1.0, 1.0, 1.0])
                .friction()
                .is_none()
        );
    }
}
