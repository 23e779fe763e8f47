//! The Stribeck family's member found, described for the verdict: the excess of static over
//! kinetic friction and its velocity (the law is Gaussian in speed, exp(-(x'/vs)^2); its
//! shape exponent is not searched on main, see docs/diagnosis.md).

use super::fit::Fitted;

/// "Stribeck excess 12.1 N, vs 36.0 mm/s, Gaussian": the fitted excess fs and the Stribeck
/// velocity. None when `f` holds no Stribeck term.
pub fn describe(f: &Fitted) -> Option<String> {
    let vs = f
        .structure
        .terms
        .iter()
        .find_map(|t| t.stribeck_velocity_mps())?;
    let fs = f.coefficient("fs")?;
    Some(format!(
        "Stribeck excess {fs:.1} N, vs {:.1} mm/s, Gaussian",
        1e3 * vs
    ))
}
