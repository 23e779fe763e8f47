//! Everything a setup is, in one file: its kind as the data's channels show it
//! ([`SetupKind`]: required channels, driven channel), its constants as sources give them
//! ([`SetupConstants`], [`SubstructureSpec`]), the setup a recipe states ([`SetupSpec`], serde)
//! and the checked setup the identification runs on ([`Setup`]). A new setup is a variant of
//! each enum here, its equations per harmonic in `identify::fd` and its simulator in
//! `sim::run`.

use std::fmt;

use serde::{Deserialize, Serialize};

use super::RecipeError;
use crate::frf::LinearSubstructure;
use crate::record::Channel;
use crate::sim::element::ElementDrive;

/// The kinds of setup forcemap identifies, as the channels of the data show them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SetupKind {
    /// Base-excited test rig with a known mass (eq. 23): driven by the base displacement.
    #[serde(rename = "rig")]
    BaseExcited,
    /// Force-driven structure with the element at the drive point of a known linear
    /// substructure (eqs. 21-22, the 3-DOF example): driven by the force.
    DrivePoint,
    /// The element tested alone (damper dyno, mount or bushing tester, spring tester): the
    /// displacement across it and the force through it are measured, with a moving mass
    /// between load cell and element that is known or identified. Also a force-driven
    /// single-DOF system (mass, spring, damper, nonlinear terms) with its mass identified.
    Element,
}

impl SetupKind {
    /// Every kind, in the order [`SetupKind::of_channels`] tries them.
    /// The drive point comes before the element: its channels include the element's.
    pub const ALL: [SetupKind; 3] = [
        SetupKind::BaseExcited,
        SetupKind::DrivePoint,
        SetupKind::Element,
    ];

    /// The kind's name in exports and messages (`rig`, `drive-point`, `element`).
    pub fn name(self) -> &'static str {
        match self {
            SetupKind::BaseExcited => "rig",
            SetupKind::DrivePoint => "drive-point",
            SetupKind::Element => "element",
        }
    }

    /// The channels a record of this kind must hold. (An element test may also hold the
    /// moving fixture's acceleration, `mass_acceleration_mps2`, used for the inertia force.)
    pub fn required_channels(self) -> &'static [Channel] {
        match self {
            SetupKind::BaseExcited => &[
                Channel::BaseDisplacementM,
                Channel::RelativeDisplacementM,
                Channel::MassAccelerationMps2,
            ],
            SetupKind::DrivePoint => &[
                Channel::RelativeDisplacementM,
                Channel::DrivePointDisplacementM,
                Channel::ForceN,
            ],
            SetupKind::Element => &[Channel::RelativeDisplacementM, Channel::ForceN],
        }
    }

    /// The channel whose amplitude (sine) or RMS (random) is the excitation level.
    pub fn driven_channel(self) -> Channel {
        match self {
            SetupKind::BaseExcited => Channel::BaseDisplacementM,
            SetupKind::DrivePoint => Channel::ForceN,
            // Element benches are displacement-controlled (a force-driven single-DOF system's
            // steps are found from its displacement just as well).
            SetupKind::Element => Channel::RelativeDisplacementM,
        }
    }

    /// The kind of data that hold the channels `has` says they hold: the first kind (in
    /// [`SetupKind::ALL`] order) whose required channels are all there.
    pub fn of_channels(has: impl Fn(Channel) -> bool) -> Result<SetupKind, RecipeError> {
        SetupKind::ALL
            .into_iter()
            .find(|k| k.required_channels().iter().all(|c| has(*c)))
            .ok_or_else(|| RecipeError::UnknownChannels {
                present: {
                    let p: Vec<&str> = Channel::ALL
                        .iter()
                        .filter(|c| has(**c))
                        .map(|c| c.name())
                        .collect();
                    if p.is_empty() {
                        "none".to_string()
                    } else {
                        p.join(", ")
                    }
                },
            })
    }

    /// The setup of this kind with the constants given.
    pub fn resolve(self, constants: &SetupConstants) -> Result<SetupSpec, RecipeError> {
        match self {
            SetupKind::BaseExcited => {
                let mass_kg = constants.mass_kg.ok_or(RecipeError::MissingMass)?;
                Ok(SetupSpec::BaseExcited {
                    mass_kg: check_mass_kg(mass_kg)?,
                })
            }
            SetupKind::DrivePoint => {
                let s = constants
                    .substructure
                    .clone()
                    .ok_or(RecipeError::MissingSubstructure)?;
                s.build()?;
                Ok(SetupSpec::DrivePoint { substructure: s })
            }
            // No mass given: the moving mass is identified with the element.
            SetupKind::Element => Ok(SetupSpec::Element {
                moving_mass_kg: constants.mass_kg.map(check_moving_mass_kg).transpose()?,
                drive: None,
            }),
        }
    }
}

impl fmt::Display for SetupKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The one check of a rig mass.
pub fn check_mass_kg(mass_kg: f64) -> Result<f64, RecipeError> {
    if mass_kg > 0.0 && mass_kg.is_finite() {
        Ok(mass_kg)
    } else {
        Err(RecipeError::BadMass(mass_kg))
    }
}

/// The check of an element test's moving mass (between load cell and element): zero is a load
/// cell at the fixed end.
pub fn check_moving_mass_kg(mass_kg: f64) -> Result<f64, RecipeError> {
    if mass_kg >= 0.0 && mass_kg.is_finite() {
        Ok(mass_kg)
    } else {
        Err(RecipeError::BadMovingMass(mass_kg))
    }
}

/// The linear substructure of a drive-point setup as a user describes it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SubstructureSpec {
    /// Substructure I of the paper's 3-DOF example.
    PaperThreeDof,
    /// A chain ground -(k[0], c[0])- m[0] -(k[1], c[1])- m[1] - ... with the element at
    /// `drive_dof` (the last mass when absent).
    Chain {
        masses_kg: Vec<f64>,
        springs_n_per_m: Vec<f64>,
        dampers_n_s_per_m: Vec<f64>,
        drive_dof: Option<usize>,
    },
}

impl SubstructureSpec {
    /// The substructure, after checking that the chain is consistent.
    pub fn build(&self) -> Result<LinearSubstructure, RecipeError> {
        match self {
            SubstructureSpec::PaperThreeDof => {
                Ok(LinearSubstructure::paper_three_dof_substructure_i())
            }
            SubstructureSpec::Chain {
                masses_kg,
                springs_n_per_m,
                dampers_n_s_per_m,
                drive_dof,
            } => {
                let n = masses_kg.len();
                if n == 0 || springs_n_per_m.len() != n || dampers_n_s_per_m.len() != n {
                    return Err(RecipeError::SubstructureLengths);
                }
                let drive = drive_dof.unwrap_or(n - 1);
                if drive >= n {
                    return Err(RecipeError::DriveDofOutOfRange {
                        drive_dof: drive,
                        masses: n,
                    });
                }
                Ok(LinearSubstructure::chain(
                    masses_kg,
                    springs_n_per_m,
                    dampers_n_s_per_m,
                    drive,
                ))
            }
        }
    }
}

/// The constants of a setup as given by one source (a flag, a params file, the constants a
/// bag or the rig's topic carries); any may be absent.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SetupConstants {
    pub mass_kg: Option<f64>,
    pub substructure: Option<SubstructureSpec>,
}

impl SetupConstants {
    /// These constants where given, else `fallback`'s: sources merge in their order of
    /// priority, `flag.or(params).or(bag)`.
    pub fn or(self, fallback: SetupConstants) -> SetupConstants {
        SetupConstants {
            mass_kg: self.mass_kg.or(fallback.mass_kg),
            substructure: self.substructure.or(fallback.substructure),
        }
    }
}

/// A setup with its constants, as a recipe states it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum SetupSpec {
    #[serde(rename = "rig")]
    BaseExcited {
        mass_kg: f64,
    },
    DrivePoint {
        substructure: SubstructureSpec,
    },
    /// `moving_mass_kg` None: identified (parameter `m`). `drive`: what the bench controlled,
    /// where the user names it (None: decided from the data).
    Element {
        moving_mass_kg: Option<f64>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        drive: Option<ElementDrive>,
    },
}

impl SetupSpec {
    pub fn kind(&self) -> SetupKind {
        match self {
            SetupSpec::BaseExcited { .. } => SetupKind::BaseExcited,
            SetupSpec::DrivePoint { .. } => SetupKind::DrivePoint,
            SetupSpec::Element { .. } => SetupKind::Element,
        }
    }

    /// The checked setup the identification runs on.
    pub fn setup(&self) -> Result<Setup, RecipeError> {
        Ok(match self {
            SetupSpec::BaseExcited { mass_kg } => Setup::BaseExcited {
                mass_kg: check_mass_kg(*mass_kg)?,
            },
            SetupSpec::DrivePoint { substructure } => Setup::DrivePoint {
                substructure: substructure.build()?,
            },
            SetupSpec::Element {
                moving_mass_kg,
                drive,
            } => Setup::Element {
                moving_mass_kg: moving_mass_kg.map(check_moving_mass_kg).transpose()?,
                drive: *drive,
            },
        })
    }
}

impl fmt::Display for SetupSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SetupSpec::BaseExcited { mass_kg } => write!(f, "base-excited rig, mass {mass_kg} kg"),
            SetupSpec::DrivePoint { .. } => f.write_str("drive point of a linear substructure"),
            SetupSpec::Element {
                moving_mass_kg: Some(m),
                ..
            } => write!(f, "element test, moving mass {m} kg"),
            SetupSpec::Element {
                moving_mass_kg: None,
                ..
            } => f.write_str("element test, moving mass identified"),
        }
    }
}

/// A setup with its constants checked and built: what the identification runs on.
#[derive(Debug, Clone, PartialEq)]
pub enum Setup {
    /// Base-excited rig (eq. 23): m x_o'' = -g(x, x'), x = x_o - x_i.
    BaseExcited { mass_kg: f64 },
    /// Force-driven structure with the element at the drive point of a known linear
    /// substructure (eqs. 21-22): X_d = alpha_dd (F - G).
    DrivePoint { substructure: LinearSubstructure },
    /// Element test: F = m a + g(x, x'), with the moving mass known or (None) identified, and
    /// what the bench controlled where the user names it (`drive`; None: decided from the
    /// data, [`crate::identify::records_drive`]).
    Element {
        moving_mass_kg: Option<f64>,
        drive: Option<ElementDrive>,
    },
}

impl Setup {
    pub fn kind(&self) -> SetupKind {
        match self {
            Setup::BaseExcited { .. } => SetupKind::BaseExcited,
            Setup::DrivePoint { .. } => SetupKind::DrivePoint,
            Setup::Element { .. } => SetupKind::Element,
        }
    }

    /// Parameters the setup adds to the model's: an element test's moving mass `m` when it
    /// is not known. Their equation columns follow the model's.
    pub fn extra_parameters(&self) -> &'static [&'static str] {
        match self {
            Setup::Element {
                moving_mass_kg: None,
                ..
            } => &["m"],
            _ => &[],
        }
    }

    /// The setup with the parameters it added ([`Setup::extra_parameters`], in that order) set
    /// to `values`: an element test whose moving mass was identified becomes one whose mass
    /// is known, so that its element force is the measured force less the identified inertia.
    /// Values beyond the setup's extra parameters are ignored.
    pub fn with_extra_values(&self, values: &[f64]) -> Setup {
        match (self, values.first()) {
            (
                Setup::Element {
                    moving_mass_kg: None,
                    drive,
                },
                Some(m),
            ) => Setup::Element {
                moving_mass_kg: Some(*m),
                drive: *drive,
            },
            _ => self.clone(),
        }
    }

    /// The rig's mass, for what only a base-excited rig has (its gap diagnosis).
    pub fn rig_mass_kg(&self) -> Option<f64> {
        match self {
            Setup::BaseExcited { mass_kg } => Some(*mass_kg),
            Setup::DrivePoint { .. } | Setup::Element { .. } => None,
        }
    }
}
