//! The candidates of the time-domain path, their searched variants, and when a candidate's
//! shrink is significant.

use serde::Serialize;

use super::model::{AxisBaseline, Column};
use crate::diagnose::ParameterValue;
use crate::diagnose::effects::{Effect, Scales, SearchGrid, baseline_has, structures_on};

/// One candidate of the time-domain path.
#[derive(Debug, Clone, Serialize)]
pub struct AxisRankedEffect {
    pub effect: Effect,
    /// Relative force error on the validation record with the effect [%].
    pub gap_after_percent: f64,
    /// The same on the fitting record [%].
    pub fit_percent: f64,
    pub score_percent: f64,
    pub extra_parameters: usize,
    pub added_parameters: Vec<ParameterValue>,
    pub significant: bool,
    /// How consistently the effect lowers the squared force error over the validation
    /// record: mean over blocks of [`SHRINK_BLOCK_S`] of the reduction, over its standard
    /// error (see [`shrink_t_statistic`]).
    pub shrink_t: f64,
    pub signature: String,
}

/// Length of the blocks of the validation record over which the shrink's consistency is
/// judged [s]: long against the residual's correlation time (the force is low-passed at
/// 40 Hz), short enough for tens of blocks.
pub const SHRINK_BLOCK_S: f64 = 1.0;

/// A shrink counts as beyond chance when its block t-statistic is at least this.
pub const SHRINK_T_MIN: f64 = 3.0;

/// The t-statistic of the reduction of the squared force error from `before` to `after`
/// predictions of `measured`, over consecutive blocks of `block` samples: mean block
/// reduction over its standard error. Blocks are nearly independent where single samples are
/// not, so this is the chance a shrink has of being noise, as the noise floor is on the rig.
pub fn shrink_t_statistic(measured: &[f64], before: &[f64], after: &[f64], block: usize) -> f64 {
    let block = block.max(1);
    let d: Vec<f64> = measured
        .chunks(block)
        .zip(before.chunks(block).zip(after.chunks(block)))
        .filter(|(m, _)| m.len() == block)
        .map(|(m, (b, a))| {
            m.iter()
                .zip(b.iter().zip(a))
                .map(|(y, (pb, pa))| (y - pb).powi(2) - (y - pa).powi(2))
                .sum()
        })
        .collect();
    let n = d.len() as f64;
    if n < 2.0 {
        return 0.0;
    }
    let mean = d.iter().sum::<f64>() / n;
    let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    if var <= 0.0 {
        return if mean > 0.0 { f64::INFINITY } else { 0.0 };
    }
    mean / (var / n).sqrt()
}

/// The axis path's search grid: Stribeck velocities relative to the peak speed, yield
/// displacements relative to the position range (the rig's grid is relative to amplitudes).
pub(super) const AXIS_GRID: SearchGrid = SearchGrid {
    stribeck_velocity_fractions: &[0.01, 0.02, 0.05, 0.1, 0.2],
    hysteresis_yield_fractions: &[0.001, 0.003, 0.01, 0.03, 0.1],
    ..SearchGrid::RIG
};

/// The effects a force-driven axis is diagnosed for, in the order they are tried: the
/// element effects of the library (the rig-level ones, exciter delay, sensor low-pass and mass
/// error, have no meaning on an axis without a base; free play needs reversals of the load,
/// which a positioning axis does not see).
const AXIS_EFFECTS: [Effect; 7] = [
    Effect::CoulombFriction,
    Effect::StribeckFriction,
    Effect::QuadraticDamping,
    Effect::AsymmetricDamping,
    Effect::CubicStiffness,
    Effect::QuadraticStiffness,
    Effect::Hysteresis,
];

/// One searched variant of a candidate: its added columns and its searched parameter.
pub(super) struct Variant {
    pub(super) columns: Vec<Column>,
    pub(super) searched: Option<(String, f64)>,
    pub(super) extra_parameters: usize,
}

/// The candidates not in `baseline`, each with its searched variants, built by the effect
/// library (`effects::structures_on`) on the axis's grid.
pub(super) fn candidates(
    baseline: AxisBaseline,
    vmax: f64,
    range: f64,
) -> Vec<(Effect, Vec<Variant>)> {
    let model = baseline.model();
    let scales = Scales {
        max_displacement_m: range,
        max_velocity_mps: vmax,
        max_frequency_hz: f64::NAN,
    };
    AXIS_EFFECTS
        .into_iter()
        .filter(|e| !baseline_has(&model, *e))
        .map(|effect| {
            let variants = structures_on(&model, effect, &scales, &AXIS_GRID)
                .into_iter()
                .filter_map(|s| {
                    let mut columns: Vec<Column> = s.terms.into_iter().map(Column::Term).collect();
                    // The records integrate the one-parameter law only: a member of another
                    // shape is not offered (the grid builds none), never run as that law.
                    if let Some(law) = s.hysteresis {
                        columns.push(Column::BoucWen(law.one_parameter_yield_m()?));
                    }
                    Some(Variant {
                        columns,
                        searched: s.searched.into_iter().next(),
                        extra_parameters: s.extra_parameters,
                    })
                })
                .collect();
            (effect, variants)
        })
        .collect()
}

/// Whether a candidate's shrink is beyond chance on the axis: its penalised score beats the
/// baseline's, it removes more than 10 % of the gap and 0.2 %-points, and it does so
/// consistently over the validation record ([`SHRINK_T_MIN`]). The rig path asks the shrink to
/// exceed the noise floor instead; here the floor is not the noise but everything no force law
/// removes, and a shrink below it can still be certain (EMPS with the Coulomb baseline).
pub fn significant_on_axis(gap_before: f64, r: &AxisRankedEffect, baseline_score: f64) -> bool {
    r.score_percent < baseline_score
        && gap_before - r.gap_after_percent > (0.1 * gap_before).max(0.2)
        && r.shrink_t >= SHRINK_T_MIN
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shrink_t_statistic_is_mean_over_standard_error_of_the_block_reductions() {
        // Blocks of 2: the reductions are 2, 1, 5, 2 (mean 2.5, sample variance 3).
        let measured = vec![0.0; 8];
        let before = [1.0, 1.0, 1.0, 0.0, 2.0, 1.0, 1.0, 1.0];
        let after = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        let t = shrink_t_statistic(&measured, &before, &after, 2);
        let want = 2.5 / (3.0 / 4.0f64).sqrt();
        assert!((t - want).abs() < 1e-12, "{t} vs {want}");
        // Better in as many blocks as worse by the same amounts: no evidence.
        let after = [0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 1.0, 2.0];
        let before = [0.0, 2.0, 0.0, 0.0, 1.0, 2.0, 0.0, 0.0];
        assert_eq!(shrink_t_statistic(&measured, &before, &after, 2), 0.0);
        // A trailing partial block is left out; fewer than two blocks give no evidence.
        assert_eq!(shrink_t_statistic(&[0.0; 3], &[1.0; 3], &[0.0; 3], 2), 0.0);
    }
}
