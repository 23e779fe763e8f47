//! What the rig diagnosis returns: the ranked candidates, the best pair, the verdict and
//! where the gap lies ([`Diagnosis`], serialised for `--json`), and what its plots need beside
//! it ([`DiagnosisDetail`]).

use serde::Serialize;

use super::effects::Effect;
use super::findings::Findings;
use super::fit::Fitted;
use super::locate::Located;
use super::score::HeldOut;
use super::search;

#[derive(Debug, Clone, Serialize)]
pub struct ParameterValue {
    pub name: String,
    pub value: f64,
    /// Least-squares standard deviation (null for searched parameters).
    pub std: Option<f64>,
}

pub(crate) fn parameter_values(list: Vec<(String, f64, f64)>) -> Vec<ParameterValue> {
    list.into_iter()
        .map(|(name, value, std)| ParameterValue {
            name,
            value,
            std: std.is_finite().then_some(std),
        })
        .collect()
}

/// One candidate's result.
#[derive(Debug, Clone, Serialize)]
pub struct RankedEffect {
    pub effect: Effect,
    /// The family member found and its fitted shape, for a family (sensor_lowpass: "channel
    /// mass_acceleration, 2nd order, 6.1 Hz, damping 0.70, delay 2.0 ms").
    pub member: Option<String>,
    /// Set when the effect's fit alone was not physical or could not be simulated and it is
    /// ranked as the best pair's second member: its figures are then the pair's, fitted with
    /// this (the top) effect ([`super::pair_partners::joint_only_entry`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fitted_with: Option<Effect>,
    /// Held-out NMSE with the effect added [%].
    pub gap_after_percent: f64,
    /// `gap_before - gap_after` [%-points].
    pub shrink_percent: f64,
    /// Penalised score (lower is better) [%].
    pub score_percent: f64,
    /// Leave-one-step-out cross-validated element-force error on the sine steps [%].
    pub phasor_cv_percent: Option<f64>,
    /// Output-error misfit on the sine steps (RMS in noise std) when the candidate was refitted
    /// by output error ([`super::output_error`]); its held-out figures are then the refit's.
    pub output_error_misfit: Option<f64>,
    pub extra_parameters: usize,
    pub added_parameters: Vec<ParameterValue>,
    /// The baseline's coefficients refitted beside the effect (with `added_parameters`, the
    /// whole model with the effect); empty where the figures are a pair's.
    pub refitted_baseline: Vec<ParameterValue>,
    pub significant: bool,
    pub added: String,
    pub signature: String,
}

#[derive(Debug, Clone, Serialize)]
pub struct PairResult {
    pub effects: [Effect; 2],
    pub gap_after_percent: f64,
    pub score_percent: f64,
    /// Leave-one-step-out cross-validated element-force error of the joint fit on the sine
    /// steps [%].
    pub phasor_cv_percent: Option<f64>,
    pub added_parameters: Vec<ParameterValue>,
    /// The baseline's coefficients refitted beside the pair.
    pub refitted_baseline: Vec<ParameterValue>,
    /// A neighbour of the first effect fitted with the pair as part of the first effect's form
    /// (two restoring-force forms together fit one wider form, e.g. a hardening spring with an
    /// x^5 share), when the second effect was searched beside it ([`super::pairs`]); the
    /// figures and added parameters are then those of the three fitted together.
    pub form_neighbour: Option<Effect>,
}

/// The diagnosis.
#[derive(Debug, Clone, Serialize)]
pub struct Diagnosis {
    /// The verdict on the held-out NMSE ([`super::findings::Evidence::HeldOutNmse`]); its floor
    /// is the held-out NMSE the measurement noise alone would leave (estimate) [%].
    #[serde(flatten)]
    pub findings: Findings,
    pub baseline_model: String,
    pub baseline_parameters: Vec<ParameterValue>,
    pub fit_steps: Vec<usize>,
    pub heldout_records: Vec<usize>,
    /// Held-out NMSE of the baseline per held-out record [%].
    pub gap_before_by_record_percent: Vec<f64>,
    pub ranked_effects: Vec<RankedEffect>,
    pub best_pair: Option<PairResult>,
    pub located: Located,
    pub baseline_phasor_cv_percent: Option<f64>,
    /// The baseline's output-error misfit on the sine steps (RMS in noise std), when a
    /// candidate was refitted by output error.
    pub baseline_output_error_misfit: Option<f64>,
    /// Exciter delay from the kinematic identity [s] and its standard deviation.
    pub kinematic_delay_s: Option<[f64; 2]>,
    /// What the user should know (candidates left out, ...).
    pub notes: Vec<String>,
}

/// The diagnosis with what the plots need.
#[derive(Debug, Clone)]
pub struct DiagnosisDetail {
    pub diagnosis: Diagnosis,
    pub search: search::PhasorSearch,
    pub baseline_heldout: Vec<HeldOut>,
    /// Held-out predictions with the top (or best) candidate.
    pub after_heldout: Vec<HeldOut>,
    /// The top (or best) candidate's fit.
    pub after_fit: Option<Fitted>,
    /// Where the residual lies with the top (or best) candidate added.
    pub after_located: Option<Located>,
}
