//! Periodic multisine records through the CSV contract: the simulator's records written and
//! read back equal (samples bit for bit, base frequency and lines exact, the RMS estimated
//! from the force as for every export), exports without multisines unchanged, and bad
//! multisine cells named by line and column.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use forcemap_io::csv_export::{read_csv, write_csv};
use forcemap_math::record::{Excitation, Record};
use forcemap_math::sim::{MultisineDesign, MultisinePlan, RunSpec, TruthElement};

fn records() -> (RunSpec, Vec<Record>) {
    let plan = MultisinePlan {
        base_frequency_hz: 2.0,
        band_hz: [4.0, 40.0],
        rms: 60.0,
        design: MultisineDesign::RandomOdd,
        periods: 3,
    };
    let element = TruthElement {
        cubic_stiffness_n_per_m3: 5.0e7,
        ..TruthElement::linear(2.0e4, 60.0)
    };
    let spec = RunSpec {
        snr_db: Some(30.0),
        seed: 7,
        ..RunSpec::force_driven_multisine(2.0, element, &plan, 2, 1000.0)
    };
    let records = spec.simulate().unwrap();
    (spec, records)
}

#[test]
fn multisine_records_round_trip() {
    let (spec, mut records) = records();
    // A sine step after the multisines: the columns are 0 and empty on its rows.
    let mut sine = records[0].clone();
    sine.step = 2;
    sine.start_time_s = records[1].start_time_s + records[1].len() as f64 / 1000.0;
    sine.excitation = Excitation::Sine {
        frequency_hz: 5.0,
        amplitude: 1.0,
    };
    records.push(sine);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("multisine.csv");
    write_csv(&path, &records, spec.setup_kind()).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let header = text.lines().next().unwrap();
    assert!(
        header.starts_with("time_s,step,frequency_hz,multisine_base_hz,multisine_lines,"),
        "{header}"
    );
    let import = read_csv(&path).unwrap();
    assert_eq!(import.kind, spec.setup_kind());
    assert!(
        import.ignored_columns.is_empty(),
        "{:?}",
        import.ignored_columns
    );
    // The multisine labels are not checked by the segmenter; the fake sine step (multisine
    // samples) is, and is caught.
    assert_eq!(import.warnings.len(), 1, "{:?}", import.warnings);
    assert!(import.warnings[0].starts_with("step 2 is labelled a sine of 5 Hz"));
    assert_eq!(import.records.len(), records.len());
    // The reader estimates a level on its profile's driven channel (the element profile's is
    // the displacement; the run's own, the force, is not in the export).
    let driven = spec.setup_kind().driven_channel();
    for (a, b) in records.iter().zip(&import.records) {
        assert_eq!(a.step, b.step);
        assert_eq!(a.channels.len(), b.channels.len());
        for (c, x) in &a.channels {
            let y = b.channel(*c).unwrap();
            assert!(
                x.iter().zip(y).all(|(u, v)| u.to_bits() == v.to_bits()),
                "step {} channel {}",
                a.step,
                c.name()
            );
        }
        assert_eq!(a.start_time_s.to_bits(), b.start_time_s.to_bits());
        assert_eq!(b.sample_rate_hz, 1000.0);
        match (&a.excitation, &b.excitation) {
            (
                Excitation::Multisine {
                    base_frequency_hz: f1,
                    lines: l1,
                    ..
                },
                Excitation::Multisine {
                    base_frequency_hz: f2,
                    lines: l2,
                    rms,
                },
            ) => {
                assert_eq!(f1.to_bits(), f2.to_bits());
                assert_eq!(l1, l2);
                assert!(l1.len() > 3, "{l1:?}");
                // The export carries no level: the driven channel's RMS about its mean.
                let f = a.channel(driven).unwrap();
                let mean = f.iter().sum::<f64>() / f.len() as f64;
                let want =
                    (f.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / f.len() as f64).sqrt();
                assert_eq!(rms.to_bits(), want.to_bits());
            }
            (
                Excitation::Sine {
                    frequency_hz: 5.0, ..
                },
                Excitation::Sine { frequency_hz, .. },
            ) => {
                assert_eq!(*frequency_hz, 5.0);
            }
            (x, y) => panic!("excitation changed: {x:?} -> {y:?}"),
        }
    }
    // Written once more from what was read: the same file.
    let again = dir.path().join("again.csv");
    write_csv(&again, &import.records, import.kind).unwrap();
    assert_eq!(std::fs::read_to_string(&again).unwrap(), text);
}

#[test]
fn exports_without_multisines_keep_their_header() {
    let (spec, mut records) = records();
    for r in &mut records {
        r.excitation = Excitation::Random {
            band_hz: None,
            rms: 60.0,
        };
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("random.csv");
    write_csv(&path, &records, spec.setup_kind()).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(!text.lines().next().unwrap().contains("multisine"));
    for r in read_csv(&path).unwrap().records {
        assert!(matches!(r.excitation, Excitation::Random { .. }));
    }
}

/// Bad multisine cells and layouts: refused with the line and column named.
#[test]
fn bad_multisine_labels_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let head = "time_s,step,frequency_hz,multisine_base_hz,multisine_lines,relative_displacement_m,force_n";
    let rows = |cells: &[&str]| {
        let mut t = format!("{head}\n");
        for (i, c) in cells.iter().enumerate() {
            t.push_str(&format!("{},0,0,{c},{},{}\n", i as f64 * 0.001, i, 2 * i));
        }
        t
    };
    let cases = [
        (
            rows(&["2,3 5", "2,3 5", "2,3 7", "2,3 7"]),
            vec!["line 4", "step 0", "changes inside the step"],
        ),
        (
            rows(&["2,5 3", "2,5 3", "2,5 3"]),
            vec!["line 2", "multisine_lines", "ascending"],
        ),
        (
            rows(&["0,3", "0,3", "0,3"]),
            vec!["line 2", "multisine_lines", "is 0 or empty"],
        ),
        (
            "time_s,multisine_base_hz,multisine_lines,relative_displacement_m,force_n\n0,2,3,0,0\n".to_string(),
            vec!["need the 'step' and 'frequency_hz' columns"],
        ),
        (
            "time_s,step,frequency_hz,multisine_base_hz,relative_displacement_m,force_n\n0,0,0,2,0,0\n"
                .to_string(),
            vec!["go together"],
        ),
    ];
    for (k, (text, needles)) in cases.iter().enumerate() {
        let path = dir.path().join(format!("bad{k}.csv"));
        std::fs::write(&path, text).unwrap();
        let e = read_csv(&path).unwrap_err().to_string();
        for n in needles {
            assert!(e.contains(n), "case {k}: '{n}' not in: {e}");
        }
    }
}

#[test]
fn writing_refuses_malformed_lines() {
    let (spec, mut records) = records();
    records.truncate(1);
    records[0].excitation = Excitation::Multisine {
        base_frequency_hz: 2.0,
        lines: vec![5, 3],
        rms: 1.0,
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("x.csv");
    let e = write_csv(&path, &records, spec.setup_kind())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("record 0 (step 0)") && e.contains("ascending"),
        "{e}"
    );
    assert!(!path.exists());
}
