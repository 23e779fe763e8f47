//! Conversions from and to the forcemap_math types.

mod common;

use forcemap_math::identify::{Identification, Parameter};
use forcemap_math::phasor::{PhasorOptions, SweepKind, SweepLaw, analyse_record};
use forcemap_math::record::{Channel, Excitation, Record};
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::msg::{ExcitationState, HarmonicPhasors, IdentifiedParameters, RigSample};
use forcemap_msgs::std_msgs::Header;
use forcemap_msgs::{ConversionError, RosMessage};

fn sine_record() -> Record {
    let fs = 200.0;
    let f = 5.0;
    let n = 400;
    let t0 = 12.5;
    let w = 2.0 * std::f64::consts::PI * f;
    let sig = |a: f64, ph: f64, h2: f64| -> Vec<f64> {
        (0..n)
            .map(|i| {
                let t = t0 + i as f64 / fs;
                a * (w * t + ph).cos() + h2 * (2.0 * w * t).sin() + 0.1 * a
            })
            .collect()
    };
    Record {
        step: 3,
        excitation: Excitation::Sine {
            frequency_hz: f,
            amplitude: 2e-3,
        },
        sample_rate_hz: fs,
        start_time_s: t0,
        channels: vec![
            (Channel::BaseDisplacementM, sig(2e-3, 0.0, 0.0)),
            (Channel::RelativeDisplacementM, sig(5e-4, 0.3, 1e-5)),
            (Channel::MassAccelerationMps2, sig(0.8, -0.2, 0.05)),
        ],
    }
}

#[test]
fn time_helpers() {
    assert_eq!(
        Time::from_secs_f64(-1.7),
        Time {
            sec: -2,
            nanosec: 300_000_000
        }
    );
    assert_eq!(
        Time::from_secs_f64(1.7),
        Time {
            sec: 1,
            nanosec: 700_000_000
        }
    );
    assert_eq!(
        Time::from_secs_f64(0.999_999_999_9),
        Time { sec: 1, nanosec: 0 }
    );
    let t = Time {
        sec: 100,
        nanosec: 900_000_000,
    };
    assert_eq!(
        t.add_secs_f64(0.25),
        Time {
            sec: 101,
            nanosec: 150_000_000
        }
    );
    assert_eq!(
        t.add_secs_f64(-101.0),
        Time {
            sec: -1,
            nanosec: 900_000_000
        }
    );
    assert!((t.add_secs_f64(12.345).secs_since(t) - 12.345).abs() < 1e-9);
    assert_eq!(
        Time::from_nanos(-1),
        Time {
            sec: -1,
            nanosec: 999_999_999
        }
    );
    assert_eq!(Time::from_nanos(i64::MAX).sec, i32::MAX);
}

#[test]
fn rig_sample_from_record() {
    let rec = sine_record();
    let s = RigSample::from_record(&rec, 7, Header::default());
    assert_eq!(s.step, 3);
    assert_eq!(
        s.present(),
        [
            Channel::BaseDisplacementM,
            Channel::RelativeDisplacementM,
            Channel::MassAccelerationMps2
        ]
    );
    assert_eq!(s.present_channels, 0b111);
    assert_eq!(
        s.channel(Channel::MassAccelerationMps2),
        Some(rec.channels[2].1[7])
    );
    assert_eq!(s.relative_displacement_m, rec.channels[1].1[7]);
    assert!(s.force_n.is_nan());
    assert_eq!(s.channel(Channel::ForceN), None);
}

#[test]
fn three_dof_fits_rig_sample() {
    let s = common::three_dof_sample();
    assert_eq!(
        s.present(),
        [
            Channel::RelativeDisplacementM,
            Channel::ForceN,
            Channel::DrivePointDisplacementM
        ]
    );
    let mut s2 = s.clone();
    s2.set_channel(Channel::ForceN, None);
    assert_eq!(s2.channel(Channel::ForceN), None);
    assert!(s2.force_n.is_nan());
    assert_eq!(
        s2.present_channels,
        RigSample::RELATIVE_DISPLACEMENT | RigSample::DRIVE_POINT_DISPLACEMENT
    );
}

#[test]
fn excitation_state_both_ways() {
    let start = Time {
        sec: 10,
        nanosec: 0,
    };
    let sine = Excitation::Sine {
        frequency_hz: 6.0,
        amplitude: 1e-3,
    };
    let m = ExcitationState::from_excitation(
        Header::default(),
        4,
        start,
        &sine,
        Channel::BaseDisplacementM,
        1300,
    );
    assert_eq!(m.kind, ExcitationState::SINE);
    assert_eq!(m.sample_count, 1300);
    assert_eq!(m.driven_channel, "base_displacement_m");
    assert!(m.band_low_hz.is_nan() && m.band_high_hz.is_nan());
    assert_eq!(m.excitation().unwrap(), sine);
    assert_eq!(m.driven().unwrap(), Channel::BaseDisplacementM);

    for band in [Some([1.0, 30.0]), None] {
        let random = Excitation::Random {
            band_hz: band,
            rms: 3.0,
        };
        let m = ExcitationState::from_excitation(
            Header::default(),
            5,
            start,
            &random,
            Channel::ForceN,
            0,
        );
        assert_eq!(m.kind, ExcitationState::RANDOM);
        assert_eq!(m.frequency_hz, 0.0);
        let back = ExcitationState::from_cdr(&m.to_cdr()).unwrap();
        assert_eq!(back.excitation().unwrap(), random);
    }
    let mut bad = m;
    bad.kind = 9;
    assert_eq!(
        bad.excitation().unwrap_err(),
        ConversionError::UnknownKind(9)
    );
    bad.driven_channel = "torque_nm".into();
    assert!(matches!(
        bad.driven(),
        Err(ConversionError::UnknownChannel { .. })
    ));
}

#[test]
fn harmonic_phasors_from_analysis_and_back() {
    let rec = sine_record();
    let an = analyse_record(
        &rec,
        &PhasorOptions {
            max_harmonic: 4,
            ..PhasorOptions::default()
        },
    )
    .unwrap();
    let run_start = Time {
        sec: 1_700_000_000,
        nanosec: 900_000_000,
    };
    let m = HarmonicPhasors::from_analysis(&an, run_start, Header::new(run_start, "rig"));
    assert_eq!(m.harmonic_orders, [0, 1, 2, 3, 4]);
    assert_eq!(
        m.channel_names,
        [
            "base_displacement_m",
            "relative_displacement_m",
            "mass_acceleration_mps2"
        ]
    );
    assert_eq!(m.phasor_real.len(), 15);
    // Channel-major layout: channel 2 (acceleration), harmonic 1.
    let c = an.channels[2].phasors[1];
    assert_eq!(m.phasor(2, 1), Some((c.re, c.im)));
    assert_eq!(m.phasor_real[2 * 5 + 1], c.re);
    assert_eq!(m.noise_std[5 + 3], an.channels[1].noise_std[3]);
    assert_eq!(m.phasor(3, 0), None);
    assert!((m.t_ref.secs_since(run_start) - an.t_ref_s).abs() < 1e-9);
    assert_eq!(m.settled, an.settled);

    let decoded = HarmonicPhasors::from_cdr(&m.to_cdr()).unwrap();
    let mut back = decoded.to_analysis(run_start).unwrap();
    assert!((back.t_ref_s - an.t_ref_s).abs() < 1e-9);
    back.t_ref_s = an.t_ref_s;
    assert_eq!(back, an);

    let via_from: HarmonicPhasors = (&an, run_start).into();
    assert_eq!(via_from.phasor_real, m.phasor_real);
}

#[test]
fn harmonic_phasors_bad_layout_is_an_error() {
    let run_start = Time::ZERO;
    let mut m = common::harmonic_phasors();
    m.noise_std.pop();
    assert_eq!(
        m.to_analysis(run_start).unwrap_err(),
        ConversionError::Length {
            message: "HarmonicPhasors",
            field: "noise_std",
            expected: 6,
            actual: 5
        }
    );
    let mut m = common::harmonic_phasors();
    m.harmonic_orders = vec![1, 2, 3];
    assert!(matches!(
        m.to_analysis(run_start),
        Err(ConversionError::HarmonicOrders(_))
    ));
    let mut m = common::harmonic_phasors();
    m.channel_names[1] = "speed".into();
    let err = m.to_analysis(run_start).unwrap_err();
    assert!(err.to_string().contains("\"speed\""), "{err}");
}

fn identification() -> Identification {
    Identification {
        model: "coulomb".into(),
        method: "fd".into(),
        parameters: vec![
            Parameter {
                name: "k".into(),
                value: 2e4,
                std: 10.0,
            },
            Parameter {
                name: "c".into(),
                value: 150.0,
                std: 1.0,
            },
            Parameter {
                name: "fd".into(),
                value: 30.0,
                std: 0.5,
            },
        ],
        covariance: vec![
            vec![100.0, 0.1, 0.2],
            vec![0.1, 1.0, 0.3],
            vec![0.2, 0.3, 0.25],
        ],
        condition_number: 12.0,
        equations: 36,
        // r in a different order than the parameters: matched by name.
        r: vec![("c".into(), 20.0), ("k".into(), 70.0), ("fd".into(), 10.0)],
        residual_rms: 0.5,
        steps_used: vec![0, 2, 3],
        warnings: vec!["few equations".into()],
        fit_quality: None,
        misfit_noise_std: None,
    }
}

#[test]
fn identified_parameters_from_identification() {
    let id = identification();
    let m = IdentifiedParameters::from(&id);
    assert_eq!(m.parameter_names, ["k", "c", "fd"]);
    assert_eq!(m.values, [2e4, 150.0, 30.0]);
    assert_eq!(m.standard_deviations, [10.0, 1.0, 0.5]);
    assert_eq!(m.r_percent, [70.0, 20.0, 10.0]);
    // Row-major: (0, 1) at 1, (1, 2) at 3 + 2, (2, 0) at 6.
    assert_eq!(m.covariance[1], 0.1);
    assert_eq!(m.covariance[5], 0.3);
    assert_eq!(m.covariance[6], 0.2);
    assert_eq!(m.covariance_at(1, 2), Some(0.3));
    assert_eq!(m.value("fd"), Some(30.0));
    assert_eq!(m.equations, 36);
    assert_eq!(m.steps_used, [0, 2, 3]);
    assert_eq!(m.warnings, ["few equations"]);

    let back = IdentifiedParameters::from_cdr(&m.to_cdr())
        .unwrap()
        .to_identification()
        .unwrap();
    assert_eq!(back.covariance, id.covariance);
    assert_eq!(back.theta(), id.theta());
    assert_eq!(back.value("c"), Some(150.0));
    assert_eq!(
        back.r,
        [
            ("k".to_string(), 70.0),
            ("c".into(), 20.0),
            ("fd".into(), 10.0)
        ]
    );
    assert_eq!(back.steps_used, id.steps_used);

    let mut bad = m.clone();
    bad.covariance.pop();
    assert!(matches!(
        bad.to_identification(),
        Err(ConversionError::Length {
            field: "covariance",
            expected: 9,
            actual: 8,
            ..
        })
    ));
    let with_header = IdentifiedParameters::from_identification(&id, common::header("rig"));
    assert_eq!(with_header.header.frame_id, "rig");
}

/// A multisine travels with its own kind, its base frequency, its RMS and the band of its
/// lines; the line set is not carried (the reader finds it from the samples), so it comes
/// back empty.
#[test]
fn a_multisine_excitation_travels_with_its_base_frequency_and_band() {
    let ms = Excitation::Multisine {
        base_frequency_hz: 0.5,
        lines: vec![9, 11, 49],
        rms: 60.0,
    };
    let m = ExcitationState::from_excitation(
        Header::default(),
        1,
        Time::ZERO,
        &ms,
        Channel::ForceN,
        18_000,
    );
    assert_eq!(m.kind, ExcitationState::MULTISINE);
    assert_eq!((m.frequency_hz, m.amplitude), (0.5, 60.0));
    assert_eq!((m.band_low_hz, m.band_high_hz), (4.5, 24.5));
    assert_eq!(
        m.excitation().unwrap(),
        Excitation::Multisine {
            base_frequency_hz: 0.5,
            lines: Vec::new(),
            rms: 60.0,
        }
    );
}

/// A sweep travels with its own kind, its start and end frequency in the band fields (a
/// downward sweep too) and its peak amplitude; its duration is the step's, set by the
/// assembler from the samples, so the message gives NaN.
#[test]
fn a_sweep_excitation_travels_with_its_law() {
    for (kind, code, start, end) in [
        (SweepKind::Linear, ExcitationState::SWEEP_LINEAR, 1.6, 3.4),
        (
            SweepKind::Logarithmic,
            ExcitationState::SWEEP_LOG,
            25.0,
            8.0,
        ),
    ] {
        let law = SweepLaw {
            kind,
            amplitude: 6e-3,
            start_frequency_hz: start,
            end_frequency_hz: end,
            duration_s: 130.0,
        };
        let m = ExcitationState::from_excitation(
            Header::default(),
            0,
            Time::ZERO,
            &Excitation::Sweep { law },
            Channel::BaseDisplacementM,
            260_000,
        );
        assert_eq!(m.kind, code);
        assert_eq!((m.band_low_hz, m.band_high_hz), (start, end));
        assert_eq!((m.frequency_hz, m.amplitude), (0.0, 6e-3));
        let back = ExcitationState::from_cdr(&m.to_cdr()).unwrap();
        let Excitation::Sweep { law: got } = back.excitation().unwrap() else {
            panic!("{back:?} is not a sweep");
        };
        assert!(got.duration_s.is_nan());
        assert_eq!(
            SweepLaw {
                duration_s: 130.0,
                ..got
            },
            law
        );
    }
}
