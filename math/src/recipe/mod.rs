//! What an identification is, in one serde type ([`Recipe`]): the setup with its constants,
//! the model, the method, the weighting and the phasor options. The `forcemap` command, the
//! identifier node and the diagnoser build it the same way, through the rules here:
//!
//! - which setup the data are, from the channels they hold ([`SetupKind::of_channels`]);
//! - the setup's constants, from whichever sources the user gave, in their order of priority
//!   ([`SetupConstants::or`]), checked once ([`check_mass_kg`], [`SubstructureSpec::build`]);
//! - model and method names ([`ModelSpec`], [`Method`] and [`Weighting`] implement `FromStr`).
//!
//! Everything a setup is lives in [`setup`]; a new setup is a variant there, its equations in
//! `identify::fd` and its simulator in `sim::run`.

use std::str::FromStr;

use serde::{Deserialize, Serialize};
use thiserror::Error;

mod setup;

pub use setup::{Setup, SetupConstants, SetupKind, SetupSpec, SubstructureSpec, check_mass_kg};

use crate::identify::{FdMultiOptions, Method, Weighting};
use crate::model::{Model, ModelError, ModelOptions, is_model_name};
use crate::phasor::PhasorOptions;

/// Why a recipe cannot be made.
#[derive(Debug, Clone, Error, PartialEq)]
pub enum RecipeError {
    #[error("mass_kg = {0}: the rig's mass must be a positive number of kg")]
    BadMass(f64),
    #[error("mass_kg = {0}: an element test's moving mass must be zero or a positive number of kg")]
    BadMovingMass(f64),
    #[error("the rig's mass is needed (mass_kg)")]
    MissingMass,
    #[error(
        "a drive-point setup (force_n, drive_point_displacement_m) needs the linear substructure the element is attached to: \
         give `substructure: paper_three_dof` or the chain `substructure.masses_kg`, `substructure.springs_n_per_m`, \
         `substructure.dampers_n_s_per_m` (ground first) and `substructure.drive_dof` \
         (see launch_configs/three_dof.params.yaml)"
    )]
    MissingSubstructure,
    #[error(
        "substructure.masses_kg, springs_n_per_m and dampers_n_s_per_m must have the same, non-zero length"
    )]
    SubstructureLengths,
    #[error("substructure.drive_dof = {drive_dof} but the chain has {masses} masses")]
    DriveDofOutOfRange { drive_dof: usize, masses: usize },
    #[error("the channels present ({present}) are neither {}", describe_kinds())]
    UnknownChannels { present: String },
    #[error(
        "method '{0}': expected fd, fd-multi, output-error, td (20 points per step), td-all or td-N"
    )]
    UnknownMethod(String),
    #[error("weighting '{0}': expected robust, noise or uniform")]
    UnknownWeighting(String),
    #[error(
        "forgetting_per_step = {0}: expected a factor in (0, 1] (1: converged; 0.8: a window of about 4 steps)"
    )]
    BadForgetting(f64),
    #[error(
        "method {0}: {reason}",
        reason = live_refusal(*.0).unwrap_or("")
    )]
    NotLive(Method),
    #[error(transparent)]
    Model(#[from] ModelError),
}

fn describe_kinds() -> String {
    SetupKind::ALL
        .iter()
        .map(|k| {
            let names: Vec<&str> = k.required_channels().iter().map(|c| c.name()).collect();
            format!("the {} channels ({})", k.name(), names.join(", "))
        })
        .collect::<Vec<_>>()
        .join(" nor ")
}

/// A named model with the options some names need.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelSpec {
    /// One of [`MODEL_NAMES`].
    pub name: String,
    /// Slope M [s/m] of the atan friction term (the `*-atan*` models).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub atan_slope_s_per_m: Option<f64>,
    /// Orders (P, Q) of the polynomial model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub polynomial_order: Option<(u32, u32)>,
}

impl ModelSpec {
    pub fn with_options(mut self, options: ModelOptions) -> ModelSpec {
        self.atan_slope_s_per_m = options.atan_slope_s_per_m;
        self.polynomial_order = options.polynomial_order;
        self
    }

    pub fn options(&self) -> ModelOptions {
        ModelOptions {
            atan_slope_s_per_m: self.atan_slope_s_per_m,
            polynomial_order: self.polynomial_order,
        }
    }

    pub fn build(&self) -> Result<Model, ModelError> {
        Model::by_name(&self.name, &self.options())
    }
}

impl FromStr for ModelSpec {
    type Err = ModelError;

    /// A model name of [`MODEL_NAMES`] (or one with [`crate::model::OFFSET_SUFFIX`]), without
    /// options. A name with [`crate::model::HYSTERESIS_SUFFIX`] is refused with where it is
    /// fitted: it is no model of terms.
    fn from_str(name: &str) -> Result<ModelSpec, ModelError> {
        if name
            .strip_suffix(crate::model::HYSTERESIS_SUFFIX)
            .is_some_and(is_model_name)
        {
            return Err(ModelError::HysteresisOffline { name: name.into() });
        }
        if is_model_name(name) {
            Ok(ModelSpec {
                name: name.to_string(),
                atan_slope_s_per_m: None,
                polynomial_order: None,
            })
        } else {
            Err(ModelError::unknown(name))
        }
    }
}

/// Why the live identifier cannot run `method` (it keeps equations, never samples), if it
/// cannot.
pub fn live_refusal(method: Method) -> Option<&'static str> {
    match method {
        Method::Fd | Method::FdMulti => None,
        Method::Td { .. } => Some(
            "the time-domain FSM needs the samples, which the identifier never keeps; use fd or fd-multi live, or `forcemap identify --method td` on a bag",
        ),
        Method::OutputError => Some(
            "output error refits against a simulation of every sample, which the identifier never keeps; use fd or fd-multi live, or `forcemap identify --method output-error` on a bag",
        ),
    }
}

/// Everything an identification is.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Recipe {
    pub setup: SetupSpec,
    pub model: ModelSpec,
    pub method: Method,
    pub weighting: Weighting,
    pub phasor: PhasorOptions,
    /// Whether theta converges over the run or follows drifting parameters.
    #[serde(default)]
    pub tracking: Tracking,
}

/// Converged (every step weighs the same) or tracking (exponential forgetting per step,
/// `EquationAccumulator::forget`): the theta of a damper that heats up follows its damping,
/// with a lag of factor / (1 - factor) steps.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Tracking {
    #[default]
    Converged,
    Forgetting {
        factor_per_step: f64,
    },
}

impl Tracking {
    /// From a forgetting factor per step: 1 is converged; (0, 1) tracks.
    pub fn from_factor(factor_per_step: f64) -> Result<Tracking, RecipeError> {
        if factor_per_step == 1.0 {
            Ok(Tracking::Converged)
        } else if factor_per_step > 0.0 && factor_per_step < 1.0 {
            Ok(Tracking::Forgetting { factor_per_step })
        } else {
            Err(RecipeError::BadForgetting(factor_per_step))
        }
    }

    /// The weight of the steps so far against the next one (1 when converged).
    pub fn factor_per_step(self) -> f64 {
        match self {
            Tracking::Converged => 1.0,
            Tracking::Forgetting { factor_per_step } => factor_per_step,
        }
    }
}

impl Recipe {
    /// The options of the improved method this recipe asks for.
    pub fn fd_options(&self) -> FdMultiOptions {
        FdMultiOptions {
            weighting: self.weighting,
            ..FdMultiOptions::default()
        }
    }

    /// Refuses a recipe the live identifier cannot run.
    pub fn check_live(&self) -> Result<(), RecipeError> {
        match live_refusal(self.method) {
            None => Ok(()),
            Some(_) => Err(RecipeError::NotLive(self.method)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::Channel;

    fn present(list: &[Channel]) -> impl Fn(Channel) -> bool + '_ {
        move |c| list.contains(&c)
    }

    #[test]
    fn a_hysteresis_model_is_refused_with_where_it_is_fitted() {
        let e = "damper+hysteresis".parse::<ModelSpec>().unwrap_err();
        assert_eq!(
            e,
            ModelError::HysteresisOffline {
                name: "damper+hysteresis".into()
            }
        );
        assert!(
            e.to_string()
                .contains("forcemap identify --model damper+hysteresis")
        );
        // An unknown base stays unknown.
        assert!(matches!(
            "bogus+hysteresis".parse::<ModelSpec>(),
            Err(ModelError::Unknown { .. })
        ));
        assert!("damper".parse::<ModelSpec>().is_ok());
    }

    #[test]
    fn kinds_come_from_the_channels_present() {
        let rig = SetupKind::BaseExcited.required_channels();
        assert_eq!(
            SetupKind::of_channels(present(rig)),
            Ok(SetupKind::BaseExcited)
        );
        let dp = SetupKind::DrivePoint.required_channels();
        assert_eq!(
            SetupKind::of_channels(present(dp)),
            Ok(SetupKind::DrivePoint)
        );
        let e = SetupKind::of_channels(present(&[Channel::RelativeDisplacementM])).unwrap_err();
        let text = e.to_string();
        assert!(text.contains("relative_displacement_m"), "{text}");
        assert!(text.contains("rig channels"), "{text}");
        assert!(text.contains("drive-point channels"), "{text}");
    }

    #[test]
    fn the_mass_is_checked_once_for_every_source() {
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let c = SetupConstants {
                mass_kg: Some(bad),
                ..SetupConstants::default()
            };
            assert!(matches!(
                SetupKind::BaseExcited.resolve(&c),
                Err(RecipeError::BadMass(_))
            ));
        }
        assert_eq!(
            SetupKind::BaseExcited.resolve(&SetupConstants::default()),
            Err(RecipeError::MissingMass)
        );
        let flag = SetupConstants {
            mass_kg: Some(36.0),
            ..SetupConstants::default()
        };
        let bag = SetupConstants {
            mass_kg: Some(40.0),
            ..SetupConstants::default()
        };
        assert_eq!(
            SetupKind::BaseExcited.resolve(&flag.or(bag.clone())),
            Ok(SetupSpec::BaseExcited { mass_kg: 36.0 })
        );
        assert_eq!(
            SetupKind::BaseExcited.resolve(&SetupConstants::default().or(bag)),
            Ok(SetupSpec::BaseExcited { mass_kg: 40.0 })
        );
    }

    #[test]
    fn chains_are_checked() {
        let chain = |m: Vec<f64>, d: Option<usize>| SubstructureSpec::Chain {
            springs_n_per_m: vec![1.0; m.len()],
            dampers_n_s_per_m: vec![1.0; m.len()],
            masses_kg: m,
            drive_dof: d,
        };
        assert_eq!(
            chain(vec![], None).build(),
            Err(RecipeError::SubstructureLengths)
        );
        assert_eq!(
            chain(vec![1.0, 2.0], Some(2)).build(),
            Err(RecipeError::DriveDofOutOfRange {
                drive_dof: 2,
                masses: 2
            })
        );
        assert_eq!(chain(vec![1.0, 2.0], None).build().unwrap().drive_dof, 1);
        assert_eq!(
            SetupKind::DrivePoint.resolve(&SetupConstants::default()),
            Err(RecipeError::MissingSubstructure)
        );
    }

    #[test]
    fn names_parse_and_print_back() {
        for name in ["fd", "fd-multi", "output-error", "td-all", "td-7"] {
            let m: Method = name.parse().unwrap();
            assert_eq!(m.name(), name);
        }
        assert_eq!(
            "td".parse::<Method>(),
            Ok(Method::Td {
                points_per_step: Some(20)
            })
        );
        for bad in ["", "FD", "td-0", "td-x", "output"] {
            assert_eq!(
                bad.parse::<Method>(),
                Err(RecipeError::UnknownMethod(bad.into()))
            );
        }
        assert_eq!("uniform".parse::<Weighting>(), Ok(Weighting::Uniform));
        assert!("none".parse::<Weighting>().is_err());
        for (name, _) in crate::model::MODEL_NAMES {
            assert_eq!(name.parse::<ModelSpec>().unwrap().name, *name);
        }
        let e = "quadratic".parse::<ModelSpec>().unwrap_err().to_string();
        assert!(
            e.contains("unknown model 'quadratic'") && e.contains("coulomb-cubic"),
            "{e}"
        );
    }

    #[test]
    fn only_per_step_methods_run_live() {
        let recipe = |method| Recipe {
            setup: SetupSpec::BaseExcited { mass_kg: 36.0 },
            model: "coulomb".parse().unwrap(),
            method,
            weighting: Weighting::Noise,
            phasor: PhasorOptions::default(),
            tracking: Tracking::Converged,
        };
        assert!(recipe(Method::Fd).check_live().is_ok());
        assert!(recipe(Method::FdMulti).check_live().is_ok());
        for m in [
            Method::OutputError,
            Method::Td {
                points_per_step: None,
            },
        ] {
            let e = recipe(m).check_live().unwrap_err().to_string();
            assert!(e.contains("never keeps"), "{e}");
        }
    }

    #[test]
    fn a_recipe_survives_a_round_trip_through_serde() {
        let r = Recipe {
            setup: SetupSpec::DrivePoint {
                substructure: SubstructureSpec::PaperThreeDof,
            },
            model: "coulomb-atan"
                .parse::<ModelSpec>()
                .unwrap()
                .with_options(ModelOptions {
                    atan_slope_s_per_m: Some(1000.0),
                    polynomial_order: None,
                }),
            method: Method::Td {
                points_per_step: Some(20),
            },
            weighting: Weighting::Uniform,
            phasor: PhasorOptions::default(),
            tracking: Tracking::Forgetting {
                factor_per_step: 0.8,
            },
        };
        let text = serde_json::to_string(&r).unwrap();
        assert!(text.contains(r#""kind":"drive-point""#), "{text}");
        let back: Recipe = serde_json::from_str(&text).unwrap();
        assert_eq!(back, r);
        // A recipe written before tracking existed is a converged one.
        let old = text.replace(r#","tracking":{"forgetting":{"factor_per_step":0.8}}"#, "");
        assert_ne!(old, text);
        let back: Recipe = serde_json::from_str(&old).unwrap();
        assert_eq!(back.tracking, Tracking::Converged);
    }

    #[test]
    fn a_forgetting_factor_is_in_zero_to_one() {
        assert_eq!(Tracking::from_factor(1.0).unwrap(), Tracking::Converged);
        assert_eq!(Tracking::from_factor(0.8).unwrap().factor_per_step(), 0.8);
        for bad in [0.0, -0.5, 1.2, f64::NAN] {
            let e = Tracking::from_factor(bad).unwrap_err().to_string();
            assert!(e.contains("forgetting_per_step"), "{e}");
        }
    }
}
