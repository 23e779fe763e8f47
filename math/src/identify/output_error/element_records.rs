//! Output error on element-test records of any excitation (band-random, one-period or short
//! multisines, road profiles): records that have no settled steps to take phasors from.
//!
//! The start is the time-domain fit of the force along the measured motion
//! (`td_range_equations` of the element test). What refines it depends on what the bench
//! controlled ([`records_drive`]):
//!
//! - Displacement drive (damper dyno, mount tester): the model's output is the force along the
//!   imposed motion, `m x'' + g(x, x')`, linear in theta, so the start is already the
//!   output-error estimate; it is returned as it is.
//! - Force drive (a single-DOF system on a shaker): the mass is simulated under the measured
//!   force (a spline through its samples) with exact stick-slip, each record from its own
//!   initial displacement and velocity (fitted, so records may start in motion), and theta,
//!   the moving mass when it is identified, and the initial states are fitted to every sample
//!   of the measured displacement, each record weighted by its displacement noise (estimated
//!   from its spectrum above the band). The standard deviations are the Gauss-Newton ones,
//!   scaled up by the misfit when the model misses by more than the noise.

use std::ops::Range;

use nalgebra::DMatrix;
use num_complex::Complex64;

use super::element::{ModelElement, check_model};
use super::lm::{self, Limits, Partial, Problem};
use crate::identify::{Identification, IdentifyError, Method, Parameter};
use crate::measured_state::{CUTOFF_MULTIPLE, MeasuredState, white_noise_std_above};
use crate::model::Model;
use crate::record::{Channel, Excitation, Record};
use crate::sim::{ElementDrive, ForcedInitial, SolverOptions, simulate_on_sampled_force};

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

/// Share of a channel's power at the bins a periodic multisine record does not excite, over
/// the record's last whole periods; None when the record is not a multisine of whole samples
/// per period.
fn off_line_share(r: &Record, c: Channel) -> Option<f64> {
    let Excitation::Multisine {
        base_frequency_hz,
        lines,
        ..
    } = &r.excitation
    else {
        return None;
    };
    let y = r.channel(c)?;
    let per = r.sample_rate_hz / base_frequency_hz;
    if (per - per.round()).abs() > 1e-6 || per.round() < 4.0 {
        return None;
    }
    let per = per.round() as usize;
    let periods = y.len() / per;
    if periods == 0 {
        return None;
    }
    let tail = &y[y.len() - periods * per..];
    let mut buf: Vec<Complex64> = tail.iter().map(|v| Complex64::new(*v, 0.0)).collect();
    rustfft::FftPlanner::new()
        .plan_fft_forward(buf.len())
        .process(&mut buf);
    let (mut on, mut off) = (0.0, 0.0);
    for (k, b) in buf.iter().enumerate().take(buf.len() / 2).skip(1) {
        let line = k % periods == 0 && lines.binary_search(&(k / periods)).is_ok();
        if line {
            on += b.norm_sqr();
        } else {
            off += b.norm_sqr();
        }
    }
    Some(off / (on + off).max(f64::MIN_POSITIVE))
}

/// What the bench controlled in records that are not sine steps: where every record is a
/// labelled multisine, the channel of x and F with the smaller share of its power off the
/// excited lines (the other carries the element's distortion, as [`super::element_drive_of`]
/// decides for sine steps); otherwise the displacement, as element benches are (a damper dyno,
/// a mount tester).
pub fn records_drive(records: &[&Record]) -> ElementDrive {
    let share = |c: Channel| -> Option<f64> {
        records
            .iter()
            .map(|r| off_line_share(r, c))
            .sum::<Option<f64>>()
    };
    match (
        share(Channel::RelativeDisplacementM),
        share(Channel::ForceN),
    ) {
        (Some(x), Some(f)) if f < x => ElementDrive::Force,
        _ => ElementDrive::Displacement,
    }
}

/// The displacement and velocity a record starts with: a parabola fitted to its first samples
/// (an eighth of the highest excitation period, at least five samples).
fn starting_state(x: &[f64], sample_rate_hz: f64, top_frequency_hz: f64) -> ForcedInitial {
    let k = ((START_WINDOW_PERIODS * sample_rate_hz / top_frequency_hz).round() as usize)
        .clamp(5, x.len());
    let a = DMatrix::from_fn(k, 3, |i, j| (i as f64 / sample_rate_hz).powi(j as i32));
    let b = nalgebra::DVector::from_column_slice(&x[..k]);
    match a.svd(true, true).solve(&b, 1e-12) {
        Ok(c) => ForcedInitial {
            displacement_m: c[0],
            velocity_mps: c[1],
        },
        Err(_) => ForcedInitial {
            displacement_m: x[0],
            velocity_mps: 0.0,
        },
    }
}

/// The force-driven output-error problem. Parameters: the model's, the moving mass when it is
/// identified, then each record's initial displacement and velocity.
pub struct ForcedRecordsOutputError<'a> {
    model: Model,
    mass_kg: Option<f64>,
    records: Vec<&'a Record>,
    /// Noise std of each record's displacement [m].
    sigma_m: Vec<f64>,
    /// Residual rows of each record.
    blocks: Vec<Range<usize>>,
    /// Scale of each record's displacement and velocity (their RMS).
    state_scale: Vec<[f64; 2]>,
    start_states: Vec<ForcedInitial>,
    solver: SolverOptions,
}

impl<'a> ForcedRecordsOutputError<'a> {
    /// The problem of `records` (each with displacement and force), the moving mass known or
    /// (None) fitted.
    pub fn new(
        model: &Model,
        moving_mass_kg: Option<f64>,
        records: &[&'a Record],
    ) -> Result<Self, IdentifyError> {
        check_model(model)?;
        let mut sigma_m = Vec::new();
        let mut blocks = Vec::new();
        let mut state_scale = Vec::new();
        let mut start_states = Vec::new();
        let mut rows = 0;
        for r in records {
            let state = MeasuredState::of(r).map_err(|e| step_error(r.step, e.to_string()))?;
            let x = &state.displacement_m;
            let fs = r.sample_rate_hz;
            let cutoff = CUTOFF_MULTIPLE * state.top_frequency_hz;
            let rms = |y: &[f64]| {
                let mean = y.iter().sum::<f64>() / y.len() as f64;
                (y.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / y.len() as f64).sqrt()
            };
            let x_rms = rms(x).max(f64::MIN_POSITIVE);
            // Noise-free data would be weighted by round-off: floor at 1e-6 of the motion.
            let sigma = white_noise_std_above(x, fs, cutoff)
                .unwrap_or(0.0)
                .max(1e-6 * x_rms);
            sigma_m.push(sigma);
            state_scale.push([x_rms, rms(&state.velocity_mps).max(f64::MIN_POSITIVE)]);
            start_states.push(starting_state(x, fs, state.top_frequency_hz));
            blocks.push(rows..rows + x.len());
            rows += x.len();
        }
        Ok(ForcedRecordsOutputError {
            model: model.clone(),
            mass_kg: moving_mass_kg,
            records: records.to_vec(),
            sigma_m,
            blocks,
            state_scale,
            start_states,
            solver: SolverOptions::default(),
        })
    }

    fn p_element(&self) -> usize {
        self.model.terms.len() + usize::from(self.mass_kg.is_none())
    }

    /// Initial-state parameter index of record `k` (displacement; velocity is the next).
    fn state_index(&self, k: usize) -> usize {
        self.p_element() + 2 * k
    }

    /// The simulated displacement of record `k` with element parameters `element` (theta,
    /// then the mass when fitted) from `initial`.
    pub fn simulate(
        &self,
        k: usize,
        element: &[f64],
        initial: ForcedInitial,
    ) -> Result<Vec<f64>, IdentifyError> {
        let r = self.records[k];
        let p = self.model.terms.len();
        let mass = self.mass_kg.unwrap_or_else(|| element[p]);
        let el = ModelElement::new(&self.model, &element[..p]);
        let force = r.channel(Channel::ForceN).unwrap_or(&[]);
        simulate_on_sampled_force(&el, mass, force, r.sample_rate_hz, initial, &self.solver)
            .map(|resp| resp.displacement_m)
            .map_err(|e| step_error(r.step, format!("output-error simulation: {e}")))
            .and_then(|x| {
                if x.iter().all(|v| v.is_finite()) {
                    Ok(x)
                } else {
                    Err(step_error(r.step, "output-error simulation diverges"))
                }
            })
    }

    /// Whether every record simulates at parameters `p` (all of this problem's).
    fn simulates(&self, p: &[f64]) -> Result<(), IdentifyError> {
        let np = self.p_element();
        for k in 0..self.records.len() {
            let j = self.state_index(k);
            let initial = ForcedInitial {
                displacement_m: p[j],
                velocity_mps: p[j + 1],
            };
            self.simulate(k, &p[..np], initial)?;
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
            p0.extend([s.displacement_m, s.velocity_mps]);
        }
        self.simulates(&p0).map_err(|e| {
            step_error(
                self.records[0].step,
                format!("the time-domain start cannot be simulated under the measured force: {e}"),
            )
        })?;
        // Initial states first, theta held: a start far from the record's state would
        // otherwise pull theta along.
        let states = Partial {
            inner: self,
            full: p0.clone(),
            free: (self.p_element()..p0.len()).collect(),
        };
        let fit = lm::levenberg_marquardt_within(
            &states,
            p0[self.p_element()..].to_vec(),
            FROM_TIME_DOMAIN,
        )?;
        let p1 = states.expand(&fit.p);
        let fit = lm::levenberg_marquardt_within(self, p1, FROM_TIME_DOMAIN)?;
        let cov = self.sandwich_covariance(&fit)?;
        Ok(self.identification(start, &fit, &cov))
    }

    /// The covariance of the parameters from the residuals as they are: the sandwich
    /// `B^-1 M B^-1` with `B = J^T J` and `M` the Bartlett-weighted sum of the products of the
    /// per-sample scores `J_i r_i` up to the lag where the residual stops being correlated,
    /// within each record. The residual of a force-driven fit is not white (the noise on the
    /// measured force drives the simulated mass, and a form error is smooth), and the
    /// Gauss-Newton covariance would then understate the uncertainty several times over.
    fn sandwich_covariance(&self, fit: &lm::Fit) -> Result<DMatrix<f64>, IdentifyError> {
        let np = fit.p.len();
        let jac = lm::jacobian(self, &fit.p, &fit.residual, &fit.scale)?;
        let r = &fit.residual;
        let lag = self.correlation_lag(r);
        let mut meat = DMatrix::<f64>::zeros(np, np);
        for block in &self.blocks {
            let scores: Vec<nalgebra::DVector<f64>> = block
                .clone()
                .map(|i| jac.row(i).transpose() * r[i])
                .collect();
            for l in 0..=lag.min(scores.len().saturating_sub(1)) {
                let w = if l == 0 {
                    1.0
                } else {
                    1.0 - l as f64 / (lag + 1) as f64
                };
                let mut sum = DMatrix::<f64>::zeros(np, np);
                for i in 0..scores.len() - l {
                    sum += &scores[i] * scores[i + l].transpose();
                }
                meat += if l == 0 {
                    sum * w
                } else {
                    (&sum + sum.transpose()) * w
                };
            }
        }
        let bread = (jac.transpose() * &jac)
            .try_inverse()
            .unwrap_or_else(|| DMatrix::from_element(np, np, f64::NAN));
        let cov = &bread * meat * &bread;
        Ok(DMatrix::from_fn(np, np, |i, j| {
            cov[(i, j)] * fit.scale[i] * fit.scale[j]
        }))
    }

    /// The first lag at which the residual's autocorrelation (pooled over the records) falls
    /// below its white-noise band `2 / sqrt(N)`; at most a tenth of the shortest record.
    fn correlation_lag(&self, r: &[f64]) -> usize {
        let shortest = self
            .blocks
            .iter()
            .map(ExactSizeIterator::len)
            .min()
            .unwrap_or(0);
        let variance: f64 = r.iter().map(|v| v * v).sum();
        if variance <= 0.0 || shortest < 20 {
            return 0;
        }
        let band = 2.0 / (r.len() as f64).sqrt();
        for l in 1..shortest / 10 {
            let c: f64 = self
                .blocks
                .iter()
                .map(|b| (b.start..b.end - l).map(|i| r[i] * r[i + l]).sum::<f64>())
                .sum();
            if c / variance < band {
                return l;
            }
        }
        shortest / 10
    }

    fn identification(
        &self,
        start: &Identification,
        fit: &lm::Fit,
        cov: &DMatrix<f64>,
    ) -> Identification {
        let np = self.p_element();
        let rms = fit.rms();
        let parameters: Vec<Parameter> = (0..np)
            .map(|i| Parameter {
                name: start.parameters[i].name.clone(),
                value: fit.p[i],
                std: cov[(i, i)].sqrt(),
            })
            .collect();
        let covariance = (0..np)
            .map(|i| (0..np).map(|j| cov[(i, j)]).collect())
            .collect();
        let mut warnings = start.warnings.clone();
        warnings.push(format!(
            "output error: the mass simulated under the measured force of {} record(s), each from its fitted initial state; {} samples, RMS misfit {rms:.3} displacement noise std",
            self.records.len(),
            fit.residual.len()
        ));
        if rms * rms > 2.0 {
            warnings.push(format!(
                "output error: the simulated model misses the measured displacement by {rms:.1} noise std (RMS); the model's form may not describe these data (try diagnose)"
            ));
        }
        let info = fit.information.clone();
        let sub = info.view((0, 0), (np, np)).into_owned();
        let sv = sub.singular_values();
        Identification {
            model: self.model.name.clone(),
            method: Method::OutputError.name(),
            parameters,
            covariance,
            condition_number: (sv.max() / sv.min()).sqrt(),
            equations: fit.residual.len(),
            r: start.r.clone(),
            residual_rms: rms,
            steps_used: self.records.iter().map(|r| r.step).collect(),
            fit_quality: None,
            warnings,
        }
    }

    /// The displacement of `record` (not among the fitted ones) predicted by simulation with
    /// the element parameters `element` (theta, then the mass when fitted), from the initial
    /// state that fits it best with those parameters held.
    pub fn predict(
        model: &Model,
        moving_mass_kg: Option<f64>,
        element: &[f64],
        record: &Record,
    ) -> Result<Vec<f64>, IdentifyError> {
        let problem = ForcedRecordsOutputError::new(model, moving_mass_kg, &[record])?;
        let s = problem.start_states[0];
        let mut full = element.to_vec();
        full.extend([s.displacement_m, s.velocity_mps]);
        let np = problem.p_element();
        let states = Partial {
            inner: &problem,
            full: full.clone(),
            free: vec![np, np + 1],
        };
        let fit = lm::levenberg_marquardt_within(&states, full[np..].to_vec(), FROM_TIME_DOMAIN)?;
        problem.simulate(
            0,
            element,
            ForcedInitial {
                displacement_m: fit.p[0],
                velocity_mps: fit.p[1],
            },
        )
    }
}

impl Problem for ForcedRecordsOutputError<'_> {
    fn residual(&self, p: &[f64]) -> Result<Vec<f64>, IdentifyError> {
        let np = self.p_element();
        let n = self.blocks.last().map_or(0, |b| b.end);
        let mut out = Vec::with_capacity(n);
        for (k, r) in self.records.iter().enumerate() {
            let j = self.state_index(k);
            let initial = ForcedInitial {
                displacement_m: p[j],
                velocity_mps: p[j + 1],
            };
            let measured = r.channel(Channel::RelativeDisplacementM).unwrap_or(&[]);
            match self.simulate(k, &p[..np], initial) {
                Ok(x) => out.extend(
                    measured
                        .iter()
                        .zip(&x)
                        .map(|(m, s)| (m - s) / self.sigma_m[k]),
                ),
                Err(_) => return Ok(vec![FAILED_TRIAL_RESIDUAL; n]),
            }
        }
        Ok(out)
    }

    /// Each record's initial displacement moves its own rows only, so one simulation gives
    /// the finite differences of every record's; the same for the velocities.
    fn column_groups(&self, np: usize) -> Vec<Vec<usize>> {
        let pe = self.p_element();
        let mut groups: Vec<Vec<usize>> = (0..pe.min(np)).map(|j| vec![j]).collect();
        groups.push((pe..np).step_by(2).collect());
        groups.push((pe + 1..np).step_by(2).collect());
        groups.retain(|g| !g.is_empty());
        groups
    }

    fn rows(&self, j: usize, n: usize) -> Range<usize> {
        let pe = self.p_element();
        if j < pe {
            0..n
        } else {
            self.blocks[(j - pe) / 2].clone()
        }
    }

    fn scale(&self, p: &[f64]) -> Vec<f64> {
        let pe = self.p_element();
        p.iter()
            .enumerate()
            .map(|(j, v)| {
                if j < pe {
                    if v.abs() > 0.0 { v.abs() } else { 1.0 }
                } else {
                    let [xs, vs] = self.state_scale[(j - pe) / 2];
                    if (j - pe).is_multiple_of(2) { xs } else { vs }
                }
            })
            .collect()
    }
}
