//! One period of a step's element state and force, rebuilt from its harmonics: what a
//! force-state map plots.

use std::f64::consts::TAU;

use num_complex::Complex64;

use super::{IdentifyError, Setup, element_harmonics};
use crate::phasor::HarmonicAnalysis;

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

fn synthesize(c: &[Complex64], points: usize, derivative_omega: Option<f64>) -> Vec<f64> {
    (0..points)
        .map(|i| {
            let th = TAU * i as f64 / points as f64;
            c.iter()
                .enumerate()
                .map(|(n, cn)| {
                    let d = derivative_omega.map_or(Complex64::new(1.0, 0.0), |w| {
                        Complex64::new(0.0, n as f64 * w)
                    });
                    (cn * d * Complex64::from_polar(1.0, n as f64 * th)).re
                })
                .sum()
        })
        .collect()
}

/// Rebuilds `points` samples of one period of the step's relative displacement, velocity and
/// element force (all measured harmonics).
pub fn rebuilt_cycle(
    setup: &Setup,
    an: &HarmonicAnalysis,
    points: usize,
) -> Result<Cycle, IdentifyError> {
    let eh = element_harmonics(setup, an, false)?;
    Ok(Cycle {
        step: an.step,
        frequency_hz: an.frequency_hz,
        displacement_m: synthesize(&eh.displacement, points, None),
        velocity_mps: synthesize(&eh.displacement, points, Some(eh.omega_rad_s)),
        force_n: synthesize(&eh.force, points, None),
    })
}
