//! What the time-domain diagnosis returns, and where the baseline's residual lies.

use serde::Serialize;

use super::candidates::AxisRankedEffect;
use super::model::TdFit;
use super::preprocess::Prepared;
use crate::diagnose::{Findings, ParameterValue};

/// Where the baseline's residual lies, by velocity.
#[derive(Debug, Clone, Serialize)]
pub struct AxisLocated {
    /// Mean residual force for q' > 0 and q' < 0 [N] (asymmetry).
    pub mean_residual_positive_velocity_n: f64,
    pub mean_residual_negative_velocity_n: f64,
    /// RMS residual near zero velocity (|q'| < 10 % of the peak) and elsewhere [N].
    pub rms_residual_near_zero_velocity_n: f64,
    pub rms_residual_elsewhere_n: f64,
    pub summary: Vec<String>,
}

/// The floor of the verdict (see the docs of [`super`], "Floor").
#[derive(Debug, Clone, Serialize)]
pub struct AxisFloor {
    /// The floor the rule is applied with: the smallest validation error of the flexible
    /// law, the baseline and the candidates [%].
    pub floor_percent: f64,
    /// Which of them set it.
    pub set_by: String,
    /// The flexible memoryless law's relative force error on the validation record [%].
    pub flexible_law_percent: f64,
    /// The same on the fitting record [%].
    pub flexible_law_fit_percent: f64,
    /// The member of the flexible family with the smallest validation error.
    pub flexible_law: String,
    /// How many members the family has.
    pub flexible_laws_tried: usize,
    pub what: String,
}

/// The validation record's decimated traces, for plots (not serialised).
#[derive(Debug, Clone, Default)]
pub struct AxisTraces {
    pub time_s: Vec<f64>,
    /// Low-passed position and its central difference at the decimated samples.
    pub position_m: Vec<f64>,
    pub velocity_mps: Vec<f64>,
    /// Measured force (anti-alias filtered) [N].
    pub measured_n: Vec<f64>,
    /// The baseline's force [N].
    pub baseline_n: Vec<f64>,
    /// The top candidate's force, when there is a candidate [N].
    pub top_n: Option<Vec<f64>>,
}

/// The time-domain diagnosis.
#[derive(Debug, Clone, Serialize)]
pub struct AxisDiagnosis {
    /// The verdict on the relative force error on the validation record
    /// ([`crate::diagnose::Evidence::ValidationForceError`]); its floor is `floor.floor_percent`.
    #[serde(flatten)]
    pub findings: Findings,
    pub fit_before_percent: f64,
    pub floor: AxisFloor,
    pub baseline_model: String,
    pub baseline_parameters: Vec<ParameterValue>,
    pub ranked_effects: Vec<AxisRankedEffect>,
    pub located: AxisLocated,
    /// Decimated equations on the fitting and the validation record.
    pub equations: usize,
    pub validation_equations: usize,
    #[serde(skip)]
    pub traces: AxisTraces,
}

/// Where the baseline's residual lies on the validation record, by velocity.
pub(super) fn locate(pv: &Prepared, b: &TdFit) -> AxisLocated {
    let qd = pv.motion.kept_values(&pv.motion.qd);
    let vpk = qd.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-12);
    let (mut sp, mut np, mut sn, mut nn, mut s0, mut n0, mut s1, mut n1) =
        (0.0, 0usize, 0.0, 0usize, 0.0, 0usize, 0.0, 0usize);
    for ((t, pred), v) in pv.force.iter().zip(&b.validation_prediction).zip(&qd) {
        let r = t - pred;
        if *v > 0.0 {
            sp += r;
            np += 1;
        } else if *v < 0.0 {
            sn += r;
            nn += 1;
        }
        if v.abs() < 0.1 * vpk {
            s0 += r * r;
            n0 += 1;
        } else {
            s1 += r * r;
            n1 += 1;
        }
    }
    let mp = sp / np.max(1) as f64;
    let mn = sn / nn.max(1) as f64;
    let r0 = (s0 / n0.max(1) as f64).sqrt();
    let r1 = (s1 / n1.max(1) as f64).sqrt();
    AxisLocated {
        mean_residual_positive_velocity_n: mp,
        mean_residual_negative_velocity_n: mn,
        rms_residual_near_zero_velocity_n: r0,
        rms_residual_elsewhere_n: r1,
        summary: vec![
            format!("residual RMS near zero velocity {r0:.2} N, elsewhere {r1:.2} N"),
            format!("mean residual {mp:+.2} N moving forward, {mn:+.2} N moving back"),
        ],
    }
}
