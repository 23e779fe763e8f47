//! The Stribeck family's member found, described for the verdict: the excess of static over
//! kinetic friction, its velocity and the shape exponent of exp(-|x'/vs|^delta) (2 is the
//! Gaussian law).

use super::effects::stribeck_exponent;
use super::fit::Fitted;

/// "Stribeck excess 17.4 N, vs 19.8 mm/s, exponent 1.0": the fitted excess fs, the Stribeck
/// velocity and its shape exponent (with "(not searched)" after it when the grid had only the
/// Gaussian one). None when `f` holds no Stribeck term.
pub fn describe(f: &Fitted) -> Option<String> {
    let law = f.structure.terms.iter().find_map(|t| t.stribeck())?;
    let fs = f.coefficient("fs")?;
    let searched = if stribeck_exponent(&f.structure).is_some() {
        ""
    } else {
        " (not searched)"
    };
    Some(format!(
        "Stribeck excess {fs:.1} N, vs {:.1} mm/s, exponent {:.1}{searched}",
        1e3 * law.velocity_mps,
        law.exponent
    ))
}
