//! The constants of a setup as a user gives them in a ROS 2 params file.

use anyhow::bail;
use forcemap_math::frf::LinearSubstructure;

use crate::params::Params;

/// The drive-point substructure from the params (`substructure.*`).
pub fn substructure(params: &Params, source: &str) -> anyhow::Result<LinearSubstructure> {
    if params.opt_str("substructure")? == Some("paper_three_dof") {
        return Ok(LinearSubstructure::paper_three_dof_substructure_i());
    }
    let masses = params.opt_f64_array("substructure.masses_kg")?;
    let springs = params.opt_f64_array("substructure.springs_n_per_m")?;
    let dampers = params.opt_f64_array("substructure.dampers_n_s_per_m")?;
    let (Some(m), Some(k), Some(c)) = (masses, springs, dampers) else {
        bail!(
            "{source}: a drive-point export (force_n, drive_point_displacement_m) needs the linear substructure the element is attached to: \
             give `substructure: paper_three_dof` or the chain `substructure.masses_kg`, `substructure.springs_n_per_m`, \
             `substructure.dampers_n_s_per_m` (ground first) and `substructure.drive_dof` in a --params file \
             (see launch_configs/three_dof.params.yaml)"
        );
    };
    if m.is_empty() || m.len() != k.len() || m.len() != c.len() {
        bail!(
            "{source}: substructure.masses_kg, springs_n_per_m and dampers_n_s_per_m must have the same, non-zero length"
        );
    }
    let drive = params
        .opt_usize("substructure.drive_dof")?
        .unwrap_or(m.len() - 1);
    if drive >= m.len() {
        bail!(
            "{source}: substructure.drive_dof = {drive} but the chain has {} masses",
            m.len()
        );
    }
    Ok(LinearSubstructure::chain(&m, &k, &c, drive))
}
