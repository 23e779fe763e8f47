//! The paper's 3-DOF example (METHOD.md section 3):
//! ground -(k11, c11)- m1 -(k12, c12)- m2 -[element]- m3 -(k33, c33)- ground,
//! force f(t) on m2, element displacement x = x2 - x3.
//!
//! States: x1, v1, x2, v2, x = x2 - x3, v = v2 - v3, element internal states. While stuck,
//! m2 and m3 move together (v = 0 exactly, x constant) and the friction needed follows from
//! the force balance of the two masses with equal accelerations:
//! `f_r = (m3 F2 - m2 F3) / (m2 + m3) - g_smooth(x, 0)`, with F2 and F3 the other forces
//! on m2 and m3.

use serde::{Deserialize, Serialize};

use super::excitation::Program;
use super::hybrid::{Hybrid, Integrator, Mode, SolverOptions};
use super::rig_records::split_records;
use super::{SampleTrace, SimError, SimOutput, is_positive};
use crate::element::{Element, Friction};
use crate::record::Channel;

/// Channels of a 3-DOF record, in this order.
pub const THREE_DOF_CHANNELS: [Channel; 3] = [
    Channel::RelativeDisplacementM,
    Channel::DrivePointDisplacementM,
    Channel::ForceN,
];

/// Linear part of the 3-DOF example.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ThreeDofParams {
    pub m1_kg: f64,
    pub m2_kg: f64,
    pub m3_kg: f64,
    pub k11_n_per_m: f64,
    pub k12_n_per_m: f64,
    pub k33_n_per_m: f64,
    pub c11_n_s_per_m: f64,
    pub c12_n_s_per_m: f64,
    pub c33_n_s_per_m: f64,
}

impl ThreeDofParams {
    /// The paper's values: m1 3, m2 = m3 2 kg; k11 = k12 6000, k33 10000 N/m;
    /// c11 = c12 6, c33 10 N s/m.
    pub fn paper() -> ThreeDofParams {
        ThreeDofParams {
            m1_kg: 3.0,
            m2_kg: 2.0,
            m3_kg: 2.0,
            k11_n_per_m: 6000.0,
            k12_n_per_m: 6000.0,
            k33_n_per_m: 10000.0,
            c11_n_s_per_m: 6.0,
            c12_n_s_per_m: 6.0,
            c33_n_s_per_m: 10.0,
        }
    }
}

impl Default for ThreeDofParams {
    fn default() -> Self {
        ThreeDofParams::paper()
    }
}

struct ThreeDofSystem<'a> {
    p: ThreeDofParams,
    element: &'a dyn Element,
    friction: Option<Friction>,
    force: &'a Program,
    nz: usize,
}

impl ThreeDofSystem<'_> {
    /// Forces on m1, on m2 (without the element) and on m3 (without the element).
    fn forces(&self, t: f64, t_ref: f64, y: &[f64]) -> (f64, f64, f64) {
        let p = &self.p;
        let (x1, v1, x2, v2, x, v) = (y[0], y[1], y[2], y[3], y[4], y[5]);
        let (x3, v3) = (x2 - x, v2 - v);
        let f = self.force.signal.eval(t, t_ref).value;
        let f12 = p.k12_n_per_m * (x2 - x1) + p.c12_n_s_per_m * (v2 - v1);
        let f1 = -p.k11_n_per_m * x1 - p.c11_n_s_per_m * v1 + f12;
        let f2 = f - f12;
        let f3 = -p.k33_n_per_m * x3 - p.c33_n_s_per_m * v3;
        (f1, f2, f3)
    }

    /// Accelerations of m1, m2, m3 and the friction force in `mode`.
    fn accels(&self, t: f64, t_ref: f64, y: &[f64], mode: Mode) -> ([f64; 3], f64) {
        let p = &self.p;
        let (f1, f2, f3) = self.forces(t, t_ref, y);
        let a1 = f1 / p.m1_kg;
        let z = &y[6..6 + self.nz];
        match mode {
            Mode::Stick => {
                let a = (f2 + f3) / (p.m2_kg + p.m3_kg);
                let fr = (p.m3_kg * f2 - p.m2_kg * f3) / (p.m2_kg + p.m3_kg)
                    - self.element.smooth_force(y[4], 0.0, z);
                ([a1, a, a], fr)
            }
            Mode::Free | Mode::Slip(_) => {
                let fr = match (mode, self.friction.as_ref()) {
                    (Mode::Slip(d), Some(fr)) => fr.slip_force_toward_n(y[5], d),
                    _ => 0.0,
                };
                let g = self.element.smooth_force(y[4], y[5], z) + fr;
                ([a1, (f2 - g) / p.m2_kg, (f3 + g) / p.m3_kg], fr)
            }
        }
    }
}

impl Hybrid for ThreeDofSystem<'_> {
    fn dim(&self) -> usize {
        6 + self.nz
    }

    fn friction(&self) -> Option<Friction> {
        self.friction
    }

    fn vel_index(&self) -> usize {
        5
    }

    fn rhs(&self, t: f64, t_ref: f64, y: &[f64], mode: Mode, dy: &mut [f64]) {
        let ([a1, a2, a3], _) = self.accels(t, t_ref, y, mode);
        let v = if mode == Mode::Stick { 0.0 } else { y[5] };
        dy[0] = y[1];
        dy[1] = a1;
        dy[2] = y[3];
        dy[3] = a2;
        dy[4] = v;
        dy[5] = if mode == Mode::Stick { 0.0 } else { a2 - a3 };
        if self.nz > 0 {
            self.element
                .internal_rates(y[4], v, &y[6..6 + self.nz], &mut dy[6..6 + self.nz]);
        }
    }

    fn needed_friction(&self, t: f64, t_ref: f64, y: &[f64]) -> f64 {
        self.accels(t, t_ref, y, Mode::Stick).1
    }
}

/// Simulates the 3-DOF example under a force program on m2 (starting at rest). One `Record`
/// per program record with channels `THREE_DOF_CHANNELS`; state carried over between records.
pub fn simulate_three_dof(
    params: &ThreeDofParams,
    element: &dyn Element,
    force: &Program,
    solver: &SolverOptions,
) -> Result<SimOutput, SimError> {
    if !is_positive(force.sample_rate_hz) || !is_positive(solver.max_substep_s) {
        return Err(SimError::InvalidSpec(
            "sample rate and sub-step must be positive".into(),
        ));
    }
    let nz = element.internal_states();
    let sys = ThreeDofSystem {
        p: *params,
        element,
        friction: element.friction(),
        force,
        nz,
    };
    let n = force.total_samples();
    let mut y = vec![0.0; sys.dim()];
    let mut out = vec![[0.0; 3]; n];
    let mut trace = vec![SampleTrace::default(); n];
    let breaks = force.signal.breakpoints();
    let mut integ = Integrator::new(&sys, *solver);
    let stats = integ.run(
        &mut y,
        n,
        force.sample_rate_hz,
        &breaks,
        |i, t, t_ref, y, mode| {
            out[i] = [y[4], y[2], force.signal.eval(t, t_ref).value];
            trace[i] = SampleTrace {
                relative_velocity_mps: y[5],
                stuck: mode == Mode::Stick,
                friction_force_n: sys.accels(t, t_ref, y, mode).1,
            };
        },
    )?;
    Ok(split_records(
        force,
        &THREE_DOF_CHANNELS,
        &out,
        trace,
        &stats,
    ))
}
