//! Event-driven fixed-step RK4 for systems with one set-valued (Coulomb-type) friction.
//!
//! Three modes: `Free` (no friction), `Slip(dir)` and `Stick`. In `Slip(dir)` the friction is
//! the slip law with its direction frozen to `dir` (a smooth continuation across v = 0, so a
//! single RK4 step is a smooth function of its length and the zero crossing of the relative
//! velocity can be located by re-integrating the sub-step with bisection). In `Stick` the
//! system supplies dynamics that keep the relative velocity exactly zero (it is a state set to
//! 0.0 and its rate is 0.0), and the friction needed for that; the stick ends when the needed
//! friction leaves `[-B_-, B_+]`, again located by bisection on the sub-step length.
//! Events are located to `event_tolerance_s` (default 1e-12 s).

mod node_loop;
mod nodes;

use serde::{Deserialize, Serialize};

use super::SimError;
use super::exact_step::{ExactStep, slip_holds};
use super::linear_step::{Linear2, LinearSteps};
use crate::element::Friction;

/// Integration settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SolverOptions {
    /// Largest RK4 sub-step [s]; each sample interval is split into equal sub-steps no
    /// longer than this.
    pub max_substep_s: f64,
    /// Width of the bracket that locates a stick/slip event [s].
    pub event_tolerance_s: f64,
    /// Safety limit on events inside one sub-step (chattering guard).
    pub max_events_per_substep: usize,
}

impl Default for SolverOptions {
    fn default() -> Self {
        SolverOptions {
            max_substep_s: 1e-4,
            event_tolerance_s: 1e-12,
            max_events_per_substep: 64,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Mode {
    Free,
    Slip(f64),
    Stick,
}

/// Largest needed friction the stick holds in direction `dir`: `breakaway_n`, or the slip
/// level at zero speed if that is larger (asymmetric friction), so that a slip never starts
/// against its own friction.
pub(crate) fn stick_limit(fr: &Friction, dir: f64) -> f64 {
    fr.breakaway_n.max(fr.slip_force_toward_n(0.0, dir).abs())
}

pub(crate) trait Hybrid {
    fn dim(&self) -> usize;
    fn friction(&self) -> Option<Friction>;
    /// Index of the relative velocity across the friction element in the state.
    fn vel_index(&self) -> usize;
    /// State rates at `t`, inputs from the piece that holds at `t_ref`.
    fn rhs(&self, t: f64, t_ref: f64, y: &[f64], mode: Mode, dy: &mut [f64]);
    /// The inputs at `t` (the middle and the end of an RK4 step, asked by [`Hybrid::rhs`] in
    /// that order next) are about to be needed: a system may compute both in one pass, and
    /// must give them to the bit as [`Hybrid::rhs`] alone would.
    fn inputs_ahead(&self, _t: [f64; 2], _t_ref: f64) {}
    /// Friction force needed to keep the relative velocity zero (y has v = 0).
    fn needed_friction(&self, t: f64, t_ref: f64, y: &[f64]) -> f64;
    /// Jump conditions at an input breakpoint `t` (left limit to right limit).
    fn jump(&self, _t: f64, _y: &mut [f64]) {}
    /// `Some` when, in `mode`, the state is only (x, v) with `x' = v, v' = -a x - b v + u(t)`
    /// and `u` from [`Hybrid::forcing`]: full sub-steps are then taken as a linear map.
    fn linear(&self, _mode: Mode) -> Option<Linear2> {
        None
    }
    /// `u(t)` of [`Hybrid::linear`] in `mode`, inputs from the piece that holds at `t_ref`.
    fn forcing(&self, _t: f64, _t_ref: f64, _mode: Mode) -> f64 {
        0.0
    }
    /// [`Hybrid::forcing`] at two times.
    fn forcing_pair(&self, t: [f64; 2], t_ref: f64, mode: Mode) -> [f64; 2] {
        [
            self.forcing(t[0], t_ref, mode),
            self.forcing(t[1], t_ref, mode),
        ]
    }
    /// True when the inputs at `t_ref` and at `other` come from the same pieces (a forcing
    /// evaluated with one holds for the other).
    fn same_inputs(&self, _t_ref: f64, _other: f64) -> bool {
        false
    }
    /// True when [`Hybrid::forcing`] with inputs from the piece at `t_ref` is affine in time
    /// (a spline's second derivative): an interval of [`Hybrid::linear`] dynamics then has an
    /// exact step (`exact_step.rs`).
    fn forcing_affine(&self, _t_ref: f64) -> bool {
        false
    }
    /// True when no state moves while stuck (every rate is exactly zero), so that a stuck
    /// sub-step leaves the state as it is.
    fn static_when_stuck(&self) -> bool {
        false
    }
}

/// The last forcing evaluated at the end of a linear sub-step: (t, t_ref, mode, u).
type LastForcing = (f64, f64, Mode, f64);

/// Per-run statistics of the event-driven integration.
#[derive(Debug, Clone, Default)]
pub(crate) struct RunStats {
    /// Time spent stuck inside each sample interval `[t_i, t_i+1)`.
    pub stick_time_s: Vec<f64>,
    pub events: Vec<usize>,
}

pub(crate) struct Integrator<'a, H: Hybrid> {
    sys: &'a H,
    opts: SolverOptions,
    k: [Vec<f64>; 4],
    tmp: Vec<f64>,
    trial: Vec<f64>,
    /// Sub-step length of the current node interval (`run` sets it).
    substep_s: f64,
    /// The linear steps of the system for the sub-step lengths met.
    linear_steps: LinearSteps,
    /// Its forcing at the end of the last linear sub-step (the start of the next one).
    last_forcing: Option<LastForcing>,
    /// The exact step for (interval length, system) last used.
    exact_step: Option<(f64, Linear2, ExactStep)>,
}

impl<'a, H: Hybrid> Integrator<'a, H> {
    pub fn new(sys: &'a H, opts: SolverOptions) -> Self {
        let n = sys.dim();
        Integrator {
            sys,
            opts,
            k: [vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]],
            tmp: vec![0.0; n],
            trial: vec![0.0; n],
            substep_s: opts.max_substep_s,
            linear_steps: LinearSteps::default(),
            last_forcing: None,
            exact_step: None,
        }
    }

    /// A full sub-step of length `dt` (about `substep_s`) from `y` into `out`: the linear map
    /// when the system is linear in `mode`, else [`Integrator::rk4`].
    fn full_step(&mut self, t: f64, t_ref: f64, y: &[f64], dt: f64, mode: Mode, out: &mut [f64]) {
        let Some(lin) = self.sys.linear(mode) else {
            self.rk4(t, t_ref, y, dt, mode, out);
            return;
        };
        [out[0], out[1]] = self.linear_substep(lin, t, t_ref, [y[0], y[1]], dt, mode, false);
    }

    /// [`Integrator::full_step`] of a system linear in `mode` (`lin`). Inlined: as a call of
    /// its own (arrays through memory) the 100 Hz paper run took 8 % more CPU.
    #[inline(always)]
    #[allow(
        clippy::too_many_arguments,
        reason = "the sub-step's state, passed through"
    )]
    fn linear_substep(
        &mut self,
        lin: Linear2,
        t: f64,
        t_ref: f64,
        y: [f64; 2],
        dt: f64,
        mode: Mode,
        same_piece: bool,
    ) -> [f64; 2] {
        let u0 = match self.last_forcing {
            Some((tt, tr, m, u))
                if tt == t
                    && m == mode
                    && (same_piece || tr == t_ref || self.sys.same_inputs(t_ref, tr)) =>
            {
                u
            }
            _ => self.sys.forcing(t, t_ref, mode),
        };
        let t1 = t + dt;
        let [uh, u1] = self.sys.forcing_pair([t + 0.5 * dt, t1], t_ref, mode);
        self.last_forcing = Some((t1, t_ref, mode, u1));
        // The step by reference (a copy of its 16 numbers per sub-step was 5 % of a 10 kHz run).
        self.linear_steps
            .get(lin, self.substep_s)
            .apply(y, u0, uh, u1)
    }

    /// A sample interval of one sub-step, free or slipping without reaching zero velocity,
    /// taken as [`Integrator::advance`] takes it (the same operations, so the same state to the
    /// bit) without its loop and copies: at 10 kHz every interval is one sub-step. `None`
    /// (nothing changed) when the system is not linear in `mode` or a slip ends inside: then
    /// `advance` takes it. `same_piece`: the last sub-step's inputs are known to come from the
    /// pieces at `t_ref` (no breakpoint since), so [`Hybrid::same_inputs`] is not asked.
    #[inline(always)]
    fn one_linear_substep(
        &mut self,
        t0: f64,
        t1: f64,
        t_ref: f64,
        y: &[f64],
        mode: Mode,
        same_piece: bool,
    ) -> Option<[f64; 2]> {
        let dt = t1 - t0;
        if dt <= 0.0 || mode == Mode::Stick || self.sys.vel_index() != 1 {
            return None;
        }
        let lin = self.sys.linear(mode)?;
        let before = self.last_forcing;
        let next = self.linear_substep(lin, t0, t_ref, [y[0], y[1]], dt, mode, same_piece);
        match mode {
            Mode::Slip(dir) if dir * next[1] <= 0.0 || next[1].is_nan() => {
                self.last_forcing = before;
                None
            }
            _ => Some(next),
        }
    }

    /// The state at `t1` from `y` at `t0` in one exact step, when the system is linear in
    /// `mode`, its forcing affine over the interval and no stick-slip event can happen inside
    /// (free, or a slip whose velocity keeps its sign with a margin: see [`slip_holds`]);
    /// `None` otherwise, and the interval is sub-stepped.
    fn exact_interval(
        &mut self,
        t0: f64,
        t1: f64,
        t_ref: f64,
        y: &[f64],
        mode: Mode,
    ) -> Option<[f64; 2]> {
        if mode == Mode::Stick || !self.sys.forcing_affine(t_ref) {
            return None;
        }
        let lin = self.sys.linear(mode)?;
        let h = t1 - t0;
        let step = match self.exact_step {
            Some((hh, l, s)) if hh == h && l == lin => s,
            _ => {
                let s = ExactStep::new(lin, h);
                self.exact_step = Some((h, lin, s));
                s
            }
        };
        let u = self.sys.forcing_pair([t0, t1], t_ref, mode);
        let y0 = [y[0], y[1]];
        let y1 = step.apply(y0, u[0], u[1]);
        match mode {
            Mode::Slip(dir) if !slip_holds(lin, h, dir, y0, y1, u) => None,
            _ => Some(y1),
        }
    }

    /// One classic RK4 step of length `dt` from `y` into `out`.
    fn rk4(&mut self, t: f64, t_ref: f64, y: &[f64], dt: f64, mode: Mode, out: &mut [f64]) {
        let n = y.len();
        // Slices of the state's length: the loops without bounds checks.
        let [k1, k2, k3, k4] = &mut self.k;
        let (k1, k2, k3, k4) = (&mut k1[..n], &mut k2[..n], &mut k3[..n], &mut k4[..n]);
        let (tmp, out) = (&mut self.tmp[..n], &mut out[..n]);
        self.sys.rhs(t, t_ref, y, mode, k1);
        self.sys.inputs_ahead([t + 0.5 * dt, t + dt], t_ref);
        for i in 0..n {
            tmp[i] = y[i] + 0.5 * dt * k1[i];
        }
        self.sys.rhs(t + 0.5 * dt, t_ref, tmp, mode, k2);
        for i in 0..n {
            tmp[i] = y[i] + 0.5 * dt * k2[i];
        }
        self.sys.rhs(t + 0.5 * dt, t_ref, tmp, mode, k3);
        for i in 0..n {
            tmp[i] = y[i] + dt * k3[i];
        }
        self.sys.rhs(t + dt, t_ref, tmp, mode, k4);
        for i in 0..n {
            out[i] = y[i] + dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
    }

    /// Mode at zero relative velocity: stick if the needed friction is within the limits,
    /// otherwise slip in the direction of the needed friction.
    pub fn decide_at_rest(&self, t: f64, t_ref: f64, y: &[f64]) -> Mode {
        let Some(fr) = self.sys.friction() else {
            return Mode::Free;
        };
        let f = self.sys.needed_friction(t, t_ref, y);
        if f > stick_limit(&fr, 1.0) {
            Mode::Slip(1.0)
        } else if f < -stick_limit(&fr, -1.0) {
            Mode::Slip(-1.0)
        } else {
            Mode::Stick
        }
    }

    /// The mode consistent with the state (at the start and after input breakpoints).
    pub fn consistent(&self, t: f64, t_ref: f64, y: &[f64], mode: Mode) -> Mode {
        if self.sys.friction().is_none() {
            return Mode::Free;
        }
        let v = y[self.sys.vel_index()];
        match mode {
            Mode::Slip(d) if v * d > 0.0 => Mode::Slip(d),
            _ if v != 0.0 => Mode::Slip(v.signum()),
            _ => self.decide_at_rest(t, t_ref, y),
        }
    }

    fn stick_violated(&self, t: f64, t_ref: f64, y: &[f64], fr: &Friction) -> Option<f64> {
        let f = self.sys.needed_friction(t, t_ref, y);
        if f > stick_limit(fr, 1.0) {
            Some(1.0)
        } else if f < -stick_limit(fr, -1.0) {
            Some(-1.0)
        } else {
            None
        }
    }

    /// Advances `y` from `t0` to `t1` (no input breakpoint inside) handling stick/slip
    /// events. Returns (time spent stuck, number of events).
    pub fn advance(
        &mut self,
        t0: f64,
        t1: f64,
        t_ref: f64,
        y: &mut [f64],
        mode: &mut Mode,
    ) -> Result<(f64, usize), SimError> {
        let vi = self.sys.vel_index();
        let mut t = t0;
        let mut stuck = 0.0;
        let mut events = 0;
        let mut trial = std::mem::take(&mut self.trial);
        let result = loop {
            let dt = t1 - t;
            if dt <= 0.0 {
                break Ok(());
            }
            if events > self.opts.max_events_per_substep {
                break Err(SimError::Chattering { time_s: t });
            }
            match *mode {
                Mode::Free => {
                    self.full_step(t, t_ref, y, dt, *mode, &mut trial);
                    y.copy_from_slice(&trial);
                    break Ok(());
                }
                Mode::Slip(dir) => {
                    if t == t0 {
                        self.full_step(t, t_ref, y, dt, *mode, &mut trial);
                    } else {
                        self.rk4(t, t_ref, y, dt, *mode, &mut trial);
                    }
                    if dir * trial[vi] > 0.0 {
                        y.copy_from_slice(&trial);
                        break Ok(());
                    }
                    // The relative velocity reaches zero inside: bisect on the step length.
                    let (mut lo, mut hi) = (0.0, dt);
                    while hi - lo > self.opts.event_tolerance_s {
                        let mid = 0.5 * (lo + hi);
                        self.rk4(t, t_ref, y, mid, *mode, &mut trial);
                        if dir * trial[vi] > 0.0 {
                            lo = mid;
                        } else {
                            hi = mid;
                        }
                    }
                    self.rk4(t, t_ref, y, hi, *mode, &mut trial);
                    y.copy_from_slice(&trial);
                    y[vi] = 0.0;
                    t += hi;
                    events += 1;
                    *mode = self.decide_at_rest(t, t_ref, y);
                }
                Mode::Stick => {
                    let fr = self.sys.friction().expect("stick mode needs friction");
                    if self.sys.static_when_stuck() {
                        trial.copy_from_slice(y);
                    } else {
                        self.rk4(t, t_ref, y, dt, *mode, &mut trial);
                    }
                    if self.stick_violated(t1, t_ref, &trial, &fr).is_none() {
                        y.copy_from_slice(&trial);
                        stuck += dt;
                        break Ok(());
                    }
                    let (mut lo, mut hi) = (0.0, dt);
                    while hi - lo > self.opts.event_tolerance_s {
                        let mid = 0.5 * (lo + hi);
                        self.rk4(t, t_ref, y, mid, *mode, &mut trial);
                        if self.stick_violated(t + mid, t_ref, &trial, &fr).is_none() {
                            lo = mid;
                        } else {
                            hi = mid;
                        }
                    }
                    self.rk4(t, t_ref, y, hi, *mode, &mut trial);
                    y.copy_from_slice(&trial);
                    stuck += hi;
                    t += hi;
                    events += 1;
                    let dir = self.stick_violated(t, t_ref, y, &fr).unwrap_or(1.0);
                    *mode = Mode::Slip(dir);
                }
            }
        };
        self.trial = trial;
        result.map(|()| (stuck, events))
    }
}
