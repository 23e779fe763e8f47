//! Models: named sets of basis functions, and identified models that simulate.

use std::sync::Arc;

use thiserror::Error;

use crate::basis::{
    AbsVelocity, AtanVelocity, Constant, Cubic, Displacement, Polynomial, SignVelocity, Term,
    Velocity,
};
use crate::element::{Element, Friction};

/// The names `Model::by_name` understands, with what they hold.
pub const MODEL_NAMES: &[(&str, &str)] = &[
    ("linear", "k x + c x'  (eq. 24)"),
    ("coulomb", "k x + c x' + fd sgn(x')  (eq. 25)"),
    (
        "coulomb-atan",
        "k x + c x' + fd (2/pi) atan(M x')  (eq. 26; M from --atan-m)",
    ),
    ("coulomb-cubic", "k x + c x' + fd sgn(x') + s x^3  (eq. 18)"),
    (
        "coulomb-atan-cubic",
        "k x + c x' + fd (2/pi) atan(M x') + s x^3  (eq. 19)",
    ),
    ("cubic", "k x + c x' + s x^3"),
    (
        "damper",
        "offset + k x + c x' + ca |x'| + fd sgn(x')  (gas preload, gas spring, rebound/compression damping c +/- ca, friction)",
    ),
    (
        "polynomial",
        "sum of x^i x'^j for i <= P, j <= Q, i + j >= 1  (eq. 2; P, Q from --poly-order)",
    ),
];

/// Appended to a model's name (`cubic+offset`), a constant force term `offset` [N] added to its
/// terms: a load cell's zero error, a drive signal's DC, a preload the model does not hold.
pub const OFFSET_SUFFIX: &str = "+offset";

/// Appended to a model's name (`linear+hysteresis`), a Bouc-Wen hysteresis state beside its
/// terms: the force `alpha z`, z integrated along the measured velocity, its yield and loop
/// shape searched. Fitted offline on element tests and a rig's sine steps by `forcemap
/// identify` as `forcemap diagnose` refits a baseline with its hysteresis candidate; not a
/// [`Model`] of terms.
pub const HYSTERESIS_SUFFIX: &str = "+hysteresis";

/// Whether `name` names a model: one of [`MODEL_NAMES`], with or without [`OFFSET_SUFFIX`] (a
/// model that holds a constant already takes none).
pub fn is_model_name(name: &str) -> bool {
    let (base, offset) = match name.strip_suffix(OFFSET_SUFFIX) {
        Some(base) => (base, true),
        None => (name, false),
    };
    MODEL_NAMES.iter().any(|(n, _)| *n == base) && !(offset && base == "damper")
}

#[derive(Debug, Clone, Error, PartialEq)]
pub enum ModelError {
    #[error("unknown model '{name}'; known models: {known}")]
    Unknown { name: String, known: String },
    #[error("model '{name}' needs the atan slope M (e.g. --atan-m 1000), a positive number")]
    MissingAtanSlope { name: String },
    #[error(
        "model '{name}': a hysteresis state is fitted offline, along each record's samples (`forcemap identify --model {name}` on a bag or an export); the live identifier keeps the equations of a model's terms, never the samples"
    )]
    HysteresisOffline { name: String },
}

impl ModelError {
    /// `name` is not one of [`MODEL_NAMES`].
    pub fn unknown(name: &str) -> ModelError {
        ModelError::Unknown {
            name: name.into(),
            known: MODEL_NAMES
                .iter()
                .map(|(n, _)| *n)
                .collect::<Vec<_>>()
                .join(", ")
                + &format!(" (each but damper also with {OFFSET_SUFFIX})"),
        }
    }
}

/// Options that some named models need.
#[derive(Debug, Clone, Copy, Default)]
pub struct ModelOptions {
    /// Slope M [s/m] of the atan friction term.
    pub atan_slope_s_per_m: Option<f64>,
    /// Orders (P, Q) of the polynomial model.
    pub polynomial_order: Option<(u32, u32)>,
}

/// A named set of basis functions.
#[derive(Debug, Clone)]
pub struct Model {
    pub name: String,
    pub terms: Vec<Arc<dyn Term>>,
}

impl Model {
    pub fn new(name: impl Into<String>, terms: Vec<Arc<dyn Term>>) -> Model {
        Model {
            name: name.into(),
            terms,
        }
    }

    pub fn by_name(name: &str, options: &ModelOptions) -> Result<Model, ModelError> {
        if let Some(base) = name.strip_suffix(OFFSET_SUFFIX)
            && is_model_name(name)
        {
            let mut terms: Vec<Arc<dyn Term>> = vec![Arc::new(Constant)];
            terms.extend(Model::by_name(base, options)?.terms);
            return Ok(Model::new(name, terms));
        }
        let atan = || -> Result<Arc<dyn Term>, ModelError> {
            match options.atan_slope_s_per_m {
                Some(m) if m > 0.0 && m.is_finite() => {
                    Ok(Arc::new(AtanVelocity { slope_s_per_m: m }))
                }
                _ => Err(ModelError::MissingAtanSlope { name: name.into() }),
            }
        };
        let terms: Vec<Arc<dyn Term>> = match name {
            "linear" => vec![Arc::new(Displacement), Arc::new(Velocity)],
            "coulomb" => vec![
                Arc::new(Displacement),
                Arc::new(Velocity),
                Arc::new(SignVelocity),
            ],
            "coulomb-atan" => vec![Arc::new(Displacement), Arc::new(Velocity), atan()?],
            "coulomb-cubic" => vec![
                Arc::new(Displacement),
                Arc::new(Velocity),
                Arc::new(SignVelocity),
                Arc::new(Cubic),
            ],
            "coulomb-atan-cubic" => {
                vec![
                    Arc::new(Displacement),
                    Arc::new(Velocity),
                    atan()?,
                    Arc::new(Cubic),
                ]
            }
            "cubic" => vec![Arc::new(Displacement), Arc::new(Velocity), Arc::new(Cubic)],
            "damper" => vec![
                Arc::new(Constant),
                Arc::new(Displacement),
                Arc::new(Velocity),
                Arc::new(AbsVelocity),
                Arc::new(SignVelocity),
            ],
            "polynomial" => {
                let (p, q) = options.polynomial_order.unwrap_or((3, 1));
                let mut terms: Vec<Arc<dyn Term>> = Vec::new();
                for j in 0..=q {
                    for i in 0..=p {
                        if i + j >= 1 {
                            terms.push(Arc::new(Polynomial { i, j }));
                        }
                    }
                }
                terms
            }
            _ => return Err(ModelError::unknown(name)),
        };
        Ok(Model::new(name, terms))
    }

    /// Adds terms (e.g. a candidate effect) and returns the extended model.
    pub fn with_terms(&self, name: impl Into<String>, extra: &[Arc<dyn Term>]) -> Model {
        let mut terms = self.terms.clone();
        terms.extend(extra.iter().cloned());
        Model::new(name, terms)
    }

    pub fn symbols(&self) -> Vec<String> {
        self.terms.iter().map(|t| t.symbol()).collect()
    }

    pub fn has_velocity_jump(&self) -> bool {
        self.terms.iter().any(|t| t.jumps_at_zero_velocity())
    }

    /// True when a term describes friction (sgn or smoothed sgn): see `Term::describes_friction`.
    pub fn has_friction(&self) -> bool {
        self.terms.iter().any(|t| t.describes_friction())
    }

    /// The element force with parameters `theta`.
    pub fn force(&self, theta: &[f64], x: f64, v: f64) -> f64 {
        self.terms
            .iter()
            .zip(theta)
            .map(|(t, th)| th * t.eval(x, v))
            .sum()
    }
}

/// A model with its parameter values: an `Element` the simulators can run. A sgn-like term
/// becomes set-valued Coulomb friction (exact stick phase); every other term is smooth.
#[derive(Debug, Clone)]
pub struct IdentifiedModel {
    pub model: Model,
    pub theta: Vec<f64>,
}

impl IdentifiedModel {
    pub fn new(model: Model, theta: Vec<f64>) -> IdentifiedModel {
        assert_eq!(model.terms.len(), theta.len(), "one value per term");
        IdentifiedModel { model, theta }
    }

    pub fn parameter(&self, symbol: &str) -> Option<f64> {
        self.model
            .terms
            .iter()
            .zip(&self.theta)
            .find(|(t, _)| t.symbol() == symbol)
            .map(|(_, v)| *v)
    }
}

impl Element for IdentifiedModel {
    fn smooth_force(&self, x: f64, v: f64, _z: &[f64]) -> f64 {
        self.model
            .terms
            .iter()
            .zip(&self.theta)
            .filter(|(t, _)| !t.jumps_at_zero_velocity())
            .map(|(t, th)| th * t.eval(x, v))
            .sum()
    }

    fn friction(&self) -> Option<Friction> {
        // One law for every fitted model: a Stribeck term is a breakaway excess with its own
        // decay, not a share of the kinetic level.
        Friction::from_terms(&self.model.terms, &self.theta)
    }

    fn linear_coefficients(&self) -> Option<(f64, f64)> {
        let mut kc = (0.0, 0.0);
        for (t, th) in self.model.terms.iter().zip(&self.theta) {
            if t.jumps_at_zero_velocity() {
                continue;
            }
            let (a, b) = t.linear_coefficients()?;
            kc.0 += th * a;
            kc.1 += th * b;
        }
        Some(kc)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_offset_suffix_adds_a_constant_term_first() {
        let o = ModelOptions::default();
        let m = Model::by_name("cubic+offset", &o).unwrap();
        let symbols: Vec<String> = m.terms.iter().map(|t| t.symbol()).collect();
        let cubic: Vec<String> = Model::by_name("cubic", &o)
            .unwrap()
            .terms
            .iter()
            .map(|t| t.symbol())
            .collect();
        assert_eq!(symbols[0], "offset");
        assert_eq!(symbols[1..], cubic[..]);
        assert_eq!(m.name, "cubic+offset");
        // damper holds its offset already; an unknown base stays unknown.
        for bad in ["damper+offset", "quartic+offset", "cubic+offset+offset"] {
            assert!(!is_model_name(bad), "{bad}");
            assert!(Model::by_name(bad, &o).is_err(), "{bad}");
        }
    }

    #[test]
    fn linear_coefficients_are_the_smooth_force() {
        let o = ModelOptions {
            atan_slope_s_per_m: Some(500.0),
            polynomial_order: Some((1, 1)),
        };
        let coulomb = IdentifiedModel::new(
            Model::by_name("coulomb", &o).unwrap(),
            vec![6380.0, 184.0, 12.3],
        );
        assert_eq!(coulomb.linear_coefficients(), Some((6380.0, 184.0)));
        for (x, v) in [(0.003, -0.2), (-0.01, 0.05)] {
            assert_eq!(coulomb.smooth_force(x, v, &[]), 6380.0 * x + 184.0 * v);
        }
        // p10 and p01 are linear, p11 (x x') is not; atan and cubic are not.
        let poly = Model::by_name("polynomial", &o).unwrap();
        let n = poly.terms.len();
        assert_eq!(
            IdentifiedModel::new(poly, vec![1.0; n]).linear_coefficients(),
            None
        );
        for name in ["coulomb-atan", "cubic"] {
            let m = Model::by_name(name, &o).unwrap();
            let n = m.terms.len();
            assert_eq!(
                IdentifiedModel::new(m, vec![1.0; n]).linear_coefficients(),
                None
            );
        }
    }

    #[test]
    fn named_models_have_the_papers_symbols() {
        let o = ModelOptions {
            atan_slope_s_per_m: Some(500.0),
            polynomial_order: None,
        };
        assert_eq!(Model::by_name("linear", &o).unwrap().symbols(), ["k", "c"]);
        assert_eq!(
            Model::by_name("coulomb", &o).unwrap().symbols(),
            ["k", "c", "fd"]
        );
        assert_eq!(
            Model::by_name("coulomb-atan", &o).unwrap().symbols(),
            ["k", "c", "fd"]
        );
        assert_eq!(
            Model::by_name("coulomb-cubic", &o).unwrap().symbols(),
            ["k", "c", "fd", "s"]
        );
        let poly = Model::by_name(
            "polynomial",
            &ModelOptions {
                polynomial_order: Some((2, 1)),
                ..o
            },
        )
        .unwrap();
        assert_eq!(poly.symbols(), ["p10", "p20", "p01", "p11", "p21"]);
    }

    #[test]
    fn errors_name_the_problem() {
        let e = Model::by_name("coulomb-atan", &ModelOptions::default()).unwrap_err();
        assert!(e.to_string().contains("--atan-m"), "{e}");
        let e = Model::by_name("friction", &ModelOptions::default()).unwrap_err();
        assert!(e.to_string().contains("coulomb-cubic"), "{e}");
    }

    #[test]
    fn identified_model_splits_friction_from_smooth_force() {
        let m = Model::by_name("coulomb", &ModelOptions::default()).unwrap();
        let im = IdentifiedModel::new(m, vec![6380.0, 184.0, 12.3]);
        assert_eq!(im.friction().unwrap().breakaway_n, 12.3);
        assert!((im.smooth_force(0.01, 0.1, &[]) - (63.8 + 18.4)).abs() < 1e-12);
        assert!((im.model.force(&im.theta, 0.01, 0.1) - (63.8 + 18.4 + 12.3)).abs() < 1e-12);
        assert_eq!(im.parameter("fd"), Some(12.3));
    }

    #[test]
    fn a_stribeck_term_is_a_breakaway_excess_over_the_kinetic_level() {
        let m = Model::by_name("coulomb", &ModelOptions::default()).unwrap();
        let law = crate::basis::StribeckVelocity {
            velocity_mps: 0.01,
            exponent: 1.0,
        };
        let with = m.with_terms("coulomb+stribeck", &[Arc::new(law)]);
        let im = IdentifiedModel::new(with, vec![6380.0, 184.0, 12.3, 5.7]);
        let f = im.friction().unwrap();
        assert_eq!((f.kinetic_n, f.breakaway_n), (12.3, 18.0));
        assert_eq!((f.stribeck_velocity_mps, f.stribeck_exponent), (0.01, 1.0));
        // Slipping at vs the excess has decayed to 5.7 / e.
        let at_vs = 12.3 + 5.7 * (-1.0f64).exp();
        assert!((f.slip_force_n(0.01) - at_vs).abs() < 1e-12);
        // The smooth force leaves both jumping terms out.
        assert!((im.smooth_force(0.01, 0.1, &[]) - (63.8 + 18.4)).abs() < 1e-12);
    }
}
