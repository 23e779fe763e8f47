//! Round trip and happy paths of the test-bench CSV export.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::f64::consts::PI;

use forcemap_io::csv_export::{read_csv, write_csv};
use forcemap_math::recipe::SetupKind;
use forcemap_math::record::{Channel, Excitation, Record};

fn sine_record(step: usize, f: f64, fs: f64, n: usize, start: f64, channels: &[Channel]) -> Record {
    let amp = 0.002;
    let channels = channels
        .iter()
        .enumerate()
        .map(|(k, &c)| {
            let x = (0..n)
                .map(|i| {
                    let t = i as f64 / fs;
                    amp * (k as f64 + 1.0) * (2.0 * PI * f * t + 0.3 * k as f64).sin()
                        + 1e-7 * (i as f64).sqrt()
                })
                .collect();
            (c, x)
        })
        .collect();
    Record {
        step,
        excitation: Excitation::Sine {
            frequency_hz: f,
            amplitude: amp,
        },
        sample_rate_hz: fs,
        start_time_s: start,
        channels,
    }
}

const RIG: [Channel; 6] = [
    Channel::BaseDisplacementM,
    Channel::RelativeDisplacementM,
    Channel::MassAccelerationMps2,
    Channel::MassDisplacementM,
    Channel::BaseAccelerationMps2,
    Channel::ForceN,
];

fn assert_same_samples(a: &Record, b: &Record) {
    assert_eq!(a.step, b.step);
    assert_eq!(a.len(), b.len());
    let mut ca: Vec<Channel> = a.channels.iter().map(|(c, _)| *c).collect();
    let mut cb: Vec<Channel> = b.channels.iter().map(|(c, _)| *c).collect();
    ca.sort();
    cb.sort();
    assert_eq!(ca, cb, "channel sets differ");
    for (c, x) in &a.channels {
        let y = b.channel(*c).unwrap();
        for (i, (u, v)) in x.iter().zip(y).enumerate() {
            assert_eq!(
                u.to_bits(),
                v.to_bits(),
                "step {} channel {} sample {i}: {u:e} vs {v:e}",
                a.step,
                c.name()
            );
        }
    }
    assert_eq!(
        a.start_time_s.to_bits(),
        b.start_time_s.to_bits(),
        "start time"
    );
}

#[test]
fn rig_round_trip_is_bit_exact() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rig_run.csv");
    let fs = 2560.0;
    let mut records = vec![
        sine_record(0, 5.0, fs, 700, 0.0, &RIG),
        sine_record(1, 7.123456789012345, fs, 650, 0.5, &RIG),
        sine_record(2, 1.0 / 3.0, fs, 900, 0.9, &RIG),
    ];
    // Awkward values: extremes, subnormal, negative zero, thirds.
    {
        let x = records[1].channel_mut(Channel::ForceN).unwrap();
        x[0] = 1e-300;
        x[1] = -0.0;
        x[2] = 5e-324;
        x[3] = 1.0 / 3.0;
        x[4] = -1.7976931348623157e308;
        x[5] = 1e16;
        x[6] = 9.999999999999999e-6;
    }
    // A random record.
    let mut random = sine_record(3, 1.0, fs, 500, 1.4, &RIG);
    random.excitation = Excitation::Random {
        band_hz: Some([1.0, 100.0]),
        rms: 0.001,
    };
    records.push(random);

    write_csv(&path, &records, SetupKind::BaseExcited).unwrap();
    let import = read_csv(&path).unwrap();
    assert_eq!(import.kind, SetupKind::BaseExcited);
    assert!(import.ignored_columns.is_empty());
    assert_eq!(import.records.len(), records.len());
    for (a, b) in records.iter().zip(&import.records) {
        assert_same_samples(a, b);
        assert_eq!(
            b.sample_rate_hz, fs,
            "integer sample rate recovered exactly"
        );
        match (&a.excitation, &b.excitation) {
            (
                Excitation::Sine {
                    frequency_hz: f1, ..
                },
                Excitation::Sine {
                    frequency_hz: f2, ..
                },
            ) => assert_eq!(f1.to_bits(), f2.to_bits()),
            (Excitation::Random { .. }, Excitation::Random { band_hz, .. }) => {
                assert_eq!(*band_hz, None);
            }
            (x, y) => panic!("excitation kind changed: {x:?} -> {y:?}"),
        }
    }
    // Header: fixed columns, then channels in Channel::ALL order.
    let text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(
        text.lines().next().unwrap(),
        "time_s,step,frequency_hz,base_displacement_m,relative_displacement_m,\
         mass_acceleration_mps2,mass_displacement_m,base_acceleration_mps2,force_n"
    );
    // No temporary file left behind.
    let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(names.len(), 1);
}

#[test]
fn drive_point_round_trip_and_non_integer_rate() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("three_dof.csv");
    let ch = [
        Channel::RelativeDisplacementM,
        Channel::ForceN,
        Channel::DrivePointDisplacementM,
    ];
    let fs = 1000.5;
    let records = vec![
        sine_record(4, 12.5, fs, 400, 10.0, &ch),
        sine_record(5, 13.0, fs, 400, 10.5, &ch),
    ];
    write_csv(&path, &records, SetupKind::DrivePoint).unwrap();
    let import = read_csv(&path).unwrap();
    assert_eq!(import.kind, SetupKind::DrivePoint);
    for (a, b) in records.iter().zip(&import.records) {
        assert_same_samples(a, b);
        assert!(
            (b.sample_rate_hz - fs).abs() < 1e-9 * fs,
            "{}",
            b.sample_rate_hz
        );
        assert_eq!(a.excitation.frequency_hz(), b.excitation.frequency_hz());
    }
}

#[test]
fn amplitude_and_rms_are_estimated_from_the_driven_channel() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("amp.csv");
    let fs = 1000.0;
    let n = 1000; // 10 whole periods of 10 Hz
    let base: Vec<f64> = (0..n)
        .map(|i| 0.003 * (2.0 * PI * 10.0 * i as f64 / fs).sin() + 0.5)
        .collect();
    let other = vec![0.0; n];
    let rec = |step, excitation| Record {
        step,
        excitation,
        sample_rate_hz: fs,
        start_time_s: step as f64 * 2.0,
        channels: vec![
            (Channel::BaseDisplacementM, base.clone()),
            (Channel::RelativeDisplacementM, other.clone()),
            (Channel::MassAccelerationMps2, other.clone()),
        ],
    };
    let records = vec![
        rec(
            0,
            Excitation::Sine {
                frequency_hz: 10.0,
                amplitude: 0.003,
            },
        ),
        rec(
            1,
            Excitation::Random {
                band_hz: None,
                rms: 0.0,
            },
        ),
    ];
    write_csv(&path, &records, SetupKind::BaseExcited).unwrap();
    let import = read_csv(&path).unwrap();
    match import.records[0].excitation {
        Excitation::Sine { amplitude, .. } => {
            assert!((amplitude - 0.003).abs() < 1e-9, "{amplitude}");
        }
        ref e => panic!("{e:?}"),
    }
    match import.records[1].excitation {
        Excitation::Random { rms, band_hz } => {
            assert!((rms - 0.003 / 2f64.sqrt()).abs() < 1e-9, "{rms}");
            assert_eq!(band_hz, None);
        }
        ref e => panic!("{e:?}"),
    }
}

#[test]
fn ignored_columns_are_reported_and_daq_style_file_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("daq.csv");
    // A DAQ export: fixed 6 decimals of time at 10 kHz, extra columns, empty frequency for
    // random excitation, spaces around cells, a step not starting at 0.
    let mut text = String::from(
        "time_s, operator , step,frequency_hz,base_displacement_m,relative_displacement_m,\
         mass_acceleration_mps2,temperature_c,force_n\n",
    );
    let mut i = 0usize;
    for (step, freq) in [(3usize, "20"), (4, ""), (5, "0")] {
        for _ in 0..50 {
            let t = i as f64 * 1e-4 + 1.0;
            text.push_str(&format!(
                "{t:.6}, jo ,{step},{freq},{:.9},1e-6,-0.5,21.5,3\n",
                (i as f64 * 0.1).sin() * 1e-3
            ));
            i += 1;
        }
    }
    std::fs::write(&path, text).unwrap();
    let import = read_csv(&path).unwrap();
    assert_eq!(import.ignored_columns, vec!["operator", "temperature_c"]);
    assert_eq!(import.kind, SetupKind::BaseExcited);
    assert_eq!(import.records.len(), 3);
    let steps: Vec<usize> = import.records.iter().map(|r| r.step).collect();
    assert_eq!(steps, vec![3, 4, 5]);
    assert_eq!(import.records[0].sample_rate_hz, 10_000.0);
    assert_eq!(import.records[0].excitation.frequency_hz(), Some(20.0));
    assert!(matches!(
        import.records[1].excitation,
        Excitation::Random { .. }
    ));
    assert!(matches!(
        import.records[2].excitation,
        Excitation::Random { .. }
    ));
    assert_eq!(import.records[0].start_time_s, 1.0);
    let chans: Vec<Channel> = import.records[0].channels.iter().map(|(c, _)| *c).collect();
    assert_eq!(
        chans,
        vec![
            Channel::BaseDisplacementM,
            Channel::RelativeDisplacementM,
            Channel::MassAccelerationMps2,
            Channel::ForceN
        ]
    );
    assert_eq!(import.records[2].len(), 50);
}

#[test]
fn header_with_force_and_drive_point_but_no_base_is_the_drive_point_profile() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("dp.csv");
    let mut text = String::from(
        "time_s,step,frequency_hz,force_n,drive_point_displacement_m,relative_displacement_m\n",
    );
    for i in 0..5 {
        text.push_str(&format!(
            "{},0,3,{},1,2\n",
            i as f64 * 0.01,
            (i as f64).sin()
        ));
    }
    std::fs::write(&path, text).unwrap();
    let import = read_csv(&path).unwrap();
    assert_eq!(import.kind, SetupKind::DrivePoint);
    assert_eq!(import.records[0].sample_rate_hz, 100.0);
}
