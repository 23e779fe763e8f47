//! Truth simulators: the base-excited suspension rig and the paper's 3-DOF example, with
//! exact stick-slip (no regularisation), planted rig effects and measurement noise.
//!
//! Entry point: [`RunSpec`] (one description of a run, with the paper's runs as named
//! constructors) and [`RunSpec::simulate`]. Every run is reproducible from its seed (multisine phases and noise come
//! from seeded ChaCha streams).

pub mod bench_runs;
pub mod element;
mod exact_step;
pub mod excitation;
mod hybrid;
mod input_window;
mod linear_step;
pub mod noise;
pub mod periodic_multisine;
pub mod rig;
mod rig_records;
pub mod run;
mod spline;
mod stream;
pub mod three_dof;
pub mod truth;

pub use element::{
    ELEMENT_CHANNELS, ElementDrive, ForcedInitial, ForcedResponse, simulate_element,
    simulate_on_sampled_force,
};
pub use excitation::{Derivs, Multisine, Program, StepSpec};
pub use hybrid::SolverOptions;
pub use periodic_multisine::{MultisineDesign, MultisinePlan};
pub use rig::{
    ReplayOptions, RigEffects, RigInitial, RigResponse, ZeroPhaseLowpass, simulate_on_sampled_base,
    simulate_rig,
};
pub use run::{RunSpec, RunSystem, ThreeDofCase};
pub use three_dof::{ThreeDofParams, simulate_three_dof};
pub use truth::{AsymmetricDamping, BoucWen, FreePlay, TruthElement};

use crate::record::Record;

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimError {
    #[error("invalid simulation spec: {0}")]
    InvalidSpec(String),
    #[error("stick-slip chattering at t = {time_s} s (too many events in one sub-step)")]
    Chattering { time_s: f64 },
    #[error("state became non-finite at t = {time_s} s")]
    NonFinite { time_s: f64 },
}

/// Finite and strictly positive.
pub(crate) fn is_positive(x: f64) -> bool {
    x.is_finite() && x > 0.0
}

/// State of the friction element at one sample (for tests and diagnostics).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SampleTrace {
    /// Relative velocity across the element [m/s] (exactly 0.0 while stuck).
    pub relative_velocity_mps: f64,
    pub stuck: bool,
    /// Friction force [N]: the needed one while stuck, the slip law while slipping.
    pub friction_force_n: f64,
}

/// Per-record diagnostics.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RecordTrace {
    /// One entry per sample of the record.
    pub samples: Vec<SampleTrace>,
    /// Time stuck inside each sample interval [s] (exact, events located to ~1e-12 s).
    pub stick_time_s: Vec<f64>,
    /// Number of stick/slip events in the record.
    pub events: usize,
}

impl RecordTrace {
    /// Fraction of time stuck over the sample intervals `from..` of the record.
    pub fn stick_fraction_from(&self, from: usize, sample_rate_hz: f64) -> f64 {
        let n = self.stick_time_s.len().saturating_sub(from);
        if n == 0 {
            return 0.0;
        }
        self.stick_time_s[from..].iter().sum::<f64>() * sample_rate_hz / n as f64
    }
}

/// Records of a simulated run plus diagnostics.
#[derive(Debug, Clone, PartialEq)]
pub struct SimOutput {
    pub records: Vec<Record>,
    pub traces: Vec<RecordTrace>,
}
