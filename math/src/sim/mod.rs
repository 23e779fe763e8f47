//! Truth simulators: the base-excited suspension rig and the paper's 3-DOF example, with
//! exact stick-slip (no regularisation), planted rig effects and measurement noise.
//!
//! Entry point: [`RunSpec`] (one description of a run, with the paper's runs as named
//! constructors) and [`RunSpec::simulate`]; [`SimSpec`] with [`simulate`] is the same run
//! split by system. Every run is reproducible from its seed (multisine phases and noise come
//! from seeded ChaCha streams).

pub mod bench_runs;
pub mod element;
pub mod excitation;
mod hybrid;
mod input_window;
mod linear_step;
pub mod noise;
pub mod periodic_multisine;
pub mod rig;
pub mod run;
mod spline;
pub mod three_dof;
pub mod truth;

use serde::{Deserialize, Serialize};

pub use element::{ELEMENT_CHANNELS, ElementDrive, simulate_element};
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

/// A run of the base-excited rig.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct RigRun {
    /// The mass the analysis knows [kg]; the true one is `nominal * effects.mass_factor`.
    pub nominal_mass_kg: f64,
    pub element: TruthElement,
    pub sample_rate_hz: f64,
    pub samples_per_record: usize,
    /// Base displacement steps (amplitudes and RMS in m).
    pub steps: Vec<StepSpec>,
    pub effects: RigEffects,
    pub initial: RigInitial,
    /// Measurement SNR [dB] (None: noise-free).
    pub snr_db: Option<f64>,
    pub seed: u64,
    pub solver: SolverOptions,
}

impl Default for RigRun {
    /// The paper's identification run: Coulomb rig, stepped sine 1.6-3.4 Hz at 6 mm.
    fn default() -> Self {
        RigRun {
            nominal_mass_kg: rig::PAPER_RIG_MASS_KG,
            element: TruthElement::rig_coulomb(),
            sample_rate_hz: excitation::PAPER_RIG_SAMPLE_RATE_HZ,
            samples_per_record: excitation::PAPER_RIG_SAMPLES_PER_RECORD,
            steps: excitation::paper_rig_sine_steps(excitation::PAPER_RIG_SINE_AMPLITUDE_M),
            effects: RigEffects::default(),
            initial: RigInitial::default(),
            snr_db: None,
            seed: 0,
            solver: SolverOptions::default(),
        }
    }
}

impl RigRun {
    /// The paper's stepped-sine identification run with `element`.
    pub fn paper_sine(element: TruthElement) -> RigRun {
        RigRun {
            element,
            ..RigRun::default()
        }
    }

    /// A paper validation run: one band-random record (1300 samples) on `band_hz`, 4 mm RMS.
    pub fn paper_random(element: TruthElement, band_hz: [f64; 2]) -> RigRun {
        RigRun {
            element,
            steps: vec![excitation::paper_rig_random_step(
                band_hz,
                excitation::PAPER_RIG_RANDOM_RMS_M,
            )],
            ..RigRun::default()
        }
    }

    pub fn program(&self) -> Program {
        Program::from_steps(
            &self.steps,
            self.sample_rate_hz,
            self.samples_per_record,
            self.seed,
        )
    }
}

/// A run of the 3-DOF example.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ThreeDofRun {
    pub params: ThreeDofParams,
    pub element: TruthElement,
    pub sample_rate_hz: f64,
    pub samples_per_record: usize,
    /// Force steps on m2 (amplitudes and RMS in N).
    pub steps: Vec<StepSpec>,
    pub snr_db: Option<f64>,
    pub seed: u64,
    pub solver: SolverOptions,
}

impl Default for ThreeDofRun {
    /// CASE II of the paper.
    fn default() -> Self {
        ThreeDofRun::case_ii()
    }
}

impl ThreeDofRun {
    fn with_amplitudes(a: &[f64]) -> ThreeDofRun {
        ThreeDofRun {
            params: ThreeDofParams::paper(),
            element: TruthElement::three_dof_element(),
            sample_rate_hz: excitation::THREE_DOF_SAMPLE_RATE_HZ,
            samples_per_record: excitation::THREE_DOF_SAMPLES_PER_RECORD,
            steps: excitation::three_dof_steps(a),
            snr_db: None,
            seed: 0,
            solver: SolverOptions::default(),
        }
    }

    /// CASE I: 5, 10, 15, 20, 25 N at 5 Hz.
    pub fn case_i() -> ThreeDofRun {
        ThreeDofRun::with_amplitudes(&excitation::THREE_DOF_CASE_I_N)
    }

    /// CASE II: 50, 60, 70, 80, 90 N at 5 Hz.
    pub fn case_ii() -> ThreeDofRun {
        ThreeDofRun::with_amplitudes(&excitation::THREE_DOF_CASE_II_N)
    }

    pub fn program(&self) -> Program {
        Program::from_steps(
            &self.steps,
            self.sample_rate_hz,
            self.samples_per_record,
            self.seed,
        )
    }
}

/// A serialisable description of a simulated run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "system", rename_all = "snake_case")]
pub enum SimSpec {
    Rig(RigRun),
    ThreeDof(ThreeDofRun),
}

/// Simulates a run and adds its measurement noise; returns the records.
pub fn simulate(spec: &SimSpec) -> Result<Vec<Record>, SimError> {
    simulate_detailed(spec).map(|o| o.records)
}

/// [`simulate`] with per-record diagnostics (traces are noise-free): the run as a
/// [`RunSpec`], simulated by [`RunSpec::simulate_detailed`].
pub fn simulate_detailed(spec: &SimSpec) -> Result<SimOutput, SimError> {
    RunSpec::from(spec.clone()).simulate_detailed()
}
