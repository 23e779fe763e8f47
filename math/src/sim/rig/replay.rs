//! A rig model driven by a sampled base motion (validation of an identified model on the
//! measured band-random records).

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::super::excitation::{CubicSpline, Piece, PiecewiseSignal, SplineEnds};
use super::super::hybrid::SolverOptions;
use super::super::{SampleTrace, SimError};
use super::{FiltersStart, RigInitial, RigSetup, ZeroPhaseLowpass, run_rig};
use crate::element::Element;
use crate::signal::lowpass::zero_phase_lowpass;

/// Options of [`simulate_on_sampled_base`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ReplayOptions {
    pub spline: SplineEnds,
    pub prefilter: Option<ZeroPhaseLowpass>,
    pub initial: RigInitial,
    pub solver: SolverOptions,
    /// Cutoff [Hz] of a first-order low-pass on every output channel (None: none), integrated
    /// with the mechanics as the simulator's sensor low-pass, each filter starting on its
    /// channel's first value (the record's past, which would have set it, is not known). The
    /// input is the base motion the element sees.
    pub sensor_lowpass_hz: Option<f64>,
}

impl Default for ReplayOptions {
    fn default() -> Self {
        ReplayOptions {
            spline: SplineEnds::NotAKnot,
            prefilter: None,
            initial: RigInitial::default(),
            solver: SolverOptions::default(),
            sensor_lowpass_hz: None,
        }
    }
}

/// Response of a rig model to a sampled base motion, at the samples.
#[derive(Debug, Clone, PartialEq)]
pub struct RigResponse {
    pub mass_acceleration_mps2: Vec<f64>,
    pub relative_displacement_m: Vec<f64>,
    pub mass_displacement_m: Vec<f64>,
    /// The base displacement actually used (after the optional prefilter).
    pub base_displacement_m: Vec<f64>,
    pub trace: Vec<SampleTrace>,
}

/// Simulates ANY element on a mass under a sampled base displacement (how an identified
/// model is validated on measured band-random base motion). The samples are interpolated by
/// a cubic spline (value, velocity and acceleration from the spline), optionally after a
/// zero-phase low-pass. Friction, if any, is treated with the exact stick-slip scheme. The
/// run starts at rest at the first sample (x = 0, mass velocity 0, unless `opts.initial`).
pub fn simulate_on_sampled_base(
    element: &dyn Element,
    mass_kg: f64,
    base_displacement_m: &[f64],
    sample_rate_hz: f64,
    opts: &ReplayOptions,
) -> Result<RigResponse, SimError> {
    if base_displacement_m.len() < 2 {
        return Err(SimError::InvalidSpec(
            "need at least two base samples".into(),
        ));
    }
    let base: Vec<f64> = match opts.prefilter {
        Some(lp) => zero_phase_lowpass(base_displacement_m, sample_rate_hz, lp.cutoff_hz),
        None => base_displacement_m.to_vec(),
    };
    let spline = CubicSpline::new(&base, 0.0, sample_rate_hz, opts.spline);
    let mut signal = PiecewiseSignal::new(base[0]);
    signal.push(0.0, Piece::Spline(Arc::new(spline)));
    let n = base.len();
    let setup = RigSetup {
        element,
        mass_kg,
        base_meas: signal,
        delay_s: 0.0,
        lowpass_hz: opts.sensor_lowpass_hz,
        filters_start: FiltersStart::OnFirstValues,
        samples: n,
        sample_rate_hz,
        init: opts.initial,
    };
    let (out, trace, _) = run_rig(setup, &opts.solver)?;
    Ok(RigResponse {
        mass_acceleration_mps2: out.iter().map(|c| c[2]).collect(),
        relative_displacement_m: out.iter().map(|c| c[1]).collect(),
        mass_displacement_m: out.iter().map(|c| c[3]).collect(),
        base_displacement_m: base,
        trace,
    })
}
