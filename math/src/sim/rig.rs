//! The base-excited suspension rig (METHOD.md section 4): a mass on the element, base
//! displacement prescribed. With `x = x_o - x_i`, `m x_o'' = -g(x, x')`.
//!
//! States: relative displacement x, relative velocity v, the element's internal states and,
//! with a sensor low-pass, one filter state per measured channel. Stick-slip is exact (see
//! `hybrid.rs`): while stuck v is exactly 0 and the mass moves with the base.

mod base_input;
mod replay;

pub use replay::{ReplayOptions, RigResponse, simulate_on_sampled_base};

use std::cell::{Cell, RefCell};
use std::f64::consts::PI;

use serde::{Deserialize, Serialize};

use super::excitation::{Piece, PiecewiseSignal, Program};
use super::hybrid::{Hybrid, Integrator, Mode, RunStats, SolverOptions};
use super::input_window::{InputWindow, SplineInterval};
use super::linear_step::Linear2;
use super::{SampleTrace, SimError, SimOutput, is_positive};
use crate::element::{Element, Friction};
use crate::record::Channel;
pub use crate::signal::lowpass::ZeroPhaseLowpass;

/// The rig's mass [kg] (known in the paper).
pub const PAPER_RIG_MASS_KG: f64 = 36.0;

/// Channels of a rig record, in this order.
pub const RIG_CHANNELS: [Channel; 5] = [
    Channel::BaseDisplacementM,
    Channel::RelativeDisplacementM,
    Channel::MassAccelerationMps2,
    Channel::MassDisplacementM,
    Channel::BaseAccelerationMps2,
];

/// Planted rig-level effects (the "sim-to-real gap" a model of the rig may miss).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct RigEffects {
    /// Exciter delay [s]: the element sees the base motion delayed by this much relative to
    /// the measured base channels (base displacement and base acceleration are the measured
    /// exciter signal; relative displacement, mass displacement and mass acceleration are
    /// the physical ones).
    pub exciter_delay_s: f64,
    /// Cutoff [Hz] of a first-order low-pass `y' = 2 pi fc (u - y)` on every measured
    /// channel (None: no filter). Simulated exactly as extra ODE states integrated with the
    /// mechanics (same RK4 sub-steps and events), starting from the rest values.
    pub sensor_lowpass_hz: Option<f64>,
    /// True mass / nominal mass.
    pub mass_factor: f64,
}

impl Default for RigEffects {
    fn default() -> Self {
        RigEffects {
            exciter_delay_s: 0.0,
            sensor_lowpass_hz: None,
            mass_factor: 1.0,
        }
    }
}

/// Initial state of a rig run (default: rest, x = 0 and mass velocity 0).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct RigInitial {
    pub relative_displacement_m: f64,
    pub mass_velocity_mps: f64,
    /// The element's first internal state (a fitted element's Bouc-Wen z [m],
    /// `diagnose::fitted_element`); any others start at zero.
    #[serde(default)]
    pub first_internal_state: f64,
}

pub(crate) struct RigSystem<'a> {
    element: &'a dyn Element,
    friction: Option<Friction>,
    mass_kg: f64,
    base_true: PiecewiseSignal,
    base_meas: PiecewiseSignal,
    nz: usize,
    omega_c: Option<f64>,
    /// The element's `k / m` and `c / m` when it is linear (see `Element::linear_coefficients`;
    /// divided once, not at every sub-step).
    linear: Option<Linear2>,
    /// Taylor windows of the true base acceleration and displacement (sine-like pieces).
    windows: RefCell<[Option<InputWindow>; 2]>,
    /// (start, end, index) of the piece of the true base that held at the last `t_ref`
    /// (start and end in the undelayed time of the signal).
    piece: Cell<(f64, f64, usize)>,
    /// (piece, time, value) of the last true base acceleration taken from a Taylor window:
    /// the sample's channels ask again for the value the sub-step ending there computed, and
    /// the same window gives it again to the bit, so it is not evaluated twice.
    last_d2: Cell<Option<(usize, f64, f64)>>,
    /// The same for the true base displacement: the sub-step ending at a sample computes it
    /// for the sample's channels in the pass of its acceleration pair, when its window covers
    /// that time already.
    last_value: Cell<Option<(usize, f64, f64)>>,
    /// (piece, time, reference time, value) of the true base acceleration at the end of the
    /// RK4 step under way, computed with its middle ([`Hybrid::inputs_ahead`]) and taken by its
    /// last stage.
    ahead: Cell<Option<(usize, f64, f64, f64)>>,
    /// (piece, time, reference time, value) of the last true base acceleration taken from a
    /// spline: an RK4 sub-step asks twice at its middle and its end is the next one's start,
    /// so half of a replay's evaluations are the one before.
    last_spline_d2: Cell<Option<(usize, f64, f64, f64)>>,
    /// (piece, reference time in the signal's time, interval) of the last spline interval
    /// looked up: a sample interval's sub-steps all ask for the same one.
    spline_interval: Cell<Option<(usize, f64, Option<SplineInterval>)>>,
    /// The run's sample rate: the displacement is computed beside a pair only at a sample's
    /// time (`i / sample_rate_hz`), where the channels will ask for it.
    sample_rate_hz: f64,
    /// [`RigSystem::friction_per_kg`] slipping in direction -1 and 1.
    slip_per_kg: [f64; 2],
}

impl RigSystem<'_> {
    /// The constant part of the forcing of `Hybrid::linear`: minus the slip friction (of
    /// constant level there) per kg.
    fn friction_per_kg(&self, mode: Mode) -> f64 {
        // Slips are in direction 1 or -1: their values once per run, with the same operations.
        match mode {
            Mode::Slip(1.0) => return self.slip_per_kg[1],
            Mode::Slip(-1.0) => return self.slip_per_kg[0],
            _ => {}
        }
        self.friction_per_kg_of(mode)
    }

    /// [`RigSystem::friction_per_kg`], computed.
    fn friction_per_kg_of(&self, mode: Mode) -> f64 {
        let fr = match (mode, &self.friction) {
            (Mode::Slip(d), Some(fr)) => fr.slip_force_toward_n(0.0, d),
            _ => 0.0,
        };
        -fr / self.mass_kg
    }

    /// Relative acceleration x'' and friction force in `mode`, with base acceleration `b_d2`.
    #[inline(always)]
    fn accel(&self, b_d2: f64, y: &[f64], mode: Mode) -> (f64, f64) {
        let (x, v) = (y[0], y[1]);
        let z = &y[2..2 + self.nz];
        match mode {
            Mode::Stick => (
                0.0,
                -self.mass_kg * b_d2 - self.element.smooth_force(x, 0.0, z),
            ),
            Mode::Free => (
                -self.element.smooth_force(x, v, z) / self.mass_kg - b_d2,
                0.0,
            ),
            Mode::Slip(d) => {
                let fr = self
                    .friction
                    .as_ref()
                    .expect("slip needs friction")
                    .slip_force_toward_n(v, d);
                (
                    -(self.element.smooth_force(x, v, z) + fr) / self.mass_kg - b_d2,
                    fr,
                )
            }
        }
    }

    /// Unfiltered channel values in `RIG_CHANNELS` order and the friction force.
    // Inlined, as `accel`, `base_true_d2_pair` and `forcing_pair`: at 10 kHz each is called
    // once per sample, and the calls' arguments and results through memory cost as much as
    // their arithmetic.
    #[inline(always)]
    fn channels(&self, t: f64, t_ref: f64, y: &[f64], mode: Mode) -> ([f64; 5], f64) {
        // The lookups of `base_true_window` first, with one piece index for both: at a sample
        // both values are those its sub-step computed (at 10 kHz, nearly every sample).
        let j = self.base_true_index(t_ref);
        let remembered = |last: &Cell<Option<(usize, f64, f64)>>| match last.get() {
            Some((lj, lt, v)) if lj == j && lt == t => Some(v),
            _ => None,
        };
        let b_d2 = remembered(&self.last_d2).unwrap_or_else(|| self.base_true_d2(t, t_ref));
        let b_value =
            remembered(&self.last_value).unwrap_or_else(|| self.base_true_window(0, t, t_ref));
        // Without an exciter delay the measured base is the true one.
        let (m_value, m_d2) = if self.base_true.shift == self.base_meas.shift {
            (b_value, b_d2)
        } else {
            let m = self.base_meas.eval(t, t_ref);
            (m.value, m.d2)
        };
        let (a, fr) = self.accel(b_d2, y, mode);
        ([m_value, y[0], a + b_d2, y[0] + b_value, m_d2], fr)
    }
}

impl Hybrid for RigSystem<'_> {
    fn dim(&self) -> usize {
        2 + self.nz + if self.omega_c.is_some() { 5 } else { 0 }
    }

    fn friction(&self) -> Option<Friction> {
        self.friction
    }

    fn vel_index(&self) -> usize {
        1
    }

    fn rhs(&self, t: f64, t_ref: f64, y: &[f64], mode: Mode, dy: &mut [f64]) {
        let b_d2 = self.base_true_d2(t, t_ref);
        let (a, _) = self.accel(b_d2, y, mode);
        let v = if mode == Mode::Stick { 0.0 } else { y[1] };
        dy[0] = v;
        dy[1] = a;
        let nz = self.nz;
        if nz > 0 {
            self.element
                .internal_rates(y[0], v, &y[2..2 + nz], &mut dy[2..2 + nz]);
        }
        if let Some(wc) = self.omega_c {
            let b = self.base_true_at(t, t_ref);
            let m = self.base_meas.eval(t, t_ref);
            let u = [m.value, y[0], a + b_d2, y[0] + b.value, m.d2];
            for j in 0..5 {
                dy[2 + nz + j] = wc * (u[j] - y[2 + nz + j]);
            }
        }
    }

    fn inputs_ahead(&self, t: [f64; 2], t_ref: f64) {
        // Both as `base_true_window` would give each in turn, when neither is the one it
        // remembers: from the spline's interval, or from the window when it covers both.
        if t[0] == t[1] {
            return;
        }
        let j = self.base_true_index(t_ref);
        let sig = &self.base_true;
        let tl = [t[0] - sig.shift, t[1] - sig.shift];
        let v = match &sig.pieces[j] {
            Piece::Spline(s) => {
                if matches!(self.last_spline_d2.get(),
                    Some((lj, lt, lr, _)) if (lj, lr) == (j, t_ref) && t.contains(&lt))
                {
                    return;
                }
                let tr = t_ref - sig.shift;
                let v = [
                    self.spline_d2(j, s, tl[0], tr),
                    self.spline_d2(j, s, tl[1], tr),
                ];
                self.last_spline_d2.set(Some((j, t[0], t_ref, v[0])));
                v
            }
            piece => {
                if matches!(self.last_d2.get(), Some((lj, lt, _)) if lj == j && t.contains(&lt)) {
                    return;
                }
                let windows = self.windows.borrow();
                let Some(v) = InputWindow::eval_pair_covered(&windows[0], 2, j, piece, tl) else {
                    return;
                };
                self.last_d2.set(Some((j, t[0], v[0])));
                v
            }
        };
        self.ahead.set(Some((j, t[1], t_ref, v[1])));
    }

    fn needed_friction(&self, t: f64, t_ref: f64, y: &[f64]) -> f64 {
        -self.mass_kg * self.base_true_d2(t, t_ref)
            - self.element.smooth_force(y[0], 0.0, &y[2..2 + self.nz])
    }

    fn linear(&self, mode: Mode) -> Option<Linear2> {
        if self.nz > 0 || self.omega_c.is_some() {
            return None;
        }
        let lin = self.linear?;
        let constant_friction = match (mode, &self.friction) {
            (Mode::Free, _) => true,
            // Without a Stribeck excess the slip force is the constant level of `dir`.
            (Mode::Slip(_), Some(fr)) => fr.breakaway_n <= fr.kinetic_n,
            _ => false,
        };
        constant_friction.then_some(lin)
    }

    fn forcing(&self, t: f64, t_ref: f64, mode: Mode) -> f64 {
        self.friction_per_kg(mode) - self.base_true_d2(t, t_ref)
    }

    #[inline(always)]
    fn forcing_pair(&self, t: [f64; 2], t_ref: f64, mode: Mode) -> [f64; 2] {
        let f = self.friction_per_kg(mode);
        let [a, b] = self.base_true_d2_pair(t, t_ref);
        [f - a, f - b]
    }

    fn forcing_affine(&self, t_ref: f64) -> bool {
        // A spline piece's second derivative is linear in time on the interval of `t_ref`.
        let j = self.base_true_index(t_ref);
        matches!(self.base_true.pieces[j], Piece::Spline(_))
    }

    fn same_inputs(&self, t_ref: f64, other: f64) -> bool {
        // The true base alone drives the forcing.
        self.base_true_index(t_ref) == self.base_true_index(other)
    }

    fn static_when_stuck(&self) -> bool {
        self.nz == 0 && self.omega_c.is_none()
    }

    fn jump(&self, t: f64, y: &mut [f64]) {
        // The mass position and velocity are continuous; the base may jump.
        let (l, r) = (self.base_true.eval_left(t), self.base_true.eval_right(t));
        y[0] += l.value - r.value;
        y[1] += l.d1 - r.d1;
    }
}

/// Core of the rig simulators: returns the samples of every channel over the whole run
/// (raw or filtered) and the per-sample trace.
pub(crate) struct RigSetup<'a> {
    element: &'a dyn Element,
    mass_kg: f64,
    base_meas: PiecewiseSignal,
    delay_s: f64,
    lowpass_hz: Option<f64>,
    filters_start: FiltersStart,
    samples: usize,
    sample_rate_hz: f64,
    init: RigInitial,
}

/// Where the sensor low-pass filters start.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum FiltersStart {
    /// At rest on the values before the start (mass and base at rest): a run of the simulator.
    AtRest,
    /// On each channel's value at the start: a replay of a record cut from a longer run.
    OnFirstValues,
}

type RigRunOut = (Vec<[f64; 5]>, Vec<SampleTrace>, RunStats);

fn run_rig(setup: RigSetup<'_>, solver: &SolverOptions) -> Result<RigRunOut, SimError> {
    let samples = setup.samples;
    let mut out = vec![[0.0; 5]; samples];
    let mut trace = vec![SampleTrace::default(); samples];
    let mut stats = RunStats {
        stick_time_s: vec![0.0; samples],
        events: vec![0; samples],
    };
    run_rig_streamed(
        setup,
        solver,
        |i, channels, t| {
            out[i] = channels;
            trace[i] = t;
            true
        },
        |i, stuck_s, events| {
            stats.stick_time_s[i] += stuck_s;
            stats.events[i] += events;
        },
    )?;
    Ok((out, trace, stats))
}

/// [`run_rig`] sample by sample, in memory independent of the run's length:
/// `on_sample(i, channels, trace)` takes each sample (false stops the run) and
/// `on_substep(i, stuck_s, events)` the statistics of sample interval `i`.
pub(crate) fn run_rig_streamed(
    setup: RigSetup<'_>,
    solver: &SolverOptions,
    mut on_sample: impl FnMut(usize, [f64; 5], SampleTrace) -> bool,
    on_substep: impl FnMut(usize, f64, usize),
) -> Result<(), SimError> {
    let RigSetup {
        element,
        mass_kg,
        base_meas,
        delay_s,
        lowpass_hz,
        filters_start,
        samples,
        sample_rate_hz,
        init,
    } = setup;
    if !is_positive(mass_kg)
        || !is_positive(sample_rate_hz)
        || !is_positive(solver.max_substep_s)
        || delay_s.is_nan()
        || delay_s < 0.0
    {
        return Err(SimError::InvalidSpec(
            "mass, sample rate and sub-step must be positive, delay non-negative".into(),
        ));
    }
    let base_true = base_meas.delayed(delay_s);
    let nz = element.internal_states();
    let sys = RigSystem {
        element,
        friction: element.friction(),
        mass_kg,
        base_true,
        base_meas,
        nz,
        omega_c: lowpass_hz.map(|f| 2.0 * PI * f),
        linear: element.linear_coefficients().map(|(k, c)| Linear2 {
            stiffness_per_kg: k / mass_kg,
            damping_per_kg: c / mass_kg,
        }),
        windows: RefCell::new([None, None]),
        piece: Cell::new((0.0, 0.0, 0)),
        last_d2: Cell::new(None),
        last_value: Cell::new(None),
        ahead: Cell::new(None),
        last_spline_d2: Cell::new(None),
        spline_interval: Cell::new(None),
        sample_rate_hz,
        slip_per_kg: [0.0; 2],
    };
    let sys = RigSystem {
        slip_per_kg: [-1.0, 1.0].map(|d| sys.friction_per_kg_of(Mode::Slip(d))),
        ..sys
    };
    let mut y = vec![0.0; sys.dim()];
    let b0 = sys.base_true.eval_right(0.0);
    y[0] = init.relative_displacement_m;
    y[1] = init.mass_velocity_mps - b0.d1;
    if nz > 0 {
        y[2] = init.first_internal_state;
    }
    if sys.omega_c.is_some() {
        let start = match filters_start {
            FiltersStart::AtRest => {
                let m0 = sys.base_meas.eval_left(0.0);
                let bl = sys.base_true.eval_left(0.0);
                [
                    m0.value,
                    init.relative_displacement_m,
                    0.0,
                    init.relative_displacement_m + bl.value,
                    0.0,
                ]
            }
            FiltersStart::OnFirstValues => {
                let mode = match (sys.friction.is_some(), y[1]) {
                    (false, _) => Mode::Free,
                    (true, 0.0) => Mode::Stick,
                    (true, v) => Mode::Slip(v.signum()),
                };
                sys.channels(0.0, 0.0, &y, mode).0
            }
        };
        y[2 + nz..2 + nz + 5].copy_from_slice(&start);
    }
    let mut breaks = sys.base_meas.breakpoints();
    breaks.extend(sys.base_true.breakpoints());
    let mut integ = Integrator::new(&sys, *solver);
    integ.run_streamed(
        &mut y,
        samples,
        sample_rate_hz,
        &breaks,
        |i, t, t_ref, y, mode| {
            let (channels, friction_force_n) = sys.channels(t, t_ref, y, mode);
            let out = match sys.omega_c {
                Some(_) => {
                    let mut c = [0.0; 5];
                    c.copy_from_slice(&y[2 + nz..2 + nz + 5]);
                    c
                }
                None => channels,
            };
            let trace = SampleTrace {
                relative_velocity_mps: y[1],
                stuck: mode == Mode::Stick,
                friction_force_n,
            };
            on_sample(i, out, trace)
        },
        on_substep,
    )
}

/// Simulates the rig under a base-displacement program (the measured base channel) with
/// `element` on a mass of `nominal_mass_kg * effects.mass_factor`. One `Record` per program
/// record, channels `RIG_CHANNELS`, state carried over from record to record.
pub fn simulate_rig(
    element: &dyn Element,
    nominal_mass_kg: f64,
    program: &Program,
    effects: &RigEffects,
    init: RigInitial,
    solver: &SolverOptions,
) -> Result<SimOutput, SimError> {
    let setup = program_setup(element, nominal_mass_kg, program, effects, init);
    super::rig_records::simulate_rig_records(setup, program, solver)
}

/// The rig of [`simulate_rig`] under `program`.
pub(crate) fn program_setup<'a>(
    element: &'a dyn Element,
    nominal_mass_kg: f64,
    program: &Program,
    effects: &RigEffects,
    init: RigInitial,
) -> RigSetup<'a> {
    RigSetup {
        element,
        mass_kg: nominal_mass_kg * effects.mass_factor,
        base_meas: program.signal.clone(),
        delay_s: effects.exciter_delay_s,
        lowpass_hz: effects.sensor_lowpass_hz,
        filters_start: FiltersStart::AtRest,
        samples: program.total_samples(),
        sample_rate_hz: program.sample_rate_hz,
        init,
    }
}
