//! The Stribeck family's member found, described for the verdict: the excess of static over
//! kinetic friction, its velocity and the shape exponent of exp(-|x'/vs|^delta) (2 is the
//! Gaussian law).

use super::effects::stribeck_exponent;
use super::fit::Fitted;
use crate::basis::StribeckVelocity;
use crate::element::stribeck_decay;

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

/// `member` with the shape exponents that predict alike named after it ("...; exponents 0.5,
/// 1.0 and 2.0 predict the held-out records alike: the shape is not identified on these
/// steps"), unchanged when fewer than two do.
pub fn with_alike_exponents(member: String, alike: &[f64]) -> String {
    let names: Vec<String> = alike.iter().map(|e| format!("{e:.1}")).collect();
    match names.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!(
            "{member}; exponents {} and {last} predict the held-out records alike: the shape is not identified on these steps",
            rest.join(", ")
        ),
        _ => member,
    }
}

/// The Stribeck velocity at which the law of shape `exponent` is nearest `law`: least squares
/// between exp(-(v/vs)^exponent) and `law`'s curve over speeds up to four of its velocities,
/// where its excess has fallen off, the velocity searched over a factor of four each way.
/// The start of another exponent's refit when the phasor search offered none: the shapes
/// differ near zero speed and in the tail, so the nearest curve is only somewhat nearer than the
/// same velocity's (exponent 0.5 against a Gaussian: 12 % less squared difference).
pub fn equivalent_velocity_mps(law: StribeckVelocity, exponent: f64) -> f64 {
    const SPEEDS: usize = 200;
    const CANDIDATES: usize = 241;
    let curve = |vs: f64, delta: f64, v: f64| stribeck_decay(v, vs, delta);
    let v_max = 4.0 * law.velocity_mps;
    let misfit = |vs: f64| -> f64 {
        (1..=SPEEDS)
            .map(|i| {
                let v = v_max * i as f64 / SPEEDS as f64;
                (curve(vs, exponent, v) - curve(law.velocity_mps, law.exponent, v)).powi(2)
            })
            .sum()
    };
    (0..CANDIDATES)
        .map(|i| law.velocity_mps * 4f64.powf(-1.0 + 2.0 * i as f64 / (CANDIDATES - 1) as f64))
        .min_by(|&a, &b| misfit(a).total_cmp(&misfit(b)))
        .unwrap_or(law.velocity_mps)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_shape_is_its_own_equivalent() {
        let law = StribeckVelocity {
            velocity_mps: 0.03,
            exponent: 1.0,
        };
        let vs = equivalent_velocity_mps(law, 1.0);
        assert!((vs / 0.03 - 1.0).abs() < 0.01, "{vs}");
    }

    #[test]
    fn another_shape_is_nearer_the_curve_at_its_equivalent_velocity() {
        // Least squares over speeds up to four Stribeck velocities, as the function minimises:
        // for a Gaussian at 72.5 mm/s, exponent 0.5 is nearest at about 49 mm/s (its fall near
        // zero is faster, its tail longer), 12 % nearer than at 72.5 mm/s.
        let law = StribeckVelocity::gaussian(0.0725);
        let squares = |vs: f64, exponent: f64| -> f64 {
            (1..=200)
                .map(|i| {
                    let v = 0.29 * f64::from(i) / 200.0;
                    ((-(v / vs).powf(exponent)).exp() - (-(v / 0.0725).powi(2)).exp()).powi(2)
                })
                .sum()
        };
        let vs = equivalent_velocity_mps(law, 0.5);
        assert!((vs - 0.049).abs() < 0.001, "{vs}");
        assert!(squares(vs, 0.5) < 0.9 * squares(0.0725, 0.5));
        let vs1 = equivalent_velocity_mps(law, 1.0);
        assert!(squares(vs1, 1.0) < squares(0.0725, 1.0), "{vs1}");
    }
}
