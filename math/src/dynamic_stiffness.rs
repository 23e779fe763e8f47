//! What element-test users read off a stepped-sine run, per step: the dynamic stiffness
//! K*(f, A) = G_1 / X_1 of the element force's and the displacement's fundamentals (storage
//! K' = Re K*, loss K'' = Im K*, loss angle atan2(K'', K'), as ISO 10846 and the elastomer-mount
//! standards define them), the energy dissipated per cycle (the force-displacement loop's area,
//! from every measured harmonic), and the damper dyno's force at peak velocity (rebound and
//! compression: the force-velocity characteristic, read where the stroke passes mid-travel, so
//! the spring forces at the stroke's ends stay out of it; from every measured harmonic of the
//! force, far from the velocity reversals where a friction jump rings in a band-limited sum).
//!
//! The element force is what the setup says it is: the measured force less the moving mass's
//! inertia on an element test (give an identified mass through [`Setup::with_extra_values`]),
//! the mass's inertia on the base-excited rig, the drive force less the linear substructure's
//! share at a drive point.

use serde::Serialize;

use std::f64::consts::{FRAC_PI_2, PI};

use num_complex::Complex64;

use crate::identify::{ElementHarmonics, IdentifyError, element_harmonics};
use crate::phasor::HarmonicAnalysis;
use crate::recipe::Setup;

/// One step's dynamic stiffness and loop figures.
#[derive(Debug, Clone, Serialize)]
pub struct StiffnessPoint {
    pub step: usize,
    pub frequency_hz: f64,
    /// |X_1|: the displacement amplitude of the fundamental [m].
    pub displacement_amplitude_m: f64,
    /// Storage stiffness K' = Re(G_1 / X_1) [N/m].
    pub storage_stiffness_n_per_m: f64,
    /// Loss stiffness K'' = Im(G_1 / X_1) [N/m].
    pub loss_stiffness_n_per_m: f64,
    /// |K*| [N/m].
    pub dynamic_stiffness_n_per_m: f64,
    /// atan2(K'', K') [deg].
    pub loss_angle_deg: f64,
    /// The loop's area, pi * sum_n n Im(G_n conj(X_n)) over every measured harmonic [J].
    pub dissipated_energy_j: f64,
    /// The fundamental's peak velocity w |X_1| [m/s].
    pub peak_velocity_mps: f64,
    /// Element force at the largest positive velocity (rebound, extension) [N].
    pub rebound_force_at_peak_velocity_n: f64,
    /// Element force at the largest negative velocity (compression) [N].
    pub compression_force_at_peak_velocity_n: f64,
}

/// The state at a peak of the fundamental's velocity: the nominal peak velocity w |X_1| of a
/// sine program (what a dyno's force-velocity curve is drawn against), with the displacement
/// and the element force at that instant from every measured harmonic. The velocity is not
/// read off the rebuilt period: differentiating its noisy higher harmonics (n w X_n) would
/// overstate the peak.
#[derive(Debug, Clone, Copy)]
pub struct PeakVelocityState {
    pub displacement_m: f64,
    pub velocity_mps: f64,
    pub force_n: f64,
}

/// The element harmonics with the moving mass known.
fn element_force_harmonics(
    setup: &Setup,
    analysis: &HarmonicAnalysis,
) -> Result<ElementHarmonics, IdentifyError> {
    let eh = element_harmonics(setup, analysis, false)?;
    if eh.extra_column.is_some() {
        return Err(IdentifyError::Step {
            step: analysis.step,
            problem: "the element force needs the moving mass: give it, or the identified one (Setup::with_extra_values)".into(),
        });
    }
    if eh.displacement.get(1).is_none_or(|x| x.norm() == 0.0) || eh.force.len() < 2 {
        return Err(IdentifyError::Step {
            step: analysis.step,
            problem: "no displacement at the fundamental: the dynamic stiffness is undefined"
                .into(),
        });
    }
    Ok(eh)
}

/// The states at the rebound (largest positive) and compression (largest negative) velocity
/// of the fundamental.
fn peak_states(eh: &ElementHarmonics) -> [PeakVelocityState; 2] {
    let x1 = eh.displacement[1];
    let at = |c: &[Complex64], theta: f64| -> f64 {
        c.iter()
            .enumerate()
            .map(|(n, cn)| (cn * Complex64::from_polar(1.0, n as f64 * theta)).re)
            .sum()
    };
    // v_1 = Re(j w X_1 e^{j theta}) peaks at theta = -(arg X_1 + pi/2).
    let rebound = -(x1.arg() + FRAC_PI_2);
    let v_peak = eh.omega_rad_s * x1.norm();
    [(rebound, v_peak), (rebound + PI, -v_peak)].map(|(theta, v)| PeakVelocityState {
        displacement_m: at(&eh.displacement, theta),
        velocity_mps: v,
        force_n: at(&eh.force, theta),
    })
}

/// The states at the fundamental's velocity peaks (rebound, compression) of one settled sine
/// step.
pub fn peak_velocity_states(
    setup: &Setup,
    analysis: &HarmonicAnalysis,
) -> Result<[PeakVelocityState; 2], IdentifyError> {
    Ok(peak_states(&element_force_harmonics(setup, analysis)?))
}

/// The dynamic stiffness and loop figures of one settled sine step.
pub fn stiffness_point(
    setup: &Setup,
    analysis: &HarmonicAnalysis,
) -> Result<StiffnessPoint, IdentifyError> {
    let eh = element_force_harmonics(setup, analysis)?;
    let (x1, g1) = (eh.displacement[1], eh.force[1]);
    let k = g1 / x1;
    let dissipated_energy_j = PI
        * eh.force
            .iter()
            .zip(&eh.displacement)
            .enumerate()
            .map(|(n, (g, x))| n as f64 * (g * x.conj()).im)
            .sum::<f64>();
    let [rebound, compression] = peak_states(&eh);
    Ok(StiffnessPoint {
        step: analysis.step,
        frequency_hz: analysis.frequency_hz,
        displacement_amplitude_m: x1.norm(),
        storage_stiffness_n_per_m: k.re,
        loss_stiffness_n_per_m: k.im,
        dynamic_stiffness_n_per_m: k.norm(),
        loss_angle_deg: k.im.atan2(k.re).to_degrees(),
        dissipated_energy_j,
        peak_velocity_mps: rebound.velocity_mps,
        rebound_force_at_peak_velocity_n: rebound.force_n,
        compression_force_at_peak_velocity_n: compression.force_n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::element::Friction;
    use crate::phasor::{PhasorOptions, analyse_record};
    use crate::sim::ElementDrive;
    use crate::sim::excitation::sine_steps;
    use crate::sim::run::RunSpec;
    use crate::sim::truth::TruthElement;

    /// A noise-free displacement-driven element test of `element`, one step per frequency.
    fn points(
        element: TruthElement,
        frequencies_hz: &[f64],
        amplitude_m: f64,
    ) -> Vec<StiffnessPoint> {
        let run = RunSpec::element_test(
            ElementDrive::Displacement,
            0.0,
            element,
            sine_steps(frequencies_hz, amplitude_m),
            1000.0,
            4000,
        );
        let records = run.simulate().expect("simulating the element test");
        let setup = Setup::Element {
            moving_mass_kg: Some(0.0),
            drive: None,
        };
        records
            .iter()
            .map(|r| {
                let an = analyse_record(r, &PhasorOptions::for_identification())
                    .expect("analysing the step");
                stiffness_point(&setup, &an).expect("the stiffness point")
            })
            .collect()
    }

    #[test]
    fn a_spring_and_viscous_damper_give_k_and_c_omega_and_the_ellipse_area() {
        let (k, c, x) = (20_000.0, 150.0, 0.004);
        let pts = points(TruthElement::linear(k, c), &[2.0, 5.0], x);
        for p in &pts {
            let w = 2.0 * std::f64::consts::PI * p.frequency_hz;
            assert!(
                (p.storage_stiffness_n_per_m / k - 1.0).abs() < 1e-6,
                "{p:?}"
            );
            assert!(
                (p.loss_stiffness_n_per_m / (c * w) - 1.0).abs() < 1e-6,
                "{p:?}"
            );
            let angle = (c * w / k).atan().to_degrees();
            assert!((p.loss_angle_deg - angle).abs() < 1e-4, "{p:?}");
            let area = std::f64::consts::PI * c * w * x * x;
            assert!((p.dissipated_energy_j / area - 1.0).abs() < 1e-6, "{p:?}");
            // At peak velocity the stroke is at mid-travel: the force is c w x.
            let f = c * w * x;
            assert!(
                (p.rebound_force_at_peak_velocity_n / f - 1.0).abs() < 1e-4,
                "{p:?}"
            );
            assert!(
                (p.compression_force_at_peak_velocity_n / -f - 1.0).abs() < 1e-4,
                "{p:?}"
            );
            assert!((p.peak_velocity_mps / (w * x) - 1.0).abs() < 1e-4, "{p:?}");
        }
    }

    #[test]
    fn dry_friction_dissipates_four_fd_x_per_cycle() {
        // A displacement-driven friction element: the loop is a rectangle of height 2 fd and
        // width 2 X, and the fundamental's loss stiffness is the describing function 4 fd / (pi X).
        let (k, fd, x) = (10_000.0, 40.0, 0.005);
        let pts = points(
            TruthElement {
                friction: Some(Friction::coulomb(fd)),
                ..TruthElement::linear(k, 0.0)
            },
            &[3.0],
            x,
        );
        let p = &pts[0];
        assert!(
            (p.dissipated_energy_j / (4.0 * fd * x) - 1.0).abs() < 0.01,
            "{p:?}"
        );
        let describing = 4.0 * fd / (std::f64::consts::PI * x);
        assert!(
            (p.loss_stiffness_n_per_m / describing - 1.0).abs() < 0.01,
            "{p:?}"
        );
        assert!(
            (p.storage_stiffness_n_per_m / k - 1.0).abs() < 0.01,
            "{p:?}"
        );
    }

    #[test]
    fn an_identified_moving_mass_is_taken_out_of_the_element_force() {
        // A force-driven mass on a spring and damper: the measured force holds m x'' too.
        let (m, k, c) = (2.0, 30_000.0, 80.0);
        let run = RunSpec::element_test(
            ElementDrive::Force,
            m,
            TruthElement::linear(k, c),
            sine_steps(&[8.0, 15.0], 20.0),
            2000.0,
            4000,
        );
        let records = run.simulate().expect("simulating the element test");
        let unknown = Setup::Element {
            moving_mass_kg: None,
            drive: None,
        };
        for r in &records {
            let an = analyse_record(r, &PhasorOptions::for_identification()).expect("analysed");
            assert!(stiffness_point(&unknown, &an).is_err());
            let p = stiffness_point(&unknown.with_extra_values(&[m]), &an).expect("the point");
            let w = 2.0 * std::f64::consts::PI * p.frequency_hz;
            assert!(
                (p.storage_stiffness_n_per_m / k - 1.0).abs() < 1e-6,
                "{p:?}"
            );
            assert!(
                (p.loss_stiffness_n_per_m / (c * w) - 1.0).abs() < 1e-6,
                "{p:?}"
            );
        }
    }
}
