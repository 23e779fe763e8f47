//! Sine-sweep records through the CSV contract: the simulator's rig sweep (and the random
//! validation records after it) written and read back equal (samples bit for bit, law and
//! frequencies exact, the duration the record's, the amplitude estimated from the base
//! displacement), and bad sweep cells named by line and column.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use forcemap_io::csv_export::{read_csv, write_csv};
use forcemap_math::phasor::SweepKind;
use forcemap_math::record::Excitation;
use forcemap_math::sim::RunSpec;

#[test]
fn sweep_records_round_trip() {
    let spec = RunSpec::rig_sweep(SweepKind::Logarithmic, true, Some(40.0), 3);
    let records = spec.simulate().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sweep.csv");
    write_csv(&path, &records, spec.setup_kind()).unwrap();
    let back = read_csv(&path).unwrap();
    assert_eq!(back.records.len(), 3);
    for (a, b) in records.iter().zip(&back.records) {
        assert_eq!(a.channels, b.channels, "step {}", a.step);
        assert_eq!(a.start_time_s, b.start_time_s);
    }
    let (Excitation::Sweep { law: written }, Excitation::Sweep { law: read }) =
        (&records[0].excitation, &back.records[0].excitation)
    else {
        panic!("{:?}", back.records[0].excitation)
    };
    assert_eq!(read.kind, written.kind);
    assert_eq!(read.start_frequency_hz, 1.6);
    assert_eq!(read.end_frequency_hz, 3.4);
    assert!((read.duration_s - written.duration_s).abs() < 1e-9);
    // sqrt 2 times the RMS of the noisy base displacement: within 1 % of the 6 mm commanded.
    assert!(
        (read.amplitude / written.amplitude - 1.0).abs() < 0.01,
        "{read:?}"
    );
    assert!(matches!(
        back.records[1].excitation,
        Excitation::Random { .. }
    ));
}

#[test]
fn bad_sweep_cells_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let head = "time_s,step,frequency_hz,sweep_law,sweep_start_hz,sweep_end_hz,\
                base_displacement_m,relative_displacement_m,mass_acceleration_mps2";
    let row = |t: f64, law: &str| format!("{t},0,0,{law},1,4,0.001,0.0001,0.1");
    let cases = [
        (
            vec![row(0.0, "linear"), row(0.01, "cubic"), row(0.02, "linear")],
            "line 3, column 'sweep_law'",
        ),
        (
            vec![row(0.0, "linear"), row(0.01, "log"), row(0.02, "log")],
            "changes inside the step",
        ),
    ];
    for (rows, needle) in cases {
        let path = dir.path().join("bad.csv");
        std::fs::write(&path, format!("{head}\n{}\n", rows.join("\n"))).unwrap();
        let e = read_csv(&path).unwrap_err().to_string();
        assert!(e.contains(needle), "{e}");
    }
    let path = dir.path().join("lone.csv");
    std::fs::write(
        &path,
        "time_s,step,frequency_hz,sweep_law,base_displacement_m,relative_displacement_m,\
         mass_acceleration_mps2\n0,0,0,linear,0,0,0\n",
    )
    .unwrap();
    let e = read_csv(&path).unwrap_err().to_string();
    assert!(e.contains("go together"), "{e}");
}
