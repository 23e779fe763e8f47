//! One description of a simulated run: [`RunSpec`] says everything a run is (the system, the
//! truth element with its planted effects, the excitation steps, the sampling, the noise and
//! the seed), [`RunSpec::simulate`] turns it into records, and [`RunSpec::constants`] gives the
//! rig constants a simulated sensor publishes with them.
//!
//! The paper's runs are named constructors: [`RunSpec::paper_rig`] (the base-excited rig's
//! stepped sine and its two band-random validation records, one run),
//! [`RunSpec::paper_rig_sine`], [`RunSpec::paper_rig_random`] and [`RunSpec::three_dof`]. The
//! places that simulate (the sensor node, `forcemap simulate`, the diagnosis demo and its
//! evaluation, the reproduction) only parse their own parameters into a `RunSpec`.

use serde::{Deserialize, Serialize};

use super::excitation::{self, StepSpec};
use super::periodic_multisine::MultisinePlan;
use super::{
    ElementDrive, Program, RigEffects, RigInitial, SimError, SimOutput, SolverOptions,
    ThreeDofParams, TruthElement, noise, rig, simulate_element, simulate_rig, simulate_three_dof,
};
use crate::element::Element;
use crate::recipe::SetupKind;
use crate::record::{Channel, Record};

/// Noise stream number derived from the run seed.
pub(crate) const NOISE_STREAM: u64 = 1;

/// The paper's 3-DOF cases (the force amplitudes of the five steps at 5 Hz).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ThreeDofCase {
    /// CASE I: 5, 10, 15, 20, 25 N.
    I,
    /// CASE II: 50, 60, 70, 80, 90 N.
    Ii,
}

impl ThreeDofCase {
    /// The force amplitudes of the case's steps [N].
    pub fn amplitudes_n(self) -> &'static [f64] {
        match self {
            ThreeDofCase::I => &excitation::THREE_DOF_CASE_I_N,
            ThreeDofCase::Ii => &excitation::THREE_DOF_CASE_II_N,
        }
    }
}

/// The simulated system: what is excited, and how.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "system", rename_all = "snake_case")]
pub enum RunSystem {
    /// The base-excited suspension rig: the steps displace the base (amplitudes in m).
    Rig {
        /// The mass the analysis knows [kg]; the true one is `nominal * effects.mass_factor`.
        nominal_mass_kg: f64,
        /// Planted rig-level effects (exciter delay, sensor low-pass, mass error).
        #[serde(default)]
        effects: RigEffects,
        #[serde(default)]
        initial: RigInitial,
    },
    /// The paper's 3-DOF example: the steps are forces on m2 (amplitudes in N).
    ThreeDof {
        #[serde(default)]
        params: ThreeDofParams,
    },
    /// An element test: the steps are displacements (m) or forces (N) as `drive` says, with
    /// a moving mass between load cell and element.
    Element {
        drive: ElementDrive,
        moving_mass_kg: f64,
    },
}

impl RunSystem {
    /// What the system is, for messages ("the rig", ...).
    pub fn description(&self) -> &'static str {
        match self {
            RunSystem::Rig { .. } => "the rig",
            RunSystem::ThreeDof { .. } => "the 3-DOF example",
            RunSystem::Element { .. } => "an element test",
        }
    }
}

/// Everything a simulated run is. Simulating the same spec gives the same records, bit for
/// bit (multisine phases and noise come from seeded streams).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunSpec {
    #[serde(flatten)]
    pub system: RunSystem,
    /// The truth element, with its planted element effects.
    pub element: TruthElement,
    /// The excitation program, one record per step.
    pub steps: Vec<StepSpec>,
    pub sample_rate_hz: f64,
    pub samples_per_record: usize,
    /// Measurement SNR [dB] (None: noise-free).
    pub snr_db: Option<f64>,
    pub seed: u64,
    #[serde(default)]
    pub solver: SolverOptions,
}

impl RunSpec {
    /// A rig run of `steps` with the paper's rig (36 kg, 100 Hz, 1300 samples per record),
    /// the Coulomb truth element, no planted effects, noise-free, seed 0.
    pub fn rig(steps: Vec<StepSpec>) -> RunSpec {
        RunSpec {
            system: RunSystem::Rig {
                nominal_mass_kg: rig::PAPER_RIG_MASS_KG,
                effects: RigEffects::default(),
                initial: RigInitial::default(),
            },
            element: TruthElement::rig_coulomb(),
            steps,
            sample_rate_hz: excitation::PAPER_RIG_SAMPLE_RATE_HZ,
            samples_per_record: excitation::PAPER_RIG_SAMPLES_PER_RECORD,
            snr_db: None,
            seed: 0,
            solver: SolverOptions::default(),
        }
    }

    /// The paper's simulated rig run: the Coulomb rig, 10 stepped-sine steps 1.6-3.4 Hz at
    /// 6 mm, then the two band-random validation records (1.5-2.5 and 2.5-3.5 Hz, 4 mm RMS),
    /// 1300 samples per record at 100 Hz, noise at `snr_db`, from `seed`.
    pub fn paper_rig(snr_db: Option<f64>, seed: u64) -> RunSpec {
        let mut steps = excitation::paper_rig_sine_steps(excitation::PAPER_RIG_SINE_AMPLITUDE_M);
        steps.extend(excitation::paper_rig_random_steps());
        RunSpec {
            snr_db,
            seed,
            ..RunSpec::rig(steps)
        }
    }

    /// The paper's rig identification run alone: the 10 stepped-sine steps.
    pub fn paper_rig_sine(snr_db: Option<f64>, seed: u64) -> RunSpec {
        RunSpec {
            snr_db,
            seed,
            ..RunSpec::rig(excitation::paper_rig_sine_steps(
                excitation::PAPER_RIG_SINE_AMPLITUDE_M,
            ))
        }
    }

    /// One paper validation record of the rig alone: band random on `band_hz`, 4 mm RMS.
    pub fn paper_rig_random(band_hz: [f64; 2], snr_db: Option<f64>, seed: u64) -> RunSpec {
        RunSpec {
            snr_db,
            seed,
            ..RunSpec::rig(vec![excitation::paper_rig_random_step(
                band_hz,
                excitation::PAPER_RIG_RANDOM_RMS_M,
            )])
        }
    }

    /// The paper's 3-DOF example, `case`: five 5 Hz force steps of 8000 samples at 1 kHz.
    pub fn three_dof(case: ThreeDofCase, snr_db: Option<f64>, seed: u64) -> RunSpec {
        RunSpec {
            system: RunSystem::ThreeDof {
                params: ThreeDofParams::paper(),
            },
            element: TruthElement::three_dof_element(),
            steps: excitation::three_dof_steps(case.amplitudes_n()),
            sample_rate_hz: excitation::THREE_DOF_SAMPLE_RATE_HZ,
            samples_per_record: excitation::THREE_DOF_SAMPLES_PER_RECORD,
            snr_db,
            seed,
            solver: SolverOptions::default(),
        }
    }

    /// An element test of `element` behind a moving mass of `moving_mass_kg`, driven by
    /// `steps` (displacements or forces, as `drive` says), noise-free, seed 0.
    pub fn element_test(
        drive: ElementDrive,
        moving_mass_kg: f64,
        element: TruthElement,
        steps: Vec<StepSpec>,
        sample_rate_hz: f64,
        samples_per_record: usize,
    ) -> RunSpec {
        RunSpec {
            system: RunSystem::Element {
                drive,
                moving_mass_kg,
            },
            element,
            steps,
            sample_rate_hz,
            samples_per_record,
            snr_db: None,
            seed: 0,
            solver: SolverOptions::default(),
        }
    }

    /// A force-driven single-DOF system (`element` behind a moving mass of `mass_kg`) driven
    /// by `realisations` periodic multisines of `plan` (force in N), one record each, with
    /// phases (and random-odd lines) differing from record to record; noise-free, seed 0.
    pub fn force_driven_multisine(
        mass_kg: f64,
        element: TruthElement,
        plan: &MultisinePlan,
        realisations: usize,
        sample_rate_hz: f64,
    ) -> RunSpec {
        RunSpec::element_test(
            ElementDrive::Force,
            mass_kg,
            element,
            vec![plan.step(); realisations],
            sample_rate_hz,
            plan.samples_per_record(sample_rate_hz),
        )
    }

    /// The same run with `element` as the truth.
    pub fn with_element(self, element: TruthElement) -> RunSpec {
        RunSpec { element, ..self }
    }

    /// The same run with the planted rig-level `effects` (a rig run; ignored by the 3-DOF
    /// example, which has none).
    pub fn with_effects(mut self, effects: RigEffects) -> RunSpec {
        if let RunSystem::Rig { effects: e, .. } = &mut self.system {
            *e = effects;
        }
        self
    }

    /// The kind of setup the run's records are: the rig is base-excited, the 3-DOF example
    /// is driven at a point of its linear substructure.
    pub fn setup_kind(&self) -> SetupKind {
        match self.system {
            RunSystem::Rig { .. } => SetupKind::BaseExcited,
            RunSystem::ThreeDof { .. } => SetupKind::DrivePoint,
            RunSystem::Element { .. } => SetupKind::Element,
        }
    }

    /// The channel whose amplitude the excitation gives: the force of a force-driven element
    /// test, the setup kind's driven channel otherwise.
    pub fn driven_channel(&self) -> Channel {
        match self.system {
            // The program is the force on the moving mass (the element profile's driven channel
            // is the displacement of a dyno).
            RunSystem::Element {
                drive: ElementDrive::Force,
                ..
            } => Channel::ForceN,
            _ => self.setup_kind().driven_channel(),
        }
    }

    /// The mass the analysis knows [kg]: the rig's, an element test's moving mass (None
    /// for the 3-DOF example).
    pub fn mass_kg(&self) -> Option<f64> {
        match self.system {
            RunSystem::Rig {
                nominal_mass_kg, ..
            } => Some(nominal_mass_kg),
            RunSystem::Element { moving_mass_kg, .. } => Some(moving_mass_kg),
            RunSystem::ThreeDof { .. } => None,
        }
    }

    /// The rig constants a simulated sensor publishes with the run, in order: `mass_kg` (the
    /// rig), then the truth element's `truth.k`, `truth.c`, `truth.fd` (with friction) and
    /// `truth.s` (with a cubic stiffness), for summaries.
    pub fn constants(&self) -> Vec<(String, f64)> {
        let e = &self.element;
        let mut out = Vec::new();
        if let Some(m) = self.mass_kg() {
            out.push(("mass_kg".to_string(), m));
        }
        out.push(("truth.k".to_string(), e.stiffness_n_per_m));
        out.push(("truth.c".to_string(), e.damping_n_s_per_m));
        if let Some(f) = &e.friction {
            out.push(("truth.fd".to_string(), f.kinetic_n));
        }
        if e.cubic_stiffness_n_per_m3 != 0.0 {
            out.push(("truth.s".to_string(), e.cubic_stiffness_n_per_m3));
        }
        out
    }

    /// The excitation program of the run.
    pub fn program(&self) -> Program {
        Program::from_steps(
            &self.steps,
            self.sample_rate_hz,
            self.samples_per_record,
            self.seed,
        )
    }

    /// Simulates the run and adds its measurement noise; returns the records.
    pub fn simulate(&self) -> Result<Vec<Record>, SimError> {
        self.simulate_detailed().map(|o| o.records)
    }

    /// [`RunSpec::simulate`] with per-record diagnostics (traces are noise-free).
    pub fn simulate_detailed(&self) -> Result<SimOutput, SimError> {
        self.simulate_with_element(&self.element)
    }

    /// [`RunSpec::simulate_detailed`] with another truth `element` in place of `self.element`
    /// (one that is no [`TruthElement`], e.g. with internal states of its own).
    pub fn simulate_with_element(&self, element: &dyn Element) -> Result<SimOutput, SimError> {
        let what = self.system.description();
        if self.samples_per_record == 0 || self.steps.is_empty() {
            return Err(SimError::InvalidSpec(format!(
                "{what} needs steps and samples"
            )));
        }
        let mut out = match &self.system {
            RunSystem::Rig {
                nominal_mass_kg,
                effects,
                initial,
            } => simulate_rig(
                element,
                *nominal_mass_kg,
                &self.program(),
                effects,
                *initial,
                &self.solver,
            )?,
            RunSystem::ThreeDof { params } => {
                simulate_three_dof(params, element, &self.program(), &self.solver)?
            }
            RunSystem::Element {
                drive,
                moving_mass_kg,
            } => simulate_element(
                element,
                *moving_mass_kg,
                *drive,
                &self.program(),
                &self.solver,
            )?,
        };
        noise::add_noise(
            &mut out.records,
            self.snr_db,
            excitation::derive_seed(self.seed, NOISE_STREAM),
        );
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::excitation::{
        PAPER_RIG_RANDOM_BANDS_HZ, PAPER_RIG_RANDOM_RMS_M, paper_rig_random_step,
    };
    #[test]
    fn paper_rig_is_the_paper_run() {
        let spec = RunSpec::paper_rig(Some(40.0), 1);
        let mut steps = excitation::paper_rig_sine_steps(excitation::PAPER_RIG_SINE_AMPLITUDE_M);
        steps.extend(
            PAPER_RIG_RANDOM_BANDS_HZ.map(|b| paper_rig_random_step(b, PAPER_RIG_RANDOM_RMS_M)),
        );
        assert_eq!(spec.steps, steps);
        assert_eq!(spec.element, TruthElement::rig_coulomb());
        assert_eq!(spec.steps.len(), 12);
        assert_eq!(spec.samples_per_record, 1300);
        assert_eq!(spec.sample_rate_hz, 100.0);
        assert_eq!(spec.mass_kg(), Some(36.0));
        assert_eq!(spec.driven_channel(), Channel::BaseDisplacementM);
    }

    #[test]
    fn constants_are_the_mass_then_the_truth() {
        let c = RunSpec::paper_rig(None, 0).constants();
        let names: Vec<&str> = c.iter().map(|(k, _)| k.as_str()).collect();
        assert_eq!(names, ["mass_kg", "truth.k", "truth.c", "truth.fd"]);
        assert_eq!(c[0].1, 36.0);
        let e = TruthElement::rig_coulomb();
        assert_eq!(c[1].1, e.stiffness_n_per_m);
        let c = RunSpec::three_dof(ThreeDofCase::Ii, None, 0).constants();
        let names: Vec<&str> = c.iter().map(|(k, _)| k.as_str()).collect();
        assert_eq!(names, ["truth.k", "truth.c", "truth.fd", "truth.s"]);
    }

    #[test]
    fn effects_apply_to_the_rig_only() {
        let fx = RigEffects {
            exciter_delay_s: 0.01,
            ..RigEffects::default()
        };
        let rig = RunSpec::paper_rig(None, 0).with_effects(fx);
        assert!(matches!(rig.system, RunSystem::Rig { effects, .. } if effects == fx));
        let three = RunSpec::three_dof(ThreeDofCase::I, None, 0);
        assert_eq!(three.clone().with_effects(fx), three);
    }

    #[test]
    fn a_spec_round_trips_through_json() {
        for spec in [
            RunSpec::paper_rig(Some(40.0), 1),
            RunSpec::three_dof(ThreeDofCase::Ii, None, 0),
        ] {
            let text = serde_json::to_string(&spec).unwrap();
            let back: RunSpec = serde_json::from_str(&text).unwrap();
            assert_eq!(back, spec);
        }
    }

    #[test]
    fn an_empty_run_is_refused() {
        let spec = RunSpec::rig(Vec::new());
        assert!(matches!(spec.simulate(), Err(SimError::InvalidSpec(_))));
        let spec = RunSpec {
            samples_per_record: 0,
            ..RunSpec::three_dof(ThreeDofCase::I, None, 0)
        };
        assert!(matches!(spec.simulate(), Err(SimError::InvalidSpec(_))));
    }
}
