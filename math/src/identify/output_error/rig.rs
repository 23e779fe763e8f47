//! Output error for the base-excited rig: the model's element on the known mass, driven by the
//! base motion, fitted to the settled samples of the measured relative displacement and mass
//! acceleration (and, with a fitted base, the base displacement), each channel weighted by its
//! measured noise.
//!
//! How the simulation is driven ([`RigDrive`]):
//! - [`RigDrive::FittedSine`] (the method's choice): each sine step's base motion is a sine
//!   whose amplitude and phase are fitted with the element parameters, started from the base
//!   channel's first harmonic; the base samples are then measurements like the others. This is
//!   the maximum-likelihood fit for a stepped-sine run: the base noise enters through two
//!   numbers per step, not sample by sample.
//! - [`RigDrive::MeasuredSpline`]: the measured base samples through a cubic spline (after an
//!   optional zero-phase low-pass), as the band-random validation replays them. The base noise
//!   then drives the model (its second derivative is the forcing), so the fit is noisier and
//!   its reported std too small; kept for comparison and for base motions that are no sine.
//!
//! The sine records must follow one another (records 0, 1, 2, ... back to back); the run is
//! simulated from rest, its state carried from record to record, as the rig ran.

use std::ops::Range;
use std::sync::Arc;

use nalgebra::DMatrix;
use num_complex::Complex64;

use super::element::{ModelElement, check_model};
use super::lm::{Limits, Partial, Problem, levenberg_marquardt, levenberg_marquardt_within};
use super::{channel_noise, event_mask, identification, sine_records, unsupported};
use crate::basis::StribeckVelocity;
use crate::identify::{Identification, IdentifyError};
use crate::model::Model;
use crate::phasor::HarmonicAnalysis;
use crate::record::{Channel, Record};
use crate::signal::lowpass::zero_phase_lowpass;
use crate::sim::excitation::{CubicSpline, Piece, PiecewiseSignal, Program, SplineEnds};
use crate::sim::{RigEffects, RigInitial, SimOutput, SolverOptions, simulate_rig};

/// How the rig simulation of an output-error fit is driven (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RigDrive {
    /// A sine per step, amplitude and phase fitted.
    FittedSine,
    /// The measured base samples through a spline, after a zero-phase low-pass at
    /// `lowpass_hz` (None: the raw samples).
    MeasuredSpline { lowpass_hz: Option<f64> },
}

/// A fit of the model's parameters for comparing models on the same data
/// ([`RigOutputError::compare`]).
#[derive(Debug, Clone)]
pub struct RigMisfit {
    /// The model's parameters at the end of the fit.
    pub theta: Vec<f64>,
    /// RMS of the residual over the fitted samples, each channel in units of its measured noise
    /// (1 when the model misses the samples by the noise alone).
    pub misfit_rms: f64,
    /// Samples fitted.
    pub samples: usize,
    /// The Stribeck velocity fitted with the coefficients
    /// ([`RigOutputError::fitting_stribeck_velocity`]); None when it was held.
    pub stribeck_velocity_mps: Option<f64>,
}

/// A Stribeck velocity fitted with the model's coefficients: the model's term `term` is
/// exp(-|x'/vs|^exponent) with ln vs a parameter after the coefficients (the logarithm keeps vs
/// positive and makes its steps relative).
#[derive(Debug, Clone, Copy)]
struct FittedStribeckVelocity {
    term: usize,
    exponent: f64,
    start_ln_vs: f64,
}

/// Passes of [`RigOutputError::compare`] (each re-masks the samples next to the simulation's
/// stick/slip events) and the limits of each: a start from the phasor fit of a model whose
/// friction acts where that fit looks away may be off by a factor of three (a Stribeck excess of
/// 5 N fitted for 14 N), so the trust region is wider than a refinement's.
const COMPARE_PASSES: usize = 3;
const COMPARE_LIMITS: Limits = Limits {
    iterations: 6,
    max_step: 1.0,
    // Misfits are compared between models to a few parts in a thousand.
    relative_tolerance: 1e-4,
};

/// The channels fitted, in the order of each step's residual block.
const CHANNELS: [Channel; 3] = [
    Channel::BaseDisplacementM,
    Channel::RelativeDisplacementM,
    Channel::MassAccelerationMps2,
];

/// The rig's output-error problem. Parameters: the model's, then (with a fitted sine) each
/// step's base amplitude [m] and phase at the record's start [rad].
#[derive(Clone)]
pub struct RigOutputError<'a> {
    model: Model,
    mass_kg: f64,
    drive: RigDrive,
    records: Vec<&'a Record>,
    /// Settled samples of each record (indices within the record).
    settled: Vec<Range<usize>>,
    /// Noise std of each of `CHANNELS` per step.
    sigma: Vec<[f64; 3]>,
    /// Measured base offset per step (the sine has none).
    base_offset_m: Vec<f64>,
    /// Rows of each step's residual block.
    blocks: Vec<Range<usize>>,
    /// Per step and record sample: whether the mass acceleration sample is fitted (see
    /// [`RigOutputError::masked_at`]).
    acceleration_kept: Vec<Vec<bool>>,
    /// The base signal (spline drive only: it does not change with the parameters).
    spline_base: Option<PiecewiseSignal>,
    start_nuisance: Vec<f64>,
    stribeck: Option<FittedStribeckVelocity>,
    solver: SolverOptions,
}

impl<'a> RigOutputError<'a> {
    /// The problem of the sine records of a rig run, with their harmonic analyses.
    pub fn new(
        model: &Model,
        mass_kg: f64,
        records: &'a [Record],
        analyses: &[HarmonicAnalysis],
        drive: RigDrive,
    ) -> Result<RigOutputError<'a>, IdentifyError> {
        check_model(model)?;
        let recs = sine_records(records, analyses)?;
        for r in &recs {
            if let Some(c) = CHANNELS.iter().find(|c| r.channel(**c).is_none()) {
                return Err(IdentifyError::Step {
                    step: r.step,
                    problem: format!("channel {} is missing", c.name()),
                });
            }
        }
        let settled: Vec<Range<usize>> = recs
            .iter()
            .zip(analyses)
            .map(|(r, an)| {
                let a = an.first_settled_sample.min(r.len());
                a..(a + an.samples_used).min(r.len())
            })
            .collect();
        let fitted_base = drive == RigDrive::FittedSine;
        let base_phasor = |an: &HarmonicAnalysis, n: usize| {
            an.channel(Channel::BaseDisplacementM)
                .and_then(|p| p.phasors.get(n).copied())
                .unwrap_or_default()
        };
        let mut start_nuisance = Vec::new();
        if fitted_base {
            // s(t) = Re(C1 e^{j w (t - t_ref)}) = |C1| sin(w (t - t0) + phase) at the record's
            // start t0, with phase = arg C1 + pi/2 + w (t0 - t_ref).
            for (r, an) in recs.iter().zip(analyses) {
                let c1: Complex64 = base_phasor(an, 1);
                let w = 2.0 * std::f64::consts::PI * an.frequency_hz;
                start_nuisance.push(c1.norm());
                start_nuisance.push(
                    (c1.arg() + std::f64::consts::FRAC_PI_2 + w * (r.start_time_s - an.t_ref_s))
                        .rem_euclid(2.0 * std::f64::consts::PI),
                );
            }
        }
        let spline_base = match drive {
            RigDrive::FittedSine => None,
            RigDrive::MeasuredSpline { lowpass_hz } => {
                let fs = recs[0].sample_rate_hz;
                let mut base: Vec<f64> = Vec::new();
                for r in &recs {
                    base.extend_from_slice(r.channel(Channel::BaseDisplacementM).unwrap_or(&[]));
                }
                if let Some(fc) = lowpass_hz {
                    base = zero_phase_lowpass(&base, fs, fc);
                }
                let spline = CubicSpline::new(&base, 0.0, fs, SplineEnds::NotAKnot);
                let mut signal = PiecewiseSignal::new(base[0]);
                signal.push(0.0, Piece::Spline(Arc::new(spline)));
                Some(signal)
            }
        };
        Ok(RigOutputError {
            model: model.clone(),
            mass_kg,
            drive,
            base_offset_m: analyses.iter().map(|an| base_phasor(an, 0).re).collect(),
            sigma: channel_noise(analyses, &CHANNELS),
            acceleration_kept: recs.iter().map(|r| vec![true; r.len()]).collect(),
            records: recs,
            settled,
            blocks: Vec::new(),
            spline_base,
            start_nuisance,
            stribeck: None,
            solver: SolverOptions::default(),
        }
        .with_blocks())
    }

    /// The problem with its simulations run at RK4 sub-steps of at most `max_substep_s` (the
    /// default, 0.1 ms, is the truth simulators' accuracy; a comparison of models needs less).
    pub fn with_max_substep_s(mut self, max_substep_s: f64) -> Self {
        self.solver.max_substep_s = max_substep_s;
        self
    }

    /// The problem with the velocity of the model's Stribeck term fitted too, by
    /// [`RigOutputError::compare`] (its shape exponent held). The phasor fits choose the velocity
    /// on a grid and without the slow-slip band where it acts; held there, the shape exponents
    /// trade off against it (a world's exponent 0.93 at 19.8 mm/s refitted as exponent 1 at the
    /// Gaussian member's 72.5 mm/s predicted 3.16 % where the world leaves 1.11 %).
    pub fn fitting_stribeck_velocity(mut self) -> Result<Self, IdentifyError> {
        let (term, law) = self
            .model
            .terms
            .iter()
            .enumerate()
            .find_map(|(i, t)| t.stribeck().map(|l| (i, l)))
            .ok_or_else(|| {
                unsupported(format!("model {} has no Stribeck term", self.model.name))
            })?;
        self.stribeck = Some(FittedStribeckVelocity {
            term,
            exponent: law.exponent,
            start_ln_vs: law.velocity_mps.ln(),
        });
        Ok(self)
    }

    /// Parameters of the element: the model's coefficients and a fitted Stribeck velocity.
    fn p_model(&self) -> usize {
        self.model.terms.len() + usize::from(self.stribeck.is_some())
    }

    /// The model at `p`: its own, or with the Stribeck velocity of `p`.
    fn model_at(&self, p: &[f64]) -> std::borrow::Cow<'_, Model> {
        match self.stribeck {
            None => std::borrow::Cow::Borrowed(&self.model),
            Some(s) => {
                let mut m = self.model.clone();
                m.terms[s.term] = Arc::new(StribeckVelocity {
                    velocity_mps: p[self.model.terms.len()].exp(),
                    exponent: s.exponent,
                });
                std::borrow::Cow::Owned(m)
            }
        }
    }

    /// The rows of each step's residual block, from the settled ranges and the mask.
    fn with_blocks(mut self) -> Self {
        let fitted_base = self.spline_base.is_none();
        let mut row = 0;
        self.blocks = self
            .settled
            .iter()
            .zip(&self.acceleration_kept)
            .map(|(s, kept)| {
                let n = s.len() * if fitted_base { 2 } else { 1 }
                    + s.clone().filter(|i| kept[*i]).count();
                row += n;
                row - n..row
            })
            .collect();
        self
    }

    /// The problem with the mass acceleration samples next to a stick/slip event of the
    /// simulation at `p` left out ([`event_mask`]: the acceleration jumps where the element
    /// sticks or reverses); the mask stays fixed during a pass.
    pub fn masked_at(&self, p: &[f64]) -> Result<RigOutputError<'a>, IdentifyError> {
        let sim = self.simulate(p)?;
        let mut out = self.clone();
        for (kept, trace) in out.acceleration_kept.iter_mut().zip(&sim.traces) {
            *kept = event_mask(trace, kept.len());
        }
        Ok(out.with_blocks())
    }

    /// Replaces the measured noise std of each channel by `sigma` (base displacement, relative
    /// displacement, mass acceleration), e.g. the true noise for the Cramer-Rao bound.
    pub fn with_noise(mut self, sigma: [f64; 3]) -> Self {
        for s in &mut self.sigma {
            *s = sigma;
        }
        self
    }

    /// The start of the fit: `theta`, then the fitted-sine start values.
    pub fn start(&self, theta: &[f64]) -> Vec<f64> {
        let mut p = theta.to_vec();
        p.extend(self.stribeck.map(|s| s.start_ln_vs));
        p.extend_from_slice(&self.start_nuisance);
        p
    }

    /// The covariance `(J^T W J)^-1` of every parameter at `p` (the Cramer-Rao bound when
    /// `p` is the truth and the noise the true one).
    pub fn covariance_at(&self, p: &[f64]) -> Result<DMatrix<f64>, IdentifyError> {
        super::lm::covariance_at(&self.masked_at(p)?, p)
    }

    /// Refines `first` (fd-multi on the same data). Two passes: the first weights each channel
    /// by the residual of its harmonic fit, which overstates the noise of a channel with
    /// harmonics above the fitted ones (the mass acceleration jumps where the element starts
    /// to slip: by 25-70 % on the paper's rig); the second by the RMS of each channel's
    /// misfit per step at the first fit (maximum likelihood with unknown noise levels).
    pub fn refine(&self, first: &Identification) -> Result<Identification, IdentifyError> {
        if self.stribeck.is_some() {
            return Err(unsupported(
                "a refinement with a fitted Stribeck velocity (compare fits it)".into(),
            ));
        }
        let start = self.start(&first.theta());
        let pass1 = self.masked_at(&start)?;
        let fit = levenberg_marquardt(&pass1, start)?;
        let pass2 = pass1.reweighted(&fit.residual).masked_at(&fit.p)?;
        let fit = levenberg_marquardt(&pass2, fit.p)?;
        let note = match self.drive {
            RigDrive::FittedSine => {
                let amps: Vec<f64> = fit.p[self.p_model()..].iter().step_by(2).copied().collect();
                let (lo, hi) = amps
                    .iter()
                    .fold((f64::INFINITY, 0.0f64), |(l, h), a| (l.min(*a), h.max(*a)));
                format!(
                    "rig driven by a fitted sine per step (base amplitude {lo:.4e} to {hi:.4e} m)"
                )
            }
            RigDrive::MeasuredSpline { .. } => "rig driven by the measured base samples".into(),
        };
        Ok(identification(
            &self.model,
            first,
            &fit,
            self.records.iter().map(|r| r.step).collect(),
            note,
        ))
    }

    /// Fits the model's parameters from `theta`, the channels weighted by their measured noise
    /// throughout (a refinement re-estimates the weights from its own misfit, which makes every
    /// model's misfit about 1, so that misfits could not be compared between models). Each pass
    /// re-masks the samples next to the simulation's events ([`RigOutputError::masked_at`]); the
    /// misfit is that of the last pass's mask.
    pub fn compare(&self, theta: &[f64]) -> Result<RigMisfit, IdentifyError> {
        let p_model = self.p_model();
        let full = self.start(theta);
        let mut problem = self.masked_at(&full)?;
        let mut p = full[..p_model].to_vec();
        let mut fit = None;
        for _ in 0..COMPARE_PASSES {
            let partial = Partial {
                inner: &problem,
                full: full.clone(),
                free: (0..p_model).collect(),
            };
            let f = levenberg_marquardt_within(&partial, p, COMPARE_LIMITS)?;
            p = f.p.clone();
            fit = Some(f);
            // Another pass only if the events moved across samples.
            let next = self.masked_at(&partial.expand(&p))?;
            if next.acceleration_kept == problem.acceleration_kept {
                break;
            }
            problem = next;
        }
        let fit = fit.ok_or(IdentifyError::NoSteps)?;
        let n_terms = self.model.terms.len();
        Ok(RigMisfit {
            theta: fit.p[..n_terms].to_vec(),
            misfit_rms: fit.rms(),
            samples: fit.residual.len(),
            stribeck_velocity_mps: self.stribeck.map(|_| fit.p[n_terms].exp()),
        })
    }

    /// The problem with each channel's noise per step re-estimated from the weighted residual
    /// `r` of this problem: the RMS of the channel's misfit over the step's settled samples.
    fn reweighted(&self, r: &[f64]) -> RigOutputError<'a> {
        let mut out = self.clone();
        let fitted_base = self.spline_base.is_none();
        for (k, block) in self.blocks.iter().enumerate() {
            let mut row = block.start;
            for (ci, c) in CHANNELS.iter().enumerate() {
                if ci == 0 && !fitted_base {
                    continue;
                }
                let n = if *c == Channel::MassAccelerationMps2 {
                    let kept = &self.acceleration_kept[k];
                    self.settled[k].clone().filter(|i| kept[*i]).count()
                } else {
                    self.settled[k].len()
                };
                let seg = &r[row..row + n];
                let rms = (seg.iter().map(|v| v * v).sum::<f64>() / n.max(1) as f64).sqrt();
                if rms.is_finite() && rms > 0.0 {
                    out.sigma[k][ci] *= rms;
                }
                row += n;
            }
        }
        out
    }

    /// The rig simulated at `p`.
    fn simulate(&self, p: &[f64]) -> Result<SimOutput, IdentifyError> {
        let model = self.model_at(p);
        let element = ModelElement::new(&model, &p[..self.model.terms.len()]);
        let program = Program::replaying(&self.records, self.base_signal(p));
        simulate_rig(
            &element,
            self.mass_kg,
            &program,
            &RigEffects::default(),
            RigInitial::default(),
            &self.solver,
        )
        .map_err(|e| unsupported(format!("output-error simulation of the rig: {e}")))
    }

    /// The base signal of the parameters `p` (spline: the measured one).
    fn base_signal(&self, p: &[f64]) -> PiecewiseSignal {
        if let Some(s) = &self.spline_base {
            return s.clone();
        }
        super::sine_per_record_signal(&self.records, &p[self.p_model()..])
    }
}

impl Problem for RigOutputError<'_> {
    fn residual(&self, p: &[f64]) -> Result<Vec<f64>, IdentifyError> {
        let sim = self.simulate(p)?;
        let fitted_base = self.spline_base.is_none();
        let mut out = Vec::with_capacity(self.blocks.last().map_or(0, |b| b.end));
        for (k, (rm, rs)) in self.records.iter().zip(&sim.records).enumerate() {
            for (ci, c) in CHANNELS.iter().enumerate() {
                if ci == 0 && !fitted_base {
                    continue;
                }
                let offset = if ci == 0 { self.base_offset_m[k] } else { 0.0 };
                let (Some(m), Some(s)) = (rm.channel(*c), rs.channel(*c)) else {
                    return Err(IdentifyError::Step {
                        step: rm.step,
                        problem: format!("channel {} is missing", c.name()),
                    });
                };
                let sg = self.sigma[k][ci];
                let kept = &self.acceleration_kept[k];
                out.extend(
                    self.settled[k]
                        .clone()
                        .filter(|i| *c != Channel::MassAccelerationMps2 || kept[*i])
                        .map(|i| (m[i] - offset - s[i]) / sg),
                );
            }
        }
        Ok(out)
    }

    /// Each step's amplitude (phase) moves that step's samples, and the next steps' only by
    /// the transient it leaves, which has died out where the samples are settled: all
    /// amplitudes share one simulation, all phases another.
    fn column_groups(&self, np: usize) -> Vec<Vec<usize>> {
        let p_model = self.p_model();
        let mut g: Vec<Vec<usize>> = (0..p_model).map(|j| vec![j]).collect();
        if np > p_model {
            g.push((p_model..np).step_by(2).collect());
            g.push((p_model + 1..np).step_by(2).collect());
        }
        g
    }

    /// Phases in radians and ln vs (their values say nothing of their sizes).
    fn scale(&self, p: &[f64]) -> Vec<f64> {
        let p_model = self.p_model();
        let ln_vs = self.stribeck.map(|_| self.model.terms.len());
        p.iter()
            .enumerate()
            .map(|(j, v)| {
                if j >= p_model && (j - p_model) % 2 == 1 || Some(j) == ln_vs || *v == 0.0 {
                    1.0
                } else {
                    v.abs()
                }
            })
            .collect()
    }

    fn rows(&self, j: usize, n: usize) -> Range<usize> {
        let p_model = self.p_model();
        if j < p_model {
            0..n
        } else {
            self.blocks[(j - p_model) / 2].clone()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::ModelOptions;
    use crate::phasor::PhasorOptions;
    use crate::pipeline::analyse_sine_steps;
    use crate::sim::{RunSpec, TruthElement};

    /// The acceleration samples left out are exactly those within two samples of a change of
    /// the truth simulation's stick/slip state (and some are: the rig sticks at every reversal).
    #[test]
    fn acceleration_samples_next_to_events_are_left_out() {
        let spec = RunSpec::paper_rig_sine(None, 0);
        let out = spec.simulate_detailed().unwrap();
        let (an, _) =
            analyse_sine_steps(&out.records, &PhasorOptions::for_identification()).unwrap();
        let model = Model::by_name("coulomb", &ModelOptions::default()).unwrap();
        let problem =
            RigOutputError::new(&model, 36.0, &out.records, &an, RigDrive::FittedSine).unwrap();
        let e = TruthElement::rig_coulomb();
        let mut p = vec![
            e.stiffness_n_per_m,
            e.damping_n_s_per_m,
            e.friction.unwrap().kinetic_n,
        ];
        for piece in &spec.program().signal.pieces[1..] {
            let Piece::Sine {
                amplitude, phase, ..
            } = piece
            else {
                panic!("sine steps")
            };
            p.extend([*amplitude, *phase]);
        }
        let masked = problem.masked_at(&p).unwrap();
        let mut dropped = 0;
        for (kept, trace) in masked.acceleration_kept.iter().zip(&out.traces) {
            let state: Vec<(bool, bool)> = trace
                .samples
                .iter()
                .map(|s| (s.stuck, s.relative_velocity_mps > 0.0))
                .collect();
            for (i, k) in kept.iter().enumerate() {
                let near = (i.saturating_sub(2)..(i + 2).min(state.len() - 1))
                    .any(|j| state[j] != state[j + 1]);
                assert_eq!(!k, near, "sample {i}");
                dropped += usize::from(!k);
            }
        }
        assert!(dropped > 100, "{dropped} samples left out");
        // The residual at the truth is zero, and only the mass acceleration lost samples.
        let r = masked.residual(&p).unwrap();
        assert!(
            r.iter().all(|v| v.abs() < 1e-6),
            "{:e}",
            r.iter().fold(0.0f64, |a, v| a.max(v.abs()))
        );
        let all: usize = masked.settled.iter().map(|s| 3 * s.len()).sum();
        assert!(r.len() < all && r.len() > all - dropped - 1);
    }
}
