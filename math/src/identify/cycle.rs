//! One period of a step's element state and force, rebuilt from its harmonics: what a
//! force-state map plots.

use num_complex::Complex64;

use super::fd::synthesize_grid;
use super::{IdentifyError, element_harmonics};
use crate::phasor::HarmonicAnalysis;
use crate::recipe::Setup;

/// Samples over one period of a settled step.
#[derive(Debug, Clone)]
pub struct Cycle {
    pub step: usize,
    pub frequency_hz: f64,
    pub displacement_m: Vec<f64>,
    pub velocity_mps: Vec<f64>,
    /// Element force from the measurements [N].
    pub force_n: Vec<f64>,
}

/// Rebuilds `points` samples of one period of the step's relative displacement, velocity and
/// element force (all measured harmonics).
pub fn rebuilt_cycle(
    setup: &Setup,
    an: &HarmonicAnalysis,
    points: usize,
) -> Result<Cycle, IdentifyError> {
    let eh = element_harmonics(setup, an, false)?;
    let one = Complex64::new(1.0, 0.0);
    // a grid of `points` holds harmonics up to points / 2
    let points = points.max(2 * eh.harmonics() + 2).next_power_of_two();
    Ok(Cycle {
        step: an.step,
        frequency_hz: an.frequency_hz,
        displacement_m: synthesize_grid(&eh.displacement, points, |_| one),
        velocity_mps: synthesize_grid(&eh.displacement, points, |n| {
            Complex64::new(0.0, n as f64 * eh.omega_rad_s)
        }),
        force_n: synthesize_grid(&eh.force, points, |_| one),
    })
}
