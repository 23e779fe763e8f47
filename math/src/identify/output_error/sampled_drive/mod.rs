//! Output error on records of any excitation (band-random, one-period or short multisines,
//! road profiles): records that have no settled steps to take phasors from, simulated under
//! their measured input sample by sample.
//!
//! The start is the time-domain fit of the same records (`td_range_equations`). On an element
//! test what refines it depends on what the bench controlled ([`records_drive`]):
//!
//! - Displacement drive (damper dyno, mount tester): the model's output is the force along the
//!   imposed motion, `m x'' + g(x, x')`, linear in theta, so the start is already the
//!   output-error estimate; it is returned as it is.
//! - Force drive (a single-DOF system on a shaker): the mass is simulated under the measured
//!   force (a spline through its samples) with exact stick-slip, and its displacement compared.
//!
//! On the base-excited rig the mass is simulated under the measured base displacement,
//! its bins above the differentiation band dropped (the spline's second derivative would
//! otherwise amplify its noise by w^2; a filter that loses nothing in the band biases nothing),
//! and its acceleration and relative displacement compared.
//!
//! Each record starts from its own initial state (displacement and velocity, fitted, so records
//! may start in motion); theta, the moving mass when it is identified, and the initial states
//! are fitted to every sample of the compared channels, each weighted by its noise (estimated
//! from its spectrum above the record's band). The standard deviations come from the residuals
//! as they are (a sandwich covariance over their correlation length), since the noise on the
//! measured input makes them coloured.

mod channel_effect;
mod drive_channel;

/// Names of the element parameters a Bouc-Wen state adds, after the terms' and the moving
/// mass: its force coefficient, its yield and its share r (`signal::bouc_wen::SHARE_NAME`).
pub const HYSTERESIS_PARAMETERS: [&str; 3] =
    ["alpha", "yield_m", crate::signal::bouc_wen::SHARE_NAME];
mod report;

pub use channel_effect::RigChannelEffect;
pub use drive_channel::records_drive;

use std::ops::Range;

use nalgebra::DMatrix;

use super::element::{ModelElement, check_model};
use super::lm::{self, Limits, Partial, Problem};
use super::sandwich::sandwich_covariance;
use crate::identify::{Identification, IdentifyError};
use crate::measured_state::{
    CUTOFF_MULTIPLE, MeasuredState, noise_std, rms_about_mean as rms, top_frequency_hz,
    unmeasured_noise,
};
use crate::model::Model;
use crate::record::{Channel, Record};
use crate::signal::bouc_wen::HysteresisLaw;
use crate::signal::differentiate::band_limited_derivative;
use crate::sim::{
    ForcedInitial, ReplayOptions, RigInitial, SolverOptions, simulate_on_sampled_base,
    simulate_on_sampled_force,
};

/// The fit starts from the time-domain estimate, which noise in the differentiated
/// displacement can put tens of percent off: more and longer steps than a refinement of
/// fd-multi's estimate takes.
const FROM_TIME_DOMAIN: Limits = Limits {
    iterations: 40,
    max_step: 0.5,
    relative_tolerance: 1e-10,
};

/// Fraction of the highest excitation period over which a record's first samples are fitted
/// by a parabola for its initial displacement and velocity.
const START_WINDOW_PERIODS: f64 = 0.125;

/// Residual of a trial whose simulation fails (it diverges, or a trial mass is not positive):
/// large, so that the fit rejects the trial.
const FAILED_TRIAL_RESIDUAL: f64 = 1e6;

fn step_error(step: usize, problem: impl Into<String>) -> IdentifyError {
    IdentifyError::Step {
        step,
        problem: problem.into(),
    }
}

/// The displacement and velocity a record starts with: a parabola fitted to its first samples
/// (an eighth of the highest excitation period, at least five samples).
fn starting_state(x: &[f64], sample_rate_hz: f64, top_frequency_hz: f64) -> [f64; 2] {
    let k = ((START_WINDOW_PERIODS * sample_rate_hz / top_frequency_hz).round() as usize)
        .clamp(5, x.len());
    let a = DMatrix::from_fn(k, 3, |i, j| (i as f64 / sample_rate_hz).powi(j as i32));
    let b = nalgebra::DVector::from_column_slice(&x[..k]);
    match a.svd(true, true).solve(&b, 1e-12) {
        Ok(c) => [c[0], c[1]],
        Err(_) => [x[0], 0.0],
    }
}

/// What drives the records and what the fit compares.
#[derive(Debug, Clone, Copy)]
enum SampledDrive {
    /// A force-driven element test: the mass (known, or None: fitted) under the measured
    /// force; its displacement compared. Initial state: displacement and velocity.
    Force { moving_mass_kg: Option<f64> },
    /// The base-excited rig: the mass under the measured base displacement (band-limited); its acceleration
    /// and the relative displacement compared. Initial state: the relative displacement and
    /// the mass velocity.
    Base { mass_kg: f64 },
}

/// The output-error problem of records driven by a sampled input. Parameters: the model's,
/// the moving mass when it is identified, a Bouc-Wen state's force coefficient and yield when
/// the model has one, then each record's initial state (displacement, velocity, and the
/// Bouc-Wen state z when there is one).
pub struct RecordsOutputError<'a> {
    model: Model,
    drive: SampledDrive,
    records: Vec<&'a Record>,
    /// Each record's input: the measured force, or the low-passed base displacement.
    inputs: Vec<Vec<f64>>,
    /// Each rig record's base velocity, band-limited as its input (empty for a force drive).
    input_rates: Vec<Vec<f64>>,
    /// The highest top excitation frequency of a rig's records [Hz] (0 for a force drive: only
    /// a rig's channel effect uses it).
    top_frequency_hz: f64,
    /// A transformation of the rig's channels fitted beside the element
    /// ([`Self::with_channel_effect`]).
    channel_effect: Option<RigChannelEffect>,
    /// Each record's compared channels with their noise std.
    compared: Vec<Vec<(Channel, f64)>>,
    /// Residual rows of each record.
    record_rows: Vec<Range<usize>>,
    /// Residual rows of each record's channels (contiguous runs of one channel).
    blocks: Vec<Range<usize>>,
    /// Scale of each record's initial-state numbers (the RMS of those states; the yield for
    /// z).
    state_scale: Vec<[f64; 3]>,
    start_states: Vec<[f64; 3]>,
    /// The Bouc-Wen law's shape (n, r) held and its yield's start, when the model has a
    /// hysteresis state beside its terms ([`Self::with_hysteresis`]).
    hysteresis: Option<HysteresisLaw>,
    /// Compared channels whose noise no record could measure (no band above
    /// [`CUTOFF_MULTIPLE`] times the excitation's top frequency below the Nyquist frequency):
    /// their weight is the floor of [`noise_std`], and the misfit says nothing of the noise.
    noise_unmeasured: Vec<Channel>,
    solver: SolverOptions,
}

impl<'a> RecordsOutputError<'a> {
    /// The problem of a force-driven element test's `records` (each with displacement and
    /// force), the moving mass known or (None) fitted.
    pub fn forced(
        model: &Model,
        moving_mass_kg: Option<f64>,
        records: &[&'a Record],
    ) -> Result<Self, IdentifyError> {
        let mut parts = Vec::new();
        let mut noise_bands = Vec::new();
        for r in records {
            let state = MeasuredState::of(r).map_err(|e| step_error(r.step, e.to_string()))?;
            let x = &state.displacement_m;
            let fs = r.sample_rate_hz;
            let cutoff = CUTOFF_MULTIPLE * state.top_frequency_hz;
            parts.push((
                state.force_n.clone(),
                vec![(Channel::RelativeDisplacementM, noise_std(x, fs, cutoff))],
                [
                    rms(x).max(f64::MIN_POSITIVE),
                    rms(&state.velocity_mps).max(f64::MIN_POSITIVE),
                ],
                starting_state(x, fs, state.top_frequency_hz),
            ));
            noise_bands.push((Channel::RelativeDisplacementM, x.len(), fs, cutoff));
        }
        let mut problem = Self::new(
            model,
            SampledDrive::Force { moving_mass_kg },
            records,
            parts,
        )?;
        problem.noise_unmeasured = unmeasured_noise(&noise_bands);
        Ok(problem)
    }

    /// The problem of a base-excited rig's `records` (base and relative displacement and mass
    /// acceleration) with the mass `mass_kg`.
    pub fn rig(model: &Model, mass_kg: f64, records: &[&'a Record]) -> Result<Self, IdentifyError> {
        let mut parts = Vec::new();
        let mut noise_bands = Vec::new();
        let (mut input_rates, mut highest_top_hz) = (Vec::new(), 0f64);
        for r in records {
            let channel = |c: Channel| {
                r.channel(c).ok_or_else(|| {
                    step_error(
                        r.step,
                        format!("channel {} is missing (output error compares it)", c.name()),
                    )
                })
            };
            let base = channel(Channel::BaseDisplacementM)?;
            let rel = channel(Channel::RelativeDisplacementM)?;
            let acc = channel(Channel::MassAccelerationMps2)?;
            let fs = r.sample_rate_hz;
            let top =
                top_frequency_hz(r, &[base, rel]).map_err(|e| step_error(r.step, e.to_string()))?;
            let cutoff = CUTOFF_MULTIPLE * top;
            let mass_x: Vec<f64> = base.iter().zip(rel).map(|(b, x)| b + x).collect();
            let [_, mass_v0] = starting_state(&mass_x, fs, top);
            let [rel0, _] = starting_state(rel, fs, top);
            parts.push((
                band_limited_derivative(base, fs, cutoff, 0),
                vec![
                    (Channel::MassAccelerationMps2, noise_std(acc, fs, cutoff)),
                    (Channel::RelativeDisplacementM, noise_std(rel, fs, cutoff)),
                ],
                [
                    rms(rel).max(f64::MIN_POSITIVE),
                    rms(&band_limited_derivative(&mass_x, fs, cutoff, 1)).max(f64::MIN_POSITIVE),
                ],
                [rel0, mass_v0],
            ));
            noise_bands.push((Channel::MassAccelerationMps2, acc.len(), fs, cutoff));
            noise_bands.push((Channel::RelativeDisplacementM, rel.len(), fs, cutoff));
            input_rates.push(band_limited_derivative(base, fs, cutoff, 1));
            highest_top_hz = highest_top_hz.max(top);
        }
        let mut problem = Self::new(model, SampledDrive::Base { mass_kg }, records, parts)?;
        problem.noise_unmeasured = unmeasured_noise(&noise_bands);
        problem.input_rates = input_rates;
        problem.top_frequency_hz = highest_top_hz;
        Ok(problem)
    }

    #[allow(
        clippy::type_complexity,
        reason = "the per-record parts, assembled once"
    )]
    fn new(
        model: &Model,
        drive: SampledDrive,
        records: &[&'a Record],
        parts: Vec<(Vec<f64>, Vec<(Channel, f64)>, [f64; 2], [f64; 2])>,
    ) -> Result<Self, IdentifyError> {
        check_model(model)?;
        let (mut inputs, mut compared, mut state_scale, mut start_states) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let (mut record_rows, mut blocks) = (Vec::new(), Vec::new());
        let mut rows = 0;
        for (r, (input, channels, scale, start)) in records.iter().zip(parts) {
            let first = rows;
            for _ in &channels {
                blocks.push(rows..rows + r.len());
                rows += r.len();
            }
            record_rows.push(first..rows);
            inputs.push(input);
            compared.push(channels);
            state_scale.push([scale[0], scale[1], 1.0]);
            start_states.push([start[0], start[1], 0.0]);
        }
        Ok(RecordsOutputError {
            model: model.clone(),
            drive,
            records: records.to_vec(),
            inputs,
            input_rates: Vec::new(),
            top_frequency_hz: 0.0,
            channel_effect: None,
            compared,
            record_rows,
            blocks,
            state_scale,
            start_states,
            hysteresis: None,
            noise_unmeasured: Vec::new(),
            solver: SolverOptions::default(),
        })
    }

    /// The problem with a Bouc-Wen state beside the model's terms, its law of `law`'s exponent
    /// n: three more element parameters ([`HYSTERESIS_PARAMETERS`]: the force coefficient alpha
    /// [N/m], the yield [m] and the share r, from `law`'s) and each record's initial z (from 0:
    /// from rest, or a start fitted with the state integrated from rest). The exponent n stays
    /// the one the search chose from its grid.
    ///
    /// Each initial z is the yield times tanh(u), u the fitted number: the law keeps z within
    /// the yield, and at its edge the response bends (saturation). u has a prior, zero with a
    /// std of 4 (a residual row per record after the samples): where a record's motion wipes
    /// its start out within a few yields of travel the samples say nothing of it, a flat
    /// direction whose Gauss-Newton steps would stall the fit.
    pub fn with_hysteresis(self, law: HysteresisLaw) -> Self {
        let state_scale = self.state_scale.iter().map(|s| [s[0], s[1], 1.0]).collect();
        RecordsOutputError {
            hysteresis: Some(law),
            state_scale,
            ..self
        }
    }

    /// Whether the moving mass is a parameter (a force drive with the mass not known).
    fn fitted_mass(&self) -> bool {
        matches!(
            self.drive,
            SampledDrive::Force {
                moving_mass_kg: None
            }
        )
    }

    /// Residual rows of the compared samples (a hysteresis state's priors follow them).
    fn data_rows(&self) -> usize {
        self.blocks.last().map_or(0, |b| b.end)
    }

    fn p_element(&self) -> usize {
        self.model.terms.len()
            + usize::from(self.fitted_mass())
            + HYSTERESIS_PARAMETERS.len() * usize::from(self.hysteresis.is_some())
            + usize::from(self.channel_effect.is_some())
    }

    /// Index of the first hysteresis parameter (alpha; the yield and r follow).
    fn hysteresis_index(&self) -> usize {
        self.model.terms.len() + usize::from(self.fitted_mass())
    }

    /// Initial-state numbers of each record: displacement, velocity, and z with hysteresis.
    fn state_len(&self) -> usize {
        2 + usize::from(self.hysteresis.is_some())
    }

    /// Initial-state parameter index of record `k` (its other numbers follow).
    fn state_index(&self, k: usize) -> usize {
        self.p_element() + self.state_len() * k
    }

    /// The element the records are simulated with at element parameters `element`; None when
    /// they hold no element (a yield that is not positive).
    fn element(&self, element: &[f64]) -> Option<ModelElement> {
        let p = self.model.terms.len();
        let el = ModelElement::new(&self.model, &element[..p]);
        match self.hysteresis {
            None => Some(el),
            Some(law) => {
                let at = self.hysteresis_index();
                let (alpha, yield_m, r) = (element[at], element[at + 1], element[at + 2]);
                (yield_m > 0.0)
                    .then(|| el.with_hysteresis(alpha, HysteresisLaw { yield_m, r, ..law }))
            }
        }
    }

    /// The compared channels of record `k` simulated with element parameters `element`
    /// (theta, then the mass when fitted) from `initial`, in the order of its compared
    /// channels.
    pub fn simulate(
        &self,
        k: usize,
        element: &[f64],
        initial: &[f64],
    ) -> Result<Vec<Vec<f64>>, IdentifyError> {
        let r = self.records[k];
        let p = self.model.terms.len();
        let el = self
            .element(element)
            .ok_or_else(|| step_error(r.step, "output-error simulation: a yield not positive"))?;
        let fs = r.sample_rate_hz;
        let failed =
            |e: crate::sim::SimError| step_error(r.step, format!("output-error simulation: {e}"));
        // A record's initial z is yield tanh(u): the law keeps z within the yield, and at its
        // edge the response bends (saturation), which the bound keeps the fit off.
        let z0 = match (self.hysteresis, initial.get(2)) {
            (Some(_), Some(u)) => element[self.hysteresis_index() + 1] * u.tanh(),
            _ => 0.0,
        };
        let out = match self.drive {
            SampledDrive::Force { moving_mass_kg } => {
                let mass = moving_mass_kg.unwrap_or_else(|| element[p]);
                let initial = ForcedInitial {
                    displacement_m: initial[0],
                    velocity_mps: initial[1],
                    first_internal_state: z0,
                };
                let resp = simulate_on_sampled_force(
                    &el,
                    mass,
                    &self.inputs[k],
                    fs,
                    initial,
                    &self.solver,
                )
                .map_err(failed)?;
                vec![resp.displacement_m]
            }
            SampledDrive::Base { mass_kg } => {
                let value = self
                    .channel_effect
                    .map(|_| element[self.channel_effect_index()]);
                let input = self.effective_input(k, value)?;
                let options = ReplayOptions {
                    initial: RigInitial {
                        relative_displacement_m: initial[0],
                        mass_velocity_mps: initial[1],
                        first_internal_state: z0,
                    },
                    solver: self.solver,
                    sensor_lowpass_hz: self.sensor_lowpass_hz(value),
                    ..ReplayOptions::default()
                };
                let resp =
                    simulate_on_sampled_base(&el, mass_kg, &input, fs, &options).map_err(failed)?;
                vec![resp.mass_acceleration_mps2, resp.relative_displacement_m]
            }
        };
        if out.iter().flatten().all(|v| v.is_finite()) {
            Ok(out)
        } else {
            Err(step_error(r.step, "output-error simulation diverges"))
        }
    }

    /// Whether every record simulates at parameters `p` (all of this problem's).
    fn simulates(&self, p: &[f64]) -> Result<(), IdentifyError> {
        let (np, ns) = (self.p_element(), self.state_len());
        for k in 0..self.records.len() {
            let j = self.state_index(k);
            self.simulate(k, &p[..np], &p[j..j + ns])?;
        }
        Ok(())
    }

    /// Fits theta (and the mass when identified) and every record's initial state from
    /// `start` (the time-domain identification of the same records, whose parameters are the
    /// model's and the setup's in this problem's order).
    pub fn fit(&self, start: &Identification) -> Result<Identification, IdentifyError> {
        let mut p0 = start.theta();
        if p0.len() != self.p_element() {
            return Err(step_error(
                0,
                "the start has not the parameters of this output-error problem",
            ));
        }
        for s in &self.start_states {
            p0.extend(&s[..self.state_len()]);
        }
        self.simulates(&p0).map_err(|e| {
            step_error(
                self.records[0].step,
                format!("the time-domain start cannot be simulated under the measured input: {e}"),
            )
        })?;
        // Initial states first, theta held: a start far from the record's state would
        // otherwise pull theta along. A hysteresis state's initial z is held at zero until the
        // records' other states and the element are fitted: far from the solution its
        // Gauss-Newton steps run to tens of yields (it acts as a free force offset at each
        // record's start), and the step limit that stops them would stall every other
        // parameter. The share r is held until then too (freed with the element from a start
        // 15-25 % off, it ran to 34 and k stalled 11 % off), then fitted with the element and
        // the initial states held (with them free a flat initial z stopped the fit before r
        // moved), then everything together.
        let np = self.p_element();
        let ns = self.state_len();
        let is_z0 = |j: usize| j >= np && (j - np) % ns == 2;
        let held = |j: usize| is_z0(j) || j == self.hysteresis_index() + 2;
        let mut p = p0;
        let free_sets: Vec<Vec<usize>> = if self.hysteresis.is_some() {
            vec![
                (np..p.len()).filter(|&j| !is_z0(j)).collect(),
                (0..p.len()).filter(|&j| !held(j)).collect(),
                (np..p.len()).collect(),
                (0..p.len()).filter(|&j| !is_z0(j)).collect(),
            ]
        } else {
            vec![(np..p.len()).collect()]
        };
        for free in free_sets {
            let stage = Partial {
                inner: self,
                full: p.clone(),
                free,
            };
            let start: Vec<f64> = stage.free.iter().map(|&j| p[j]).collect();
            let fit = lm::levenberg_marquardt_within(&stage, start, FROM_TIME_DOMAIN)?;
            p = stage.expand(&fit.p);
        }
        let fit = lm::levenberg_marquardt_within(self, p, FROM_TIME_DOMAIN)?;
        let cov = sandwich_covariance(self, &fit, &self.blocks)?;
        Ok(self.identification(start, &fit, &cov))
    }

    /// The displacement of a force-driven `record` (not among the fitted ones) predicted by
    /// simulation with the element parameters `element` (theta, then the mass when fitted,
    /// then with `hysteresis` (the law's exponent) its alpha, yield and r), from the initial state
    /// that fits it best with those parameters held.
    pub fn predict_forced(
        model: &Model,
        moving_mass_kg: Option<f64>,
        hysteresis: Option<HysteresisLaw>,
        element: &[f64],
        record: &Record,
    ) -> Result<Vec<f64>, IdentifyError> {
        let mut problem = RecordsOutputError::forced(model, moving_mass_kg, &[record])?;
        if let Some(law) = hysteresis {
            problem = problem.with_hysteresis(law);
        }
        let (np, ns) = (problem.p_element(), problem.state_len());
        // With the mass known, values after theta (an identified mass already folded into
        // `moving_mass_kg`) are not parameters of this simulation.
        let element = element.get(..np).ok_or_else(|| {
            step_error(
                record.step,
                format!("{} parameter values for {np} parameters", element.len()),
            )
        })?;
        let mut full = element.to_vec();
        full.extend(&problem.start_states[0][..ns]);
        let states = Partial {
            inner: &problem,
            full: full.clone(),
            free: (np..np + ns).collect(),
        };
        let fit = lm::levenberg_marquardt_within(&states, full[np..].to_vec(), FROM_TIME_DOMAIN)?;
        let mut out = problem.simulate(0, element, &fit.p)?;
        Ok(out.swap_remove(0))
    }
}

impl Problem for RecordsOutputError<'_> {
    fn residual(&self, p: &[f64]) -> Result<Vec<f64>, IdentifyError> {
        let (np, ns) = (self.p_element(), self.state_len());
        let n = self.data_rows();
        let priors = if self.hysteresis.is_some() {
            self.records.len()
        } else {
            0
        };
        let mut out = Vec::with_capacity(n + priors);
        for (k, r) in self.records.iter().enumerate() {
            let j = self.state_index(k);
            let Ok(simulated) = self.simulate(k, &p[..np], &p[j..j + ns]) else {
                return Ok(vec![FAILED_TRIAL_RESIDUAL; n + priors]);
            };
            let transient = self.filter_transient_samples(k);
            for ((c, sigma), sim) in self.compared[k].iter().zip(&simulated) {
                let measured = r.channel(*c).unwrap_or(&[]);
                out.extend(measured.iter().zip(sim).enumerate().map(|(i, (m, s))| {
                    if i < transient { 0.0 } else { (m - s) / sigma }
                }));
            }
        }
        if priors > 0 {
            // Each record's initial z, one yield std about zero (see `with_hysteresis`).
            out.extend((0..self.records.len()).map(|k| p[self.state_index(k) + 2] / 4.0));
        }
        Ok(out)
    }

    /// Each record's initial state moves its own rows only, so one simulation gives the finite
    /// differences of every record's first number; the same for the second (and third).
    fn column_groups(&self, np: usize) -> Vec<Vec<usize>> {
        let (pe, ns) = (self.p_element(), self.state_len());
        let mut groups: Vec<Vec<usize>> = (0..pe.min(np)).map(|j| vec![j]).collect();
        for first in 0..ns {
            groups.push((pe + first..np).step_by(ns).collect());
        }
        groups.retain(|g| !g.is_empty());
        groups
    }

    fn rows(&self, j: usize, n: usize) -> Range<usize> {
        let pe = self.p_element();
        if j < pe {
            0..n
        } else {
            self.record_rows[(j - pe) / self.state_len()].clone()
        }
    }

    fn scale(&self, p: &[f64]) -> Vec<f64> {
        let pe = self.p_element();
        p.iter()
            .enumerate()
            .map(|(j, v)| {
                if self.channel_effect.is_some() && j == self.channel_effect_index() {
                    // A time: the excitation's shortest period over 2 pi where it is smaller.
                    v.abs().max(self.shortest_time_s())
                } else if j < pe {
                    if v.abs() > 0.0 { v.abs() } else { 1.0 }
                } else {
                    let ns = self.state_len();
                    self.state_scale[(j - pe) / ns][(j - pe) % ns]
                }
            })
            .collect()
    }
}
