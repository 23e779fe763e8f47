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

/// A harmonic counts when it stands this many noise standard deviations above its noise.
const SIGNIFICANT: f64 = 3.0;

/// Rebuilds `points` samples of one period of the step's relative displacement, velocity and
/// element force from their harmonics that stand out of the noise (the fundamental always;
/// a higher harmonic when its amplitude exceeds three times its noise std): the noise's own
/// harmonics would otherwise scatter the period, most of all the velocity's, where harmonic n
/// is weighted by n.
pub fn rebuilt_cycle(
    setup: &Setup,
    an: &HarmonicAnalysis,
    points: usize,
) -> Result<Cycle, IdentifyError> {
    let eh = element_harmonics(setup, an, false)?;
    let significant = |c: &[Complex64], noise: &[f64]| -> Vec<Complex64> {
        c.iter()
            .enumerate()
            .map(|(n, cn)| {
                let keep = n <= 1 || cn.norm() > SIGNIFICANT * noise.get(n).copied().unwrap_or(0.0);
                if keep { *cn } else { Complex64::new(0.0, 0.0) }
            })
            .collect()
    };
    let displacement = significant(&eh.displacement, &eh.displacement_noise);
    let force = significant(&eh.force, &eh.force_noise);
    // The velocity from the displacement's significant harmonics.
    let velocity: Vec<Complex64> = eh
        .velocity
        .iter()
        .zip(&displacement)
        .map(|(v, x)| {
            if x.norm() > 0.0 {
                *v
            } else {
                Complex64::new(0.0, 0.0)
            }
        })
        .collect();
    let one = Complex64::new(1.0, 0.0);
    // a grid of `points` holds harmonics up to points / 2
    let points = points.max(2 * eh.harmonics() + 2).next_power_of_two();
    Ok(Cycle {
        step: an.step,
        frequency_hz: an.frequency_hz,
        displacement_m: synthesize_grid(&displacement, points, |_| one),
        velocity_mps: synthesize_grid(&velocity, points, |_| one),
        force_n: synthesize_grid(&force, points, |_| one),
    })
}
