//! Output error for the element test (`Setup::Element`): the model's element behind the moving
//! mass, simulated by the element-test simulator ([`simulate_element`]) under the drive the
//! bench controlled, fitted to the settled samples of every measured channel (x, F and, when
//! recorded, the mass acceleration), each weighted by its measured noise.
//!
//! The drive ([`ElementDrive`]) is the channel that is a sine: the stroke on a damper dyno or
//! mount tester, the force on a shaker-driven single-DOF system. The data do not say which, so
//! it is the channel whose harmonics above the first are the smaller share of it
//! ([`element_drive_of`]); the other channel is the element's response and carries its distortion.
//! The drive is a sine per step whose amplitude and phase are fitted with the element, plus one
//! offset for the run (the stroke's mid position, or a static force), started from the drive
//! channel's phasors; its samples are measurements like the others.
//!
//! - Displacement drive: the "simulation" is the model's force `m x'' + g(x, x')` along the
//!   fitted stroke, friction on its slip law wherever x' != 0 (the fitted stroke reverses at
//!   isolated instants). Both the stroke and the force are noisy, so this is the
//!   errors-in-variables maximum likelihood: the stroke's noise enters through the sine's
//!   numbers of each step, not sample by sample into the regressor, and the friction switches
//!   at the fitted stroke's reversals, not at the noisy ones.
//! - Force drive: the mass simulated under the fitted force with the exact stick-slip
//!   integrator, from rest, the state carried from record to record; x and x'' (and F against
//!   the fitted force) are the misfit.
//!
//! The channel that jumps at a stick/slip event (the force of a displacement drive, the
//! acceleration of a force drive) leaves out its samples next to the simulation's events, as
//! the rig does ([`super::event_mask`]).

use std::ops::Range;

use nalgebra::DMatrix;
use num_complex::Complex64;

use super::element::{ModelElement, check_model};
use super::lm::{Problem, jacobian, levenberg_marquardt};
use super::{channel_noise, event_mask, identification, sine_records, unsupported};
use crate::identify::{Identification, IdentifyError};
use crate::model::Model;
use crate::phasor::HarmonicAnalysis;
use crate::record::{Channel, Record};
use crate::sim::excitation::{PiecewiseSignal, Program};
use crate::sim::{ElementDrive, SimOutput, SolverOptions, simulate_element};

/// The channels an element test is fitted on, in the order of each step's residual block (the
/// acceleration when every record has it).
const CHANNELS: [Channel; 3] = [
    Channel::RelativeDisplacementM,
    Channel::ForceN,
    Channel::MassAccelerationMps2,
];

/// The channel a drive prescribes.
fn drive_channel(drive: ElementDrive) -> Channel {
    match drive {
        ElementDrive::Displacement => Channel::RelativeDisplacementM,
        ElementDrive::Force => Channel::ForceN,
    }
}

/// The channel whose samples jump where the simulated element sticks or reverses.
fn jumping_channel(drive: ElementDrive) -> Channel {
    match drive {
        ElementDrive::Displacement => Channel::ForceN,
        ElementDrive::Force => Channel::MassAccelerationMps2,
    }
}

/// Share of a channel's harmonics 2..N in its harmonics 1..N (power, over the steps).
fn distortion(analyses: &[HarmonicAnalysis], c: Channel) -> f64 {
    let (mut high, mut all) = (0.0, 0.0);
    for p in analyses.iter().filter_map(|an| an.channel(c)) {
        for (n, z) in p.phasors.iter().enumerate().skip(1) {
            all += z.norm_sqr();
            if n >= 2 {
                high += z.norm_sqr();
            }
        }
    }
    high / all.max(f64::MIN_POSITIVE)
}

/// The drive of an element test: the channel of x and F that is the purer sine. (A linear
/// element leaves both pure; either drive then describes the data.)
pub fn element_drive_of(analyses: &[HarmonicAnalysis]) -> ElementDrive {
    if distortion(analyses, Channel::RelativeDisplacementM) <= distortion(analyses, Channel::ForceN)
    {
        ElementDrive::Displacement
    } else {
        ElementDrive::Force
    }
}

/// The element test's output-error problem. Parameters: the model's, the moving mass when it
/// is identified, each step's drive amplitude and phase at the record's start [rad], then the
/// drive's offset.
#[derive(Clone)]
pub struct ElementOutputError<'a> {
    model: Model,
    /// The known moving mass; None: fitted (the parameter after the model's).
    mass_kg: Option<f64>,
    drive: ElementDrive,
    records: Vec<&'a Record>,
    /// Fitted channels (x, F, and the acceleration when recorded).
    channels: Vec<Channel>,
    settled: Vec<Range<usize>>,
    /// Noise std per step of each of `channels`.
    sigma: Vec<Vec<f64>>,
    /// Per step and record sample: whether the jumping channel's sample is fitted.
    kept: Vec<Vec<bool>>,
    blocks: Vec<Range<usize>>,
    start_nuisance: Vec<f64>,
}

impl<'a> ElementOutputError<'a> {
    /// The problem of the sine records of an element test driven as `drive` says (see
    /// [`element_drive_of`]), with their harmonic analyses; `moving_mass_kg` None: the mass is fitted.
    pub fn new(
        model: &Model,
        moving_mass_kg: Option<f64>,
        records: &'a [Record],
        analyses: &[HarmonicAnalysis],
        drive: ElementDrive,
    ) -> Result<ElementOutputError<'a>, IdentifyError> {
        check_model(model)?;
        let recs = sine_records(records, analyses)?;
        for r in &recs {
            if let Some(c) = CHANNELS[..2].iter().find(|c| r.channel(**c).is_none()) {
                return Err(IdentifyError::Step {
                    step: r.step,
                    problem: format!("channel {} is missing", c.name()),
                });
            }
        }
        let with_acceleration = recs
            .iter()
            .all(|r| r.channel(Channel::MassAccelerationMps2).is_some());
        let channels = CHANNELS[..if with_acceleration { 3 } else { 2 }].to_vec();
        let settled = recs
            .iter()
            .zip(analyses)
            .map(|(r, an)| {
                let a = an.first_settled_sample.min(r.len());
                a..(a + an.samples_used).min(r.len())
            })
            .collect();
        let noise = channel_noise(analyses, &CHANNELS);
        let sigma = noise.iter().map(|s| s[..channels.len()].to_vec()).collect();
        // The drive s(t) = Re(C1 e^{j w (t - t_ref)}) = |C1| sin(w (t - t0) + phase) at the
        // record's start t0, with phase = arg C1 + pi/2 + w (t0 - t_ref); the offset is the
        // mean of the steps' C0.
        let dc = drive_channel(drive);
        let phasor = |an: &HarmonicAnalysis, n: usize| -> Complex64 {
            an.channel(dc)
                .and_then(|p| p.phasors.get(n).copied())
                .unwrap_or_default()
        };
        let mut start_nuisance = Vec::new();
        for (r, an) in recs.iter().zip(analyses) {
            let c1 = phasor(an, 1);
            let w = 2.0 * std::f64::consts::PI * an.frequency_hz;
            start_nuisance.push(c1.norm());
            start_nuisance.push(
                (c1.arg() + std::f64::consts::FRAC_PI_2 + w * (r.start_time_s - an.t_ref_s))
                    .rem_euclid(2.0 * std::f64::consts::PI),
            );
        }
        start_nuisance
            .push(analyses.iter().map(|an| phasor(an, 0).re).sum::<f64>() / analyses.len() as f64);
        Ok(ElementOutputError {
            model: model.clone(),
            mass_kg: moving_mass_kg,
            drive,
            kept: recs.iter().map(|r| vec![true; r.len()]).collect(),
            records: recs,
            channels,
            settled,
            sigma,
            blocks: Vec::new(),
            start_nuisance,
        }
        .with_blocks())
    }

    /// Parameters of the element: the model's, and the moving mass when fitted.
    fn p_element(&self) -> usize {
        self.model.terms.len() + usize::from(self.mass_kg.is_none())
    }

    fn with_blocks(mut self) -> Self {
        let mut row = 0;
        self.blocks = (0..self.records.len())
            .map(|k| {
                let n: usize = self
                    .channels
                    .iter()
                    .map(|c| self.rows_of(k, *c).count())
                    .sum();
                row += n;
                row - n..row
            })
            .collect();
        self
    }

    /// The record samples of step `k` fitted on channel `c`.
    fn rows_of(&self, k: usize, c: Channel) -> impl Iterator<Item = usize> + '_ {
        let masked = c == jumping_channel(self.drive);
        let kept = &self.kept[k];
        self.settled[k].clone().filter(move |i| !masked || kept[*i])
    }

    /// Replaces the measured noise std of each channel by `sigma` (x, F, then the mass
    /// acceleration when fitted), e.g. the true noise for the Cramer-Rao bound.
    pub fn with_noise(mut self, sigma: &[f64]) -> Self {
        for s in &mut self.sigma {
            for (v, t) in s.iter_mut().zip(sigma) {
                *v = *t;
            }
        }
        self
    }

    /// The covariance `(J^T W J)^-1` of every parameter at `p` (the Cramer-Rao bound when `p`
    /// is the truth and the noise the true one): the element's parameters, each step's drive
    /// amplitude and phase, the drive's offset.
    pub fn covariance_at(&self, p: &[f64]) -> Result<DMatrix<f64>, IdentifyError> {
        super::lm::covariance_at(&self.masked_at(p)?, p)
    }

    /// The Gauss-Newton step from `p` in every parameter: when `p` is the truth and the noise
    /// the true one, the error of the linearised maximum-likelihood estimate for this noise
    /// draw (whose covariance is [`ElementOutputError::covariance_at`]).
    pub fn gauss_newton_step_at(&self, p: &[f64]) -> Result<Vec<f64>, IdentifyError> {
        let scale = self.scale(p);
        let masked = self.masked_at(p)?;
        let r = masked.residual(p)?;
        let jac = jacobian(&masked, p, &r, &scale)?;
        let rhs = jac.transpose() * nalgebra::DVector::from_column_slice(&r);
        let step = (jac.transpose() * &jac)
            .lu()
            .solve(&rhs)
            .ok_or_else(|| unsupported("singular information at the truth".into()))?;
        Ok(step.iter().zip(&scale).map(|(d, s)| d * s).collect())
    }

    /// The problem with the jumping channel's samples next to a stick/slip event of the
    /// simulation at `p` left out (fixed during a pass; see [`super::event_mask`]).
    fn masked_at(&self, p: &[f64]) -> Result<ElementOutputError<'a>, IdentifyError> {
        let mut out = self.clone();
        if self.model.has_velocity_jump() {
            let sim = self.simulate(p)?;
            for (kept, trace) in out.kept.iter_mut().zip(&sim.traces) {
                *kept = event_mask(trace, kept.len());
            }
        }
        Ok(out.with_blocks())
    }

    /// The problem with each channel's noise per step re-estimated from the weighted residual
    /// `r`: the RMS of the channel's misfit over the step's fitted samples.
    fn reweighted(&self, r: &[f64]) -> ElementOutputError<'a> {
        let mut out = self.clone();
        for (k, block) in self.blocks.iter().enumerate() {
            let mut row = block.start;
            for (ci, c) in self.channels.iter().enumerate() {
                let n = self.rows_of(k, *c).count();
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

    /// Refines `first` (fd-multi on the same data): two passes, the second with each channel's
    /// noise per step re-estimated from the first fit's misfit (as the rig's refinement).
    pub fn refine(&self, first: &Identification) -> Result<Identification, IdentifyError> {
        let mut start = first.theta();
        start.truncate(self.p_element());
        if start.len() != self.p_element() {
            return Err(unsupported(format!(
                "output error needs {} parameters from fd-multi, got {}",
                self.p_element(),
                start.len()
            )));
        }
        start.extend_from_slice(&self.start_nuisance);
        let pass1 = self.masked_at(&start)?;
        let fit = levenberg_marquardt(&pass1, start)?;
        let pass2 = pass1.reweighted(&fit.residual).masked_at(&fit.p)?;
        let fit = levenberg_marquardt(&pass2, fit.p)?;
        let what = match self.drive {
            ElementDrive::Displacement => "displacement (stroke)",
            ElementDrive::Force => "force",
        };
        let note = format!(
            "element test driven by its {what}, the least distorted channel: a fitted sine per step and one offset ({:.4e})",
            fit.p[fit.p.len() - 1]
        );
        Ok(identification(
            &self.model,
            first,
            &fit,
            self.records.iter().map(|r| r.step).collect(),
            note,
        ))
    }

    /// The element test simulated at `p`.
    fn simulate(&self, p: &[f64]) -> Result<SimOutput, IdentifyError> {
        let p_model = self.model.terms.len();
        let mass_kg = self.mass_kg.unwrap_or(p[p_model]);
        let offset = p[p.len() - 1];
        let (x0, f0) = match self.drive {
            ElementDrive::Displacement => (offset, 0.0),
            ElementDrive::Force => (0.0, offset),
        };
        let element = ModelElement::new(&self.model, &p[..p_model]).with_offsets(x0, f0);
        let program = Program::replaying(
            &self.records,
            self.drive_signal(&p[self.p_element()..p.len() - 1]),
        );
        simulate_element(
            &element,
            mass_kg,
            self.drive,
            &program,
            &SolverOptions::default(),
        )
        .map_err(|e| unsupported(format!("output-error simulation of the element test: {e}")))
    }

    /// The drive without its offset: a sine per record (`nuisance`: amplitude and phase of
    /// each), at rest before the run at its starting value.
    fn drive_signal(&self, nuisance: &[f64]) -> PiecewiseSignal {
        super::sine_per_record_signal(&self.records, nuisance)
    }
}

impl Problem for ElementOutputError<'_> {
    fn residual(&self, p: &[f64]) -> Result<Vec<f64>, IdentifyError> {
        let sim = self.simulate(p)?;
        let offset = p[p.len() - 1];
        let dc = drive_channel(self.drive);
        let mut out = Vec::with_capacity(self.blocks.last().map_or(0, |b| b.end));
        for (k, (rm, rs)) in self.records.iter().zip(&sim.records).enumerate() {
            for (ci, c) in self.channels.iter().enumerate() {
                let (Some(m), Some(s)) = (rm.channel(*c), rs.channel(*c)) else {
                    return Err(IdentifyError::Step {
                        step: rm.step,
                        problem: format!("channel {} is missing", c.name()),
                    });
                };
                // The simulated stroke is the drive without its offset (the element sees
                // x0 + s); a simulated force already holds the force offset f0.
                let shift = if *c == dc && dc == Channel::RelativeDisplacementM {
                    offset
                } else {
                    0.0
                };
                let sg = self.sigma[k][ci];
                out.extend(self.rows_of(k, *c).map(|i| (m[i] - shift - s[i]) / sg));
            }
        }
        Ok(out)
    }

    /// Each step's amplitude (phase) moves that step's samples, and the next steps' only by
    /// the transient it leaves, which has died out where the samples are settled: all
    /// amplitudes share one simulation, all phases another.
    fn column_groups(&self, np: usize) -> Vec<Vec<usize>> {
        let pe = self.p_element();
        let mut g: Vec<Vec<usize>> = (0..pe).map(|j| vec![j]).collect();
        g.push((pe..np - 1).step_by(2).collect());
        g.push((pe + 1..np - 1).step_by(2).collect());
        g.push(vec![np - 1]);
        g
    }

    fn rows(&self, j: usize, n: usize) -> Range<usize> {
        let pe = self.p_element();
        if j < pe || j + 1 == self.start_nuisance.len() + pe {
            0..n
        } else {
            self.blocks[(j - pe) / 2].clone()
        }
    }

    /// Phases in radians; the offset in units of the largest drive amplitude (it may be 0).
    fn scale(&self, p: &[f64]) -> Vec<f64> {
        let pe = self.p_element();
        let np = p.len();
        let amplitude = p[pe..np - 1]
            .iter()
            .step_by(2)
            .fold(0.0f64, |a, v| a.max(v.abs()));
        p.iter()
            .enumerate()
            .map(|(j, v)| {
                if j + 1 == np {
                    amplitude.max(f64::MIN_POSITIVE)
                } else if j >= pe && (j - pe) % 2 == 1 || *v == 0.0 {
                    1.0
                } else {
                    v.abs()
                }
            })
            .collect()
    }
}
