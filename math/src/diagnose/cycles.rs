//! One period of each settled sine step (element state and force, rebuilt from the harmonics),
//! the channel transformations of the candidate effects (the Bouc-Wen state over a cycle is
//! [`crate::signal::bouc_wen::steady_cycle`]).

use std::sync::{Arc, Mutex};

use num_complex::Complex64;

use super::sensor::{self, SensorFilter};
use crate::identify::{IdentifyError, element_harmonics};
use crate::phasor::HarmonicAnalysis;
use crate::recipe::Setup;
use crate::signal::bouc_wen::{self, HysteresisLaw};

/// One period of a settled sine step on a uniform grid.
#[derive(Debug, Clone)]
pub struct StepCycle {
    pub step: usize,
    pub frequency_hz: f64,
    /// Middle of the averaged periods [s since the start of the run] (the drift candidate's
    /// time of the step).
    pub time_s: f64,
    /// First-harmonic amplitude of the relative displacement [m].
    pub amplitude_m: f64,
    pub displacement_m: Vec<f64>,
    pub velocity_mps: Vec<f64>,
    /// Element force from the measurements [N].
    pub force_n: Vec<f64>,
    /// Noise of the rebuilt force per grid point [N] (from the per-harmonic noise), floored at
    /// 1e-4 of the force RMS so noise-free data are not weighted by round-off.
    pub force_noise_n: f64,
    /// Harmonics in the rebuilt force.
    pub harmonics: usize,
    /// With sensor dynamics undone on the state: per harmonic n = 0..=harmonics, the factor
    /// the measured force went through ([`sensor::force_response`]). The state (displacement,
    /// velocity) is the element's, the force is as measured, so a model force is passed
    /// through the same factors before it is compared (`fit::columns`). Comparing in the
    /// measured domain keeps the noise white: undoing the filter on the force instead would
    /// amplify the n-th harmonic's noise by 1 / |H(j n w)| and make the error of different
    /// members incomparable.
    pub force_response: Option<Vec<Complex64>>,
    /// Noise of each force harmonic n = 0..=harmonics [N] (complex magnitude).
    pub force_harmonic_noise_n: Vec<f64>,
    /// The element (nearly) did not move: relative displacement amplitude below
    /// [`STUCK_FRACTION`] of the largest step's (set by `search::cycles_for`). Its force is a
    /// stick force, set-valued, that no model of the state describes; fits and scores leave
    /// the step out for every model alike.
    pub stuck: bool,
    /// The Bouc-Wen states already integrated over this cycle's velocity, by law.
    pub hysteresis_states: HysteresisStates,
}

/// Bouc-Wen states over one cycle, remembered by law: the search asks for the same law's state
/// on the same cycle many times (the yield search, its shapes, the pairs, the final fits), and
/// each is three periods of RK4. An entry is used only for the exact velocity and period it was
/// integrated over, so a cycle whose velocity is changed after cloning cannot be given a stale
/// state; a clone starts empty.
#[derive(Debug, Default)]
pub struct HysteresisStates(Mutex<Vec<HysteresisEntry>>);

#[derive(Debug)]
struct HysteresisEntry {
    law: HysteresisLaw,
    period_s: f64,
    velocity_mps: Vec<f64>,
    state_m: Arc<Vec<f64>>,
}

impl Clone for HysteresisStates {
    fn clone(&self) -> Self {
        HysteresisStates::default()
    }
}

impl HysteresisStates {
    /// [`bouc_wen::steady_cycle`] of `law` over `velocity_mps` and `period_s`, integrated once.
    pub fn steady_cycle(
        &self,
        velocity_mps: &[f64],
        period_s: f64,
        law: &HysteresisLaw,
    ) -> Arc<Vec<f64>> {
        let same = |e: &HysteresisEntry| {
            e.law == *law
                && e.period_s.to_bits() == period_s.to_bits()
                && e.velocity_mps.len() == velocity_mps.len()
                && e.velocity_mps
                    .iter()
                    .zip(velocity_mps)
                    .all(|(a, b)| a.to_bits() == b.to_bits())
        };
        if let Some(e) = self.lock().iter().find(|e| same(e)) {
            return e.state_m.clone();
        }
        let state_m = Arc::new(bouc_wen::steady_cycle(velocity_mps, period_s, law));
        self.lock().push(HysteresisEntry {
            law: *law,
            period_s,
            velocity_mps: velocity_mps.to_vec(),
            state_m: state_m.clone(),
        });
        state_m
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Vec<HysteresisEntry>> {
        // A panic while the list was held leaves it valid (entries are pushed whole).
        self.0
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

/// Steps whose relative displacement amplitude is below this fraction of the largest step's
/// count as stuck (see [`StepCycle::stuck`]).
pub const STUCK_FRACTION: f64 = 0.05;

/// Grid points per period.
pub const CYCLE_POINTS: usize = 256;

/// Values over one period on `l` points of the signal with one-sided phasors `c`, each scaled
/// by `scale(n)`.
pub fn synthesize(c: &[Complex64], l: usize, scale: impl Fn(usize) -> Complex64) -> Vec<f64> {
    let mut buf = vec![Complex64::new(0.0, 0.0); l];
    for (n, cn) in c.iter().enumerate().take(l / 2) {
        buf[n] = cn * scale(n);
    }
    crate::signal::fft::inverse(l).process(&mut buf);
    buf.iter().map(|b| b.re).collect()
}

/// One-sided harmonics 0..=n of a periodic signal sampled on a uniform grid over one period.
pub fn harmonics_of(h: &[f64], n: usize) -> Vec<Complex64> {
    let l = h.len();
    let mut buf: Vec<Complex64> = h.iter().map(|v| Complex64::new(*v, 0.0)).collect();
    crate::signal::fft::forward(l).process(&mut buf);
    (0..=n.min(l / 2 - 1))
        .map(|k| buf[k] * if k == 0 { 1.0 } else { 2.0 } / l as f64)
        .collect()
}

/// Highest harmonic that stands out of its noise (3 sigma); above it a rebuilt velocity would
/// carry noise amplified by n w and no information.
fn significant(c: &[Complex64], noise: &[f64]) -> usize {
    (1..c.len())
        .rev()
        .find(|&n| c[n].norm() > 3.0 * noise[n])
        .unwrap_or(1)
}

/// The step's cycle; `sensor` undoes sensor dynamics on the state (see
/// [`StepCycle::force_response`]), `mass_factor` scales the element force (true mass = nominal
/// * factor).
pub fn step_cycle(
    setup: &Setup,
    an: &HarmonicAnalysis,
    sensor: Option<&SensorFilter>,
    mass_factor: f64,
) -> Result<StepCycle, IdentifyError> {
    // The force as measured; the state as the element saw it (the filter undone).
    let eh = element_harmonics(setup, an, false)?;
    let unfiltered_state;
    let state = match sensor {
        Some(f) => {
            unfiltered_state = element_harmonics(setup, &sensor::unfiltered(an, f), false)?;
            &unfiltered_state
        }
        None => &eh,
    };
    let force_response = sensor
        .map(|f| sensor::force_response(setup, an, f))
        .transpose()?;
    let nh = eh.harmonics();
    let l = CYCLE_POINTS.max(4 * (nh + 1)).next_power_of_two();
    let nx = significant(&state.displacement, &state.displacement_noise);
    let w = eh.omega_rad_s;
    let one = |_| Complex64::new(1.0, 0.0);
    let x = synthesize(&state.displacement[..=nx], l, one);
    let v = synthesize(&state.displacement[..=nx], l, |n| {
        Complex64::new(0.0, n as f64 * w)
    });
    let g: Vec<f64> = synthesize(&eh.force, l, one)
        .into_iter()
        .map(|g| g * mass_factor)
        .collect();
    let noise = mass_factor
        * (eh.force_noise[0].powi(2)
            + eh.force_noise[1..].iter().map(|s| s * s / 2.0).sum::<f64>())
        .sqrt();
    let g_rms = (g.iter().map(|v| v * v).sum::<f64>() / l as f64).sqrt();
    Ok(StepCycle {
        step: an.step,
        frequency_hz: an.frequency_hz,
        time_s: an.t_ref_s + 0.5 * an.periods_used as f64 / an.frequency_hz,
        amplitude_m: state.displacement.get(1).map_or(0.0, |c| c.norm()),
        displacement_m: x,
        velocity_mps: v,
        force_n: g,
        force_noise_n: if noise.is_finite() {
            noise.max(1e-4 * g_rms)
        } else {
            g_rms
        },
        harmonics: nh,
        force_response,
        force_harmonic_noise_n: eh.force_noise.iter().map(|s| s * mass_factor).collect(),
        stuck: false,
        hysteresis_states: HysteresisStates::default(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn synthesis_and_harmonics_are_inverse() {
        let c = vec![
            Complex64::new(0.2, 0.0),
            Complex64::new(1.0, -0.5),
            Complex64::new(0.0, 0.1),
        ];
        let s = synthesize(&c, 64, |_| Complex64::new(1.0, 0.0));
        let h = harmonics_of(&s, 3);
        for n in 0..3 {
            assert!((h[n] - c[n]).norm() < 1e-12);
        }
        assert!(h[3].norm() < 1e-12);
    }

    #[test]
    fn remembered_hysteresis_states_are_those_of_their_own_velocity_and_law() {
        let l = 64;
        let period_s = 0.5;
        let v: Vec<f64> = (0..l)
            .map(|i| -0.05 * (std::f64::consts::TAU * i as f64 / l as f64).sin())
            .collect();
        let law = HysteresisLaw::yield_law(0.001);
        let states = HysteresisStates::default();
        let first = states.steady_cycle(&v, period_s, &law);
        assert_eq!(*first, bouc_wen::steady_cycle(&v, period_s, &law));
        assert!(Arc::ptr_eq(
            &first,
            &states.steady_cycle(&v, period_s, &law)
        ));
        // Another law, period or velocity is integrated afresh, not taken from the list.
        let other_law = HysteresisLaw::yield_law(0.002);
        assert_eq!(
            *states.steady_cycle(&v, period_s, &other_law),
            bouc_wen::steady_cycle(&v, period_s, &other_law)
        );
        assert_eq!(
            *states.steady_cycle(&v, 0.25, &law),
            bouc_wen::steady_cycle(&v, 0.25, &law)
        );
        let w: Vec<f64> = v.iter().map(|x| 2.0 * x).collect();
        assert_eq!(
            *states.steady_cycle(&w, period_s, &law),
            bouc_wen::steady_cycle(&w, period_s, &law)
        );
        assert_ne!(*states.steady_cycle(&w, period_s, &law), *first);
        // A clone starts empty: a cycle copied and then changed cannot inherit stale states.
        assert!(states.clone().lock().is_empty());
    }
}
