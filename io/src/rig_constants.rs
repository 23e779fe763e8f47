//! The constants of a setup as a user gives them in a ROS 2 params file (`mass_kg`,
//! `substructure...`), and as a bag or the rig's `parameters` topic carries them
//! (`mass_kg`). Which of them a setup needs and how they are checked is
//! `forcemap_math::recipe`'s rule; this module only reads them.

use std::collections::BTreeMap;

use forcemap_math::recipe::{SetupConstants, SubstructureSpec};

use crate::params::{Params, ParamsError};

/// The setup constants in `params` (absent ones are `None`).
pub fn from_params(params: &Params) -> Result<SetupConstants, ParamsError> {
    Ok(SetupConstants {
        mass_kg: params.opt_f64("mass_kg")?,
        substructure: substructure(params)?,
    })
}

/// The rig constants a bag carries, by name (`/rig/parameters`: `mass_kg`).
pub fn from_values(values: &BTreeMap<String, f64>) -> SetupConstants {
    SetupConstants {
        mass_kg: values.get("mass_kg").copied(),
        substructure: None,
    }
}

/// The drive-point substructure in the params (`substructure: paper_three_dof`, or the chain
/// `substructure.masses_kg`, `.springs_n_per_m`, `.dampers_n_s_per_m`, `.drive_dof`), if
/// given; its consistency is checked when the setup is resolved.
fn substructure(params: &Params) -> Result<Option<SubstructureSpec>, ParamsError> {
    if params.opt_str("substructure")? == Some("paper_three_dof") {
        return Ok(Some(SubstructureSpec::PaperThreeDof));
    }
    let masses = params.opt_f64_array("substructure.masses_kg")?;
    let springs = params.opt_f64_array("substructure.springs_n_per_m")?;
    let dampers = params.opt_f64_array("substructure.dampers_n_s_per_m")?;
    let drive_dof = params.opt_usize("substructure.drive_dof")?;
    Ok(match (masses, springs, dampers) {
        (Some(masses_kg), Some(springs_n_per_m), Some(dampers_n_s_per_m)) => {
            Some(SubstructureSpec::Chain {
                masses_kg,
                springs_n_per_m,
                dampers_n_s_per_m,
                drive_dof,
            })
        }
        _ => None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use forcemap_math::recipe::{RecipeError, SetupKind};

    fn params(yaml: &str) -> Params {
        Params::from_yaml_str(yaml, std::path::Path::new("test.yaml"), None).unwrap()
    }

    #[test]
    fn a_chain_is_read_and_checked_when_resolved() {
        let p = params(
            "/**:\n  ros__parameters:\n    substructure:\n      masses_kg: [1.0, 2.0]\n      springs_n_per_m: [10.0, 20.0]\n      dampers_n_s_per_m: [0.1, 0.2]\n      drive_dof: 3\n",
        );
        let c = from_params(&p).unwrap();
        assert!(matches!(
            c.substructure,
            Some(SubstructureSpec::Chain {
                drive_dof: Some(3),
                ..
            })
        ));
        assert_eq!(
            SetupKind::DrivePoint.resolve(&c),
            Err(RecipeError::DriveDofOutOfRange {
                drive_dof: 3,
                masses: 2
            })
        );
    }

    #[test]
    fn the_paper_substructure_by_name() {
        let p = params(
            "/**:\n  ros__parameters:\n    substructure: paper_three_dof\n    mass_kg: 36.0\n",
        );
        let c = from_params(&p).unwrap();
        assert_eq!(c.substructure, Some(SubstructureSpec::PaperThreeDof));
        assert_eq!(c.mass_kg, Some(36.0));
    }
}
