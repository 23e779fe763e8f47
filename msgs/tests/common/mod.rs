//! Sample messages of every type, shared by the tests.
#![allow(dead_code)]

use forcemap_math::record::Channel;
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus, KeyValue};
use forcemap_msgs::msg::{ExcitationState, HarmonicPhasors, IdentifiedParameters, RigSample};
use forcemap_msgs::std_msgs::Header;

pub fn header(frame: &str) -> Header {
    Header::new(
        Time {
            sec: 1_700_000_123,
            nanosec: 456_789_012,
        },
        frame,
    )
}

/// Base-excited rig sample: the three rig channels and base acceleration; the rest absent.
pub fn rig_sample() -> RigSample {
    RigSample::new(header("rig"), 4)
        .with(Channel::BaseDisplacementM, 1.25e-3)
        .with(Channel::RelativeDisplacementM, -3.5e-4)
        .with(Channel::MassAccelerationMps2, 9.81)
        .with(Channel::BaseAccelerationMps2, -0.125)
}

/// 3-DOF drive-point sample: two element-end displacements and the drive force.
pub fn three_dof_sample() -> RigSample {
    RigSample::new(header("three_dof"), 0)
        .with(Channel::RelativeDisplacementM, 2.0e-5)
        .with(Channel::DrivePointDisplacementM, 7.5e-5)
        .with(Channel::ForceN, 12.5)
}

pub fn excitation_sine() -> ExcitationState {
    ExcitationState {
        header: header("rig"),
        step: 2,
        start_time: Time {
            sec: 1_700_000_100,
            nanosec: 5,
        },
        kind: ExcitationState::SINE,
        driven_channel: "base_displacement_m".into(),
        frequency_hz: 6.25,
        amplitude: 2.0e-3,
        band_low_hz: f64::NAN,
        band_high_hz: f64::NAN,
        sample_count: 1300,
    }
}

pub fn excitation_random() -> ExcitationState {
    ExcitationState {
        header: header("rig"),
        step: 9,
        start_time: Time {
            sec: -3,
            nanosec: 999_999_999,
        },
        kind: ExcitationState::RANDOM,
        driven_channel: "force_n".into(),
        frequency_hz: 0.0,
        amplitude: 1.5,
        band_low_hz: 1.0,
        band_high_hz: 20.0,
        sample_count: 0,
    }
}

pub fn harmonic_phasors() -> HarmonicPhasors {
    // 2 channels x 3 harmonics, channel-major.
    HarmonicPhasors {
        header: header("rig"),
        step: 3,
        frequency_hz: 4.0,
        amplitude: 1.0e-3,
        harmonic_orders: vec![0, 1, 2],
        channel_names: vec![
            "relative_displacement_m".into(),
            "mass_acceleration_mps2".into(),
        ],
        phasor_real: vec![1e-6, 5e-4, -2e-6, 0.01, -0.5, 0.02],
        phasor_imag: vec![0.0, -2.5e-4, 1e-7, 0.0, 0.25, -0.03],
        noise_std: vec![1e-8, 2e-8, 3e-8, 1e-3, 2e-3, 3e-3],
        residual_rms: vec![1.5e-7, 4e-3],
        periods_used: 12,
        periods_available: 20,
        first_settled_sample: 800,
        samples_used: 3000,
        harmonic_cap: 31,
        settled: true,
        t_ref: Time {
            sec: 1_700_000_110,
            nanosec: 250_000_000,
        },
    }
}

pub fn identified_parameters() -> IdentifiedParameters {
    IdentifiedParameters {
        header: header("rig"),
        model: "coulomb-cubic".into(),
        method: "fd-multi".into(),
        parameter_names: vec!["k".into(), "c".into(), "fd".into()],
        values: vec![20000.0, 150.0, 35.5],
        standard_deviations: vec![12.0, 0.5, 0.25],
        covariance: vec![144.0, 1.0, 0.5, 1.0, 0.25, 0.01, 0.5, 0.01, 0.0625],
        r_percent: vec![70.0, 20.0, 10.0],
        equations: 240,
        condition_number: 35.25,
        residual_rms: 0.0625,
        steps_used: vec![0, 1, 2, 5],
        warnings: vec!["step 4 left out: never slips (|x'| < 1 µm/s)".into()],
    }
}

pub fn diagnostic_array() -> DiagnosticArray {
    DiagnosticArray {
        header: header(""),
        status: vec![
            DiagnosticStatus::new(DiagnosticStatus::OK, "forcemap/sensor", "running", "rig-1")
                .with_value("sample_rate_hz", 1000)
                .with_value("step", 3),
            DiagnosticStatus::new(
                DiagnosticStatus::WARN,
                "forcemap/identifier",
                "model departs from the rig",
                "",
            ),
            DiagnosticStatus {
                level: DiagnosticStatus::STALE,
                name: "forcemap/harmonic".into(),
                message: String::new(),
                hardware_id: String::new(),
                values: vec![KeyValue::new("k", "")],
            },
        ],
    }
}
