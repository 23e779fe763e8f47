//! The element test bench: the element alone between an actuator and a load cell, with a
//! moving mass m between them (a fixture, or the mass of a force-driven single-DOF system).
//!
//! - Displacement-driven (damper dyno, mount or bushing tester): the program prescribes the
//!   displacement x(t); the load cell measures `F = m x'' + g(x, x', z)`, with the element's
//!   internal states z (Bouc-Wen) integrated along the prescribed motion by RK4. Friction
//!   slips wherever x' != 0, so it is its slip law of x'.
//! - Force-driven (a shaker on a single-DOF system): the program prescribes F(t) and
//!   `m x'' = F - g(x, x', z)`, with exact stick-slip (the hybrid integrator of `hybrid.rs`).
//!
//! Records hold [`ELEMENT_CHANNELS`]: x, F and the moving mass's acceleration x''.

use serde::{Deserialize, Serialize};

use std::sync::Arc;

use super::excitation::{CubicSpline, Derivs, Piece, PiecewiseSignal, Program, SplineEnds};
use super::hybrid::{Hybrid, Integrator, Mode, RunStats, SolverOptions};
use super::rig_records::split_records;
use super::{SampleTrace, SimError, SimOutput, is_positive};
use crate::element::{Element, Friction};
use crate::record::Channel;

/// Channels of an element-test record, in this order.
pub const ELEMENT_CHANNELS: [Channel; 3] = [
    Channel::RelativeDisplacementM,
    Channel::ForceN,
    Channel::MassAccelerationMps2,
];

/// What the actuator of an element test controls.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ElementDrive {
    /// The program is the displacement [m] (damper dynos, mount testers).
    Displacement,
    /// The program is the force [N] on the moving mass (a single-DOF system on a shaker).
    Force,
}

/// `m x'' = F(t) - g(x, x', z) - friction`.
struct ForcedMass<'a> {
    element: &'a dyn Element,
    friction: Option<Friction>,
    mass_kg: f64,
    force: PiecewiseSignal,
    nz: usize,
}

impl ForcedMass<'_> {
    /// Acceleration and friction force in `mode`.
    fn accel(&self, f: &Derivs, y: &[f64], mode: Mode) -> (f64, f64) {
        let (x, v) = (y[0], y[1]);
        let z = &y[2..2 + self.nz];
        match mode {
            Mode::Stick => (0.0, f.value - self.element.smooth_force(x, 0.0, z)),
            Mode::Free => (
                (f.value - self.element.smooth_force(x, v, z)) / self.mass_kg,
                0.0,
            ),
            Mode::Slip(d) => {
                let fr = self
                    .friction
                    .as_ref()
                    .expect("slip needs friction")
                    .slip_force_toward_n(v, d);
                (
                    (f.value - self.element.smooth_force(x, v, z) - fr) / self.mass_kg,
                    fr,
                )
            }
        }
    }
}

impl Hybrid for ForcedMass<'_> {
    fn dim(&self) -> usize {
        2 + self.nz
    }

    fn friction(&self) -> Option<Friction> {
        self.friction
    }

    fn vel_index(&self) -> usize {
        1
    }

    fn rhs(&self, t: f64, t_ref: f64, y: &[f64], mode: Mode, dy: &mut [f64]) {
        let f = self.force.eval(t, t_ref);
        let (a, _) = self.accel(&f, y, mode);
        let v = if mode == Mode::Stick { 0.0 } else { y[1] };
        dy[0] = v;
        dy[1] = a;
        if self.nz > 0 {
            self.element
                .internal_rates(y[0], v, &y[2..2 + self.nz], &mut dy[2..2 + self.nz]);
        }
    }

    fn needed_friction(&self, t: f64, t_ref: f64, y: &[f64]) -> f64 {
        let f = self.force.eval(t, t_ref);
        f.value - self.element.smooth_force(y[0], 0.0, &y[2..2 + self.nz])
    }
    // A force step moves no state: no jump conditions.
}

/// Simulates an element test under `program` (displacement in m or force in N, as `drive`
/// says) with `element` behind a moving mass of `mass_kg` (zero allowed for a displacement
/// drive: a load cell at the fixed end). One record per program record, channels
/// [`ELEMENT_CHANNELS`], the run starting at rest.
pub fn simulate_element(
    element: &dyn Element,
    mass_kg: f64,
    drive: ElementDrive,
    program: &Program,
    solver: &SolverOptions,
) -> Result<SimOutput, SimError> {
    let fs = program.sample_rate_hz;
    if !is_positive(fs) || !is_positive(solver.max_substep_s) || !mass_kg.is_finite() {
        return Err(SimError::InvalidSpec(
            "sample rate and sub-step must be positive, the mass finite".into(),
        ));
    }
    let samples = program.total_samples();
    let (out, trace, stats) = match drive {
        ElementDrive::Force => {
            if !is_positive(mass_kg) {
                return Err(SimError::InvalidSpec(
                    "a force-driven element test needs a positive moving mass".into(),
                ));
            }
            run_forced(
                element,
                mass_kg,
                program.signal.clone(),
                program.sample_rate_hz,
                samples,
                ForcedInitial::default(),
                solver,
            )?
        }
        ElementDrive::Displacement => {
            if mass_kg < 0.0 {
                return Err(SimError::InvalidSpec(
                    "the moving mass must not be negative".into(),
                ));
            }
            run_displaced(element, mass_kg, program, solver, samples)
        }
    };
    Ok(split_records(
        program,
        &ELEMENT_CHANNELS,
        &out,
        trace,
        &stats,
    ))
}

type RunOut = (Vec<[f64; 3]>, Vec<SampleTrace>, RunStats);

/// The state a force-driven mass starts from.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ForcedInitial {
    pub displacement_m: f64,
    pub velocity_mps: f64,
    /// The element's first internal state (a fitted element's Bouc-Wen z [m],
    /// `diagnose::fitted_element`); any others start at zero.
    pub first_internal_state: f64,
}

/// Response of a force-driven element test at its samples.
#[derive(Debug, Clone, PartialEq)]
pub struct ForcedResponse {
    pub displacement_m: Vec<f64>,
    pub acceleration_mps2: Vec<f64>,
    pub trace: Vec<SampleTrace>,
}

/// Simulates the moving mass of a force-driven element test under a sampled force (a cubic
/// spline through the samples, not-a-knot ends) from `initial`, with exact stick-slip: how a
/// model is fitted to, and predicts, records of any force (random, multisine, road profiles)
/// that start in motion.
pub fn simulate_on_sampled_force(
    element: &dyn Element,
    mass_kg: f64,
    force_n: &[f64],
    sample_rate_hz: f64,
    initial: ForcedInitial,
    solver: &SolverOptions,
) -> Result<ForcedResponse, SimError> {
    if force_n.len() < 2 || !is_positive(sample_rate_hz) || !is_positive(mass_kg) {
        return Err(SimError::InvalidSpec(
            "a sampled force drive needs two samples, a positive rate and a positive moving mass"
                .into(),
        ));
    }
    let spline = CubicSpline::new(force_n, 0.0, sample_rate_hz, SplineEnds::NotAKnot);
    let mut signal = PiecewiseSignal::new(force_n[0]);
    signal.push(0.0, Piece::Spline(Arc::new(spline)));
    let (out, trace, _) = run_forced(
        element,
        mass_kg,
        signal,
        sample_rate_hz,
        force_n.len(),
        initial,
        solver,
    )?;
    Ok(ForcedResponse {
        displacement_m: out.iter().map(|s| s[0]).collect(),
        acceleration_mps2: out.iter().map(|s| s[2]).collect(),
        trace,
    })
}

fn run_forced(
    element: &dyn Element,
    mass_kg: f64,
    force: PiecewiseSignal,
    sample_rate_hz: f64,
    samples: usize,
    initial: ForcedInitial,
    solver: &SolverOptions,
) -> Result<RunOut, SimError> {
    let nz = element.internal_states();
    let sys = ForcedMass {
        element,
        friction: element.friction(),
        mass_kg,
        force,
        nz,
    };
    let mut y = vec![0.0; sys.dim()];
    y[0] = initial.displacement_m;
    y[1] = initial.velocity_mps;
    if nz > 0 {
        y[2] = initial.first_internal_state;
    }
    let breaks = sys.force.breakpoints();
    let mut out = vec![[0.0; 3]; samples];
    let mut trace = vec![SampleTrace::default(); samples];
    let mut integ = Integrator::new(&sys, *solver);
    let stats = integ.run(
        &mut y,
        samples,
        sample_rate_hz,
        &breaks,
        |i, t, t_ref, y, mode| {
            let f = sys.force.eval(t, t_ref);
            let (a, fr) = sys.accel(&f, y, mode);
            out[i] = [y[0], f.value, a];
            trace[i] = SampleTrace {
                relative_velocity_mps: y[1],
                stuck: mode == Mode::Stick,
                friction_force_n: fr,
            };
        },
    )?;
    Ok((out, trace, stats))
}

/// The element's force at a prescribed state (friction: its slip law, zero at x' = 0).
fn element_force(element: &dyn Element, x: f64, v: f64, z: &[f64]) -> (f64, f64) {
    let fr = match element.friction() {
        Some(f) if v != 0.0 => f.slip_force_n(v),
        _ => 0.0,
    };
    (element.smooth_force(x, v, z) + fr, fr)
}

fn run_displaced(
    element: &dyn Element,
    mass_kg: f64,
    program: &Program,
    solver: &SolverOptions,
    samples: usize,
) -> RunOut {
    let fs = program.sample_rate_hz;
    let signal = &program.signal;
    let nz = element.internal_states();
    let mut z = vec![0.0; nz];
    let mut out = vec![[0.0; 3]; samples];
    let mut trace = vec![SampleTrace::default(); samples];
    let stats = RunStats {
        stick_time_s: vec![0.0; samples],
        events: vec![0; samples],
    };
    // RK4 of the internal states along the prescribed motion, evaluated on the piece that
    // holds over each sample interval (its midpoint), as the hybrid integrator does.
    let rates = |t: f64, t_ref: f64, z: &[f64], dz: &mut [f64]| {
        let d = signal.eval(t, t_ref);
        element.internal_rates(d.value, d.d1, z, dz);
    };
    let mut k = [vec![0.0; nz], vec![0.0; nz], vec![0.0; nz], vec![0.0; nz]];
    let mut tmp = vec![0.0; nz];
    for i in 0..samples {
        let t = i as f64 / fs;
        let t_ref = t + 0.5 / fs;
        let d = signal.eval(t, t_ref);
        let (g, fr) = element_force(element, d.value, d.d1, &z);
        out[i] = [d.value, mass_kg * d.d2 + g, d.d2];
        trace[i] = SampleTrace {
            relative_velocity_mps: d.d1,
            stuck: false,
            friction_force_n: fr,
        };
        if nz == 0 || i + 1 == samples {
            continue;
        }
        let n = ((1.0 / fs) / solver.max_substep_s).ceil().max(1.0) as usize;
        let h = 1.0 / fs / n as f64;
        for s in 0..n {
            let a = t + s as f64 * h;
            rates(a, t_ref, &z, &mut k[0]);
            for j in 0..nz {
                tmp[j] = z[j] + 0.5 * h * k[0][j];
            }
            rates(a + 0.5 * h, t_ref, &tmp, &mut k[1]);
            for j in 0..nz {
                tmp[j] = z[j] + 0.5 * h * k[1][j];
            }
            rates(a + 0.5 * h, t_ref, &tmp, &mut k[2]);
            for j in 0..nz {
                tmp[j] = z[j] + h * k[2][j];
            }
            rates(a + h, t_ref, &tmp, &mut k[3]);
            for j in 0..nz {
                z[j] += h / 6.0 * (k[0][j] + 2.0 * k[1][j] + 2.0 * k[2][j] + k[3][j]);
            }
        }
    }
    (out, trace, stats)
}

#[cfg(test)]
mod tests {
    use std::f64::consts::TAU;

    use super::*;
    use crate::sim::excitation::StepSpec;
    use crate::sim::truth::TruthElement;

    fn linear(k: f64, c: f64) -> TruthElement {
        TruthElement {
            stiffness_n_per_m: k,
            damping_n_s_per_m: c,
            ..TruthElement::default()
        }
    }

    /// Displacement drive: the force is m x'' + k x + c x' of the prescribed sine, exactly.
    #[test]
    fn displacement_drive_gives_the_closed_form_force() {
        let (m, k, c, a, f_hz, fs) = (2.0, 5.0e4, 300.0, 0.01, 3.0, 1000.0);
        let program = Program::from_steps(
            &[StepSpec::Sine {
                frequency_hz: f_hz,
                amplitude: a,
            }],
            fs,
            2000,
            0,
        );
        let out = simulate_element(
            &linear(k, c),
            m,
            ElementDrive::Displacement,
            &program,
            &SolverOptions::default(),
        )
        .unwrap();
        let r = &out.records[0];
        let w = TAU * f_hz;
        let force = r.channel(Channel::ForceN).unwrap();
        for (i, f) in force.iter().enumerate() {
            let t = i as f64 / fs;
            let x = a * (w * t).sin();
            let v = a * w * (w * t).cos();
            let expected = -m * w * w * x + k * x + c * v;
            assert!(
                (f - expected).abs() < 1e-9 * k * a,
                "sample {i}: {f} vs {expected}"
            );
        }
    }

    /// Force drive of a linear single-DOF system: after the transient the displacement is the
    /// closed-form steady state F / (k - m w^2 + j c w).
    #[test]
    fn force_drive_settles_to_the_receptance() {
        let (m, k, c, f0, f_hz, fs) = (1.5, 4.0e4, 60.0, 100.0, 12.0, 2000.0);
        let program = Program::from_steps(
            &[StepSpec::Sine {
                frequency_hz: f_hz,
                amplitude: f0,
            }],
            fs,
            20_000,
            0,
        );
        let out = simulate_element(
            &linear(k, c),
            m,
            ElementDrive::Force,
            &program,
            &SolverOptions::default(),
        )
        .unwrap();
        let r = &out.records[0];
        let w = TAU * f_hz;
        let h = num_complex::Complex64::new(k - m * w * w, c * w).inv() * f0;
        let x = r.channel(Channel::RelativeDisplacementM).unwrap();
        // The free response decays as exp(-c t / 2m): e^-200 after 10 s; check the last second.
        for (i, xi) in x.iter().enumerate().skip(18_000) {
            let t = i as f64 / fs;
            // F = f0 sin(w t) = Im(f0 e^{jwt}), so x = Im(H f0 e^{jwt}).
            let expected = (h * num_complex::Complex64::from_polar(1.0, w * t)).im;
            assert!(
                (xi - expected).abs() < 1e-6 * h.norm(),
                "sample {i}: {xi} vs {expected}"
            );
        }
        // Newton: the recorded acceleration is (F - k x - c v) / m.
        let f = r.channel(Channel::ForceN).unwrap();
        let acc = r.channel(Channel::MassAccelerationMps2).unwrap();
        let t = 19_000.0 / fs;
        let v = (h
            * num_complex::Complex64::new(0.0, w)
            * num_complex::Complex64::from_polar(1.0, w * t))
        .im;
        let expected = (f[19_000] - k * x[19_000] - c * v) / m;
        assert!((acc[19_000] - expected).abs() < 1e-5 * f0 / m);
    }

    /// Force drive below the breakaway force: the mass never moves (exact stick).
    #[test]
    fn force_drive_below_breakaway_sticks() {
        let element = TruthElement {
            stiffness_n_per_m: 1.0e4,
            friction: Some(Friction::coulomb(50.0)),
            ..TruthElement::default()
        };
        let program = Program::from_steps(
            &[StepSpec::Sine {
                frequency_hz: 5.0,
                amplitude: 40.0,
            }],
            1000.0,
            1000,
            0,
        );
        let out = simulate_element(
            &element,
            1.0,
            ElementDrive::Force,
            &program,
            &SolverOptions::default(),
        )
        .unwrap();
        let x = out.records[0]
            .channel(Channel::RelativeDisplacementM)
            .unwrap();
        assert!(x.iter().all(|v| *v == 0.0));
        assert!(out.traces[0].samples.iter().all(|s| s.stuck));
    }
}
