//! The series_compliance candidate: the baseline's damper `c x'` in series with a spring `ks`
//! (oil compressibility, rubber mounts). Per harmonic the damper force satisfies
//! `F (1 + i n w c / ks) = i n w c X`: for a given relaxation time `tau = c / ks` it is `c`
//! times the velocity through the low-pass `1 / (1 + i n w tau)`, linear in `c`. So `tau` is
//! searched (a grid, then a golden-section refinement of the cross-validated error on
//! `ln tau`) with `c` and every other coefficient solved by least squares inside.

use num_complex::Complex64;

use super::cycles::{harmonics_of, synthesize};
use super::effects::{SERIES_RELAXATION_MULTIPLES, Structure, series_structure};
use super::fit::Fitted;
use super::search::PhasorCandidate;

/// The symbol of the viscous damper term that series compliance and drift act on.
pub const DAMPER_SYMBOL: &str = "c";

/// Golden-section steps of a refinement (each one fit per step for the cross-validation):
/// they narrow the grid's bracket (a factor 1.7 either side) to about 1 % in tau.
const REFINE_STEPS: usize = 10;

/// The damper's unit-c force over one period: the velocity (one period on a uniform grid)
/// with its n-th harmonic through `1 / (1 + i n w tau)`.
pub fn damper_column(velocity_mps: &[f64], frequency_hz: f64, tau_s: f64) -> Vec<f64> {
    let l = velocity_mps.len();
    let w = std::f64::consts::TAU * frequency_hz;
    let h = harmonics_of(velocity_mps, l / 2 - 1);
    synthesize(&h, l, |n| Complex64::new(1.0, n as f64 * w * tau_s).inv())
}

/// The best grid candidate refined: golden-section search of `ln tau` between the grid's
/// neighbours of the best value, `evaluate` fitting and cross-validating one structure (None
/// when its fit fails or is not physical). Keeps the grid's candidate if nothing beats it.
pub fn refine<E>(
    best: PhasorCandidate,
    mut evaluate: impl FnMut(Structure) -> Result<Option<PhasorCandidate>, E>,
) -> Result<PhasorCandidate, E> {
    let Some(tau0) = best.structure.series_relaxation_s else {
        return Ok(best);
    };
    let key = PhasorCandidate::step_error_percent;
    let spacing = (SERIES_RELAXATION_MULTIPLES[1] / SERIES_RELAXATION_MULTIPLES[0]).ln();
    let last = golden_section_ln(tau0, spacing, |u| {
        let c = evaluate(series_structure(u.exp()))?;
        Ok((c.as_ref().map_or(f64::INFINITY, key), c))
    })?;
    let mut winner = best;
    for (k, c) in last {
        if let Some(c) = c
            && k < key(&winner)
        {
            winner = c;
        }
    }
    Ok(winner)
}

/// Golden-section search of a positive shape parameter on its log: from `value` a factor
/// `exp(spacing)` either side, [`REFINE_STEPS`] narrowings; `at(ln value)` gives the error to
/// minimise and what it was found with. Returns the two last points, (error, what).
pub fn golden_section_ln<T, E>(
    value: f64,
    spacing: f64,
    mut at: impl FnMut(f64) -> Result<(f64, T), E>,
) -> Result<[(f64, T); 2], E> {
    let (mut a, mut b) = (value.ln() - spacing, value.ln() + spacing);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let mut c1 = b - g * (b - a);
    let mut c2 = a + g * (b - a);
    let mut f1 = at(c1)?;
    let mut f2 = at(c2)?;
    for _ in 0..REFINE_STEPS {
        if f1.0 < f2.0 {
            b = c2;
            c2 = c1;
            f2 = f1;
            c1 = b - g * (b - a);
            f1 = at(c1)?;
        } else {
            a = c1;
            c1 = c2;
            f1 = f2;
            c2 = a + g * (b - a);
            f2 = at(c2)?;
        }
    }
    Ok([f1, f2])
}

/// The fitted series spring and damper, e.g. "ks 3.10 kN/m, c 184.0 N s/m, relaxation
/// 59.4 ms)"; None when the fit is not a series compliance.
pub fn describe(f: &Fitted) -> Option<String> {
    let tau = f.structure.series_relaxation_s?;
    let c = damping(f)?;
    Some(format!(
        "ks {:.2} kN/m, c {:.1} N s/m, relaxation {:.1} ms",
        c / tau / 1e3,
        c,
        tau * 1e3
    ))
}

/// The fitted damper coefficient c [N s/m].
pub fn damping(f: &Fitted) -> Option<f64> {
    f.coefficient(DAMPER_SYMBOL)
}

/// The series spring stiffness ks = c / tau [N/m].
pub fn stiffness_n_per_m(f: &Fitted) -> Option<f64> {
    Some(damping(f)? / f.structure.series_relaxation_s?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_damper_column_is_the_lagged_velocity_of_a_sine() {
        // v = cos(w t): the column is |H| cos(w t + arg H), H = 1 / (1 + i w tau).
        let (l, f, tau) = (256, 2.0, 0.05);
        let w = std::f64::consts::TAU * f;
        let t = |i: usize| i as f64 / (l as f64 * f);
        let v: Vec<f64> = (0..l).map(|i| (w * t(i)).cos()).collect();
        let col = damper_column(&v, f, tau);
        let h = Complex64::new(1.0, w * tau).inv();
        for (i, c) in col.iter().enumerate() {
            let want = h.norm() * (w * t(i) + h.arg()).cos();
            assert!((c - want).abs() < 1e-12, "{i}: {c} vs {want}");
        }
    }
}
