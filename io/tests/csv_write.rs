//! Writing refuses bad records before touching the disk and never leaves a half-written file.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::path::Path;

use forcemap_io::csv_export::{CsvError, write_csv};
use forcemap_math::recipe::SetupKind;
use forcemap_math::record::{Channel, Excitation, Record};

fn record(step: usize, channels: &[Channel]) -> Record {
    Record {
        step,
        excitation: Excitation::Sine {
            frequency_hz: 5.0 + step as f64,
            amplitude: 1e-3,
        },
        sample_rate_hz: 100.0,
        start_time_s: step as f64,
        channels: channels
            .iter()
            .map(|&c| (c, (0..20).map(|i| (i as f64 * 0.1).sin()).collect()))
            .collect(),
    }
}

const RIG: [Channel; 3] = [
    Channel::BaseDisplacementM,
    Channel::RelativeDisplacementM,
    Channel::MassAccelerationMps2,
];

fn dir_entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn nan_sample_is_refused_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.csv");
    let mut records = vec![record(0, &RIG), record(1, &RIG)];
    records[1]
        .channel_mut(Channel::RelativeDisplacementM)
        .unwrap()[7] = f64::NAN;
    let err = write_csv(&path, &records, SetupKind::BaseExcited).unwrap_err();
    assert!(
        matches!(
            err,
            CsvError::NonFiniteSample {
                record: 1,
                index: 7,
                channel: Channel::RelativeDisplacementM,
                ..
            }
        ),
        "{err:?}"
    );
    let msg = err.to_string();
    assert!(
        msg.contains("out.csv") && msg.contains("relative_displacement_m"),
        "{msg}"
    );
    assert!(
        dir_entries(dir.path()).is_empty(),
        "{:?}",
        dir_entries(dir.path())
    );
}

#[test]
fn failed_write_keeps_the_previous_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.csv");
    write_csv(&path, &[record(0, &RIG)], SetupKind::BaseExcited).unwrap();
    let before = std::fs::read(&path).unwrap();
    let mut bad = record(0, &RIG);
    bad.channel_mut(Channel::MassAccelerationMps2).unwrap()[0] = f64::INFINITY;
    assert!(write_csv(&path, &[bad], SetupKind::BaseExcited).is_err());
    assert_eq!(std::fs::read(&path).unwrap(), before);
    assert_eq!(dir_entries(dir.path()), vec!["out.csv"]);
}

#[test]
fn unwritable_target_leaves_no_file() {
    let dir = tempfile::tempdir().unwrap();
    // Directory does not exist.
    let missing = dir.path().join("no_such_dir").join("out.csv");
    let err = write_csv(&missing, &[record(0, &RIG)], SetupKind::BaseExcited).unwrap_err();
    assert!(matches!(err, CsvError::Io { .. }), "{err:?}");
    assert!(err.to_string().contains("out.csv"), "{err}");
    assert!(dir_entries(dir.path()).is_empty());

    // The target is a directory: the data are written to the temporary file, the final
    // rename fails, and the temporary file must be removed.
    let target = dir.path().join("taken.csv");
    std::fs::create_dir(&target).unwrap();
    std::fs::write(target.join("keep"), "x").unwrap();
    let err = write_csv(&target, &[record(0, &RIG)], SetupKind::BaseExcited).unwrap_err();
    assert!(matches!(err, CsvError::Io { .. }), "{err:?}");
    assert_eq!(dir_entries(dir.path()), vec!["taken.csv"]);
    assert_eq!(dir_entries(&target), vec!["keep"]);
}

#[cfg(unix)]
#[test]
fn read_only_directory_leaves_no_file() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let ro = dir.path().join("ro");
    std::fs::create_dir(&ro).unwrap();
    std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o555)).unwrap();
    // Root ignores permissions; then the check is meaningless.
    let probe = ro.join("probe");
    if std::fs::write(&probe, "x").is_ok() {
        std::fs::remove_file(&probe).unwrap();
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o755)).unwrap();
        eprintln!("skipped: directory permissions are not enforced for this user");
        return;
    }
    let err = write_csv(
        ro.join("out.csv"),
        &[record(0, &RIG)],
        SetupKind::BaseExcited,
    )
    .unwrap_err();
    std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o755)).unwrap();
    assert!(matches!(err, CsvError::Io { .. }), "{err:?}");
    assert!(dir_entries(&ro).is_empty());
}

#[test]
fn inconsistent_records_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.csv");
    let cases: Vec<(Vec<Record>, SetupKind, &str)> = vec![
        (vec![], SetupKind::BaseExcited, "no records"),
        (
            vec![record(0, &RIG[..2])],
            SetupKind::BaseExcited,
            "mass_acceleration_mps2",
        ),
        (
            vec![
                record(0, &RIG),
                record(1, &[RIG[0], RIG[1], RIG[2], Channel::ForceN]),
            ],
            SetupKind::BaseExcited,
            "same channels",
        ),
        (
            vec![record(0, &RIG), record(2, &RIG)],
            SetupKind::BaseExcited,
            "contiguous",
        ),
        (
            vec![record(
                0,
                &[
                    Channel::BaseDisplacementM,
                    Channel::RelativeDisplacementM,
                    Channel::ForceN,
                    Channel::DrivePointDisplacementM,
                ],
            )],
            SetupKind::DrivePoint,
            "rig profile",
        ),
        (
            {
                let mut r = record(1, &RIG);
                r.start_time_s = 0.1; // overlaps record 0 (0 .. 0.19 s)
                vec![record(0, &RIG), r]
            },
            SetupKind::BaseExcited,
            "does not increase",
        ),
        (
            {
                let mut r = record(0, &RIG);
                r.sample_rate_hz = 0.0;
                vec![r]
            },
            SetupKind::BaseExcited,
            "sample rate",
        ),
        (
            {
                let mut r = record(0, &RIG);
                r.excitation = Excitation::Sine {
                    frequency_hz: 0.0,
                    amplitude: 1.0,
                };
                vec![r]
            },
            SetupKind::BaseExcited,
            "sine frequency",
        ),
        (
            {
                let mut r = record(0, &RIG);
                for (_, x) in &mut r.channels {
                    x.truncate(2);
                }
                vec![r]
            },
            SetupKind::BaseExcited,
            "at least 3",
        ),
    ];
    for (records, profile, expect) in cases {
        let err = write_csv(&path, &records, profile).unwrap_err();
        let msg = err.to_string();
        assert!(
            msg.contains(expect) && msg.contains("out.csv"),
            "{expect:?}: {msg}"
        );
        assert!(dir_entries(dir.path()).is_empty(), "{expect:?}");
    }
}

#[test]
fn random_records_write_frequency_zero_and_values_round_trip_as_text() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.csv");
    let mut r = record(0, &RIG);
    r.excitation = Excitation::Random {
        band_hz: None,
        rms: 1.0,
    };
    r.channel_mut(Channel::BaseDisplacementM).unwrap()[0] = 1e-300;
    write_csv(&path, &[r], SetupKind::BaseExcited).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let second = text.lines().nth(1).unwrap();
    assert!(second.starts_with("0,0,0,1e-300,"), "{second}");
    assert_eq!(text.lines().count(), 21);
}

/// A multisine record whose lines are not ascending is refused before the file system is
/// touched.
#[test]
fn a_multisine_record_with_bad_lines_is_refused_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.csv");
    let mut r = record(3, &RIG);
    r.excitation = Excitation::Multisine {
        base_frequency_hz: 0.5,
        lines: vec![9, 15, 11],
        rms: 60.0,
    };
    let msg = write_csv(&path, &[r], SetupKind::BaseExcited)
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("out.csv") && msg.contains("step 3") && msg.contains("ascending"),
        "{msg}"
    );
    assert!(dir_entries(dir.path()).is_empty());
}
