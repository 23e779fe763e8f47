//! Independent reader: rosbags (Python) decodes the CDR bytes written here and compares the
//! fields; see tests/python/check_cdr.py. Runs when FORCEMAP_PYTHON names a python with rosbags
//! installed, otherwise says it skipped. FORCEMAP_CDR_DIR keeps the files in that directory.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use forcemap_math::record::Channel;
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus, KeyValue};
use forcemap_msgs::msg::{
    AxisSample, ExcitationState, GapDiagnosis, HarmonicPhasors, IdentifiedParameters, RigSample,
};
use forcemap_msgs::std_msgs::Header;
use forcemap_msgs::{MsgDef, RosMessage};
use serde_json::{Value, json};

struct Cases {
    dir: PathBuf,
    cases: Vec<Value>,
}

impl Cases {
    fn add<T: RosMessage>(&mut self, name: &str, msg: &T) {
        let cdr = format!("{name}.cdr");
        let schema = format!("{name}.schema");
        std::fs::write(self.dir.join(&cdr), msg.to_cdr()).unwrap();
        std::fs::write(self.dir.join(&schema), T::schema()).unwrap();
        self.cases.push(json!({
            "name": name,
            "type": T::TYPE_NAME,
            "cdr": cdr,
            "schema": schema,
            // Field names are the .msg names; NaN becomes null.
            "expected": serde_json::to_value(msg).unwrap(),
        }));
    }
}

fn msg_file(def: &MsgDef, root: &Path) -> Value {
    let ty = def.type_name();
    let (pkg, name) = def.name.split_once('/').unwrap();
    let path = if pkg == "forcemap_msgs" {
        root.join("msg").join(format!("{name}.msg"))
    } else {
        root.join("deps")
            .join(pkg)
            .join("msg")
            .join(format!("{name}.msg"))
    };
    assert!(path.exists(), "{}", path.display());
    json!({"type": ty, "path": path})
}

/// AxisSample as the EMPS importer writes it (velocity and acceleration not measured: NaN), with
/// every field finite, and with values whose bits a careless decoder would change (-0.0, the
/// smallest subnormal, the largest finite, values that are not short decimals).
fn axis_samples() -> Vec<(&'static str, AxisSample)> {
    let stamp = Time {
        sec: 1_541_462_400,
        nanosec: 999_999_999,
    };
    let emps = AxisSample {
        position_m: 0.031_415_926_535,
        reference_position_m: 0.03,
        force_n: -12.5 * 35.155_6,
        drive_input: -12.5,
        ..AxisSample::new(Header::new(stamp, "emps"))
    };
    let finite = AxisSample {
        header: Header::new(stamp, "axis µ"),
        position_m: -0.25,
        velocity_mps: 0.1,
        acceleration_mps2: -9.806_65,
        reference_position_m: 1.0 / 3.0,
        force_n: 70.0,
        drive_input: 2.0,
    };
    let edges = AxisSample {
        header: Header::new(Time { sec: 0, nanosec: 0 }, ""),
        position_m: -0.0,
        velocity_mps: f64::from_bits(1),
        acceleration_mps2: f64::MAX,
        reference_position_m: f64::MIN_POSITIVE,
        force_n: -f64::MAX,
        drive_input: 1e-300,
    };
    vec![
        ("axis_sample_emps", emps),
        ("axis_sample_finite", finite),
        ("axis_sample_edges", edges),
    ]
}

fn write_cases(dir: &Path) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut c = Cases {
        dir: dir.to_path_buf(),
        cases: vec![],
    };
    c.add(
        "time",
        &Time {
            sec: -2,
            nanosec: 300_000_000,
        },
    );
    c.add("header", &common::header("rig"));
    c.add("header_unicode", &common::header("präzisions-rig µ"));
    c.add("key_value", &KeyValue::new("k", "v1"));
    c.add("diagnostic_status", &common::diagnostic_array().status[0]);
    c.add("diagnostic_array", &common::diagnostic_array());
    c.add("diagnostic_array_empty", &DiagnosticArray::default());
    c.add("rig_sample", &common::rig_sample());
    c.add("rig_sample_three_dof", &common::three_dof_sample());
    let mut all = RigSample::new(common::header("ab"), 7);
    for (i, ch) in Channel::ALL.into_iter().enumerate() {
        all.set_channel(ch, Some(0.5 + i as f64));
    }
    c.add("rig_sample_all_channels", &all);
    c.add("excitation_sine", &common::excitation_sine());
    c.add("excitation_random", &common::excitation_random());
    c.add("harmonic_phasors", &common::harmonic_phasors());
    c.add("identified_parameters", &common::identified_parameters());
    for (name, sample) in axis_samples() {
        c.add(name, &sample);
    }
    c.add(
        "gap_diagnosis",
        &GapDiagnosis {
            header: common::header("rig"),
            baseline_model: "linear".into(),
            steps: 10,
            verdict: "explained".into(),
            top_effect: "coulomb_friction".into(),
            gap_before_percent: 11.0,
            gap_after_percent: 4.0,
            noise_floor_percent: 0.5,
            ranked_effects: vec!["coulomb_friction".into(), "quadratic_damping".into()],
            ranked_gap_after_percent: vec![4.0, 8.25],
            ranked_significant: vec![true, false],
        },
    );
    let idle = ExcitationState::idle(
        common::header("rig"),
        10,
        Time { sec: 5, nanosec: 7 },
        Channel::BaseDisplacementM,
    );
    c.add("excitation_idle", &idle);

    let defs = [
        Time::DEFINITION,
        Header::DEFINITION,
        KeyValue::DEFINITION,
        DiagnosticStatus::DEFINITION,
        DiagnosticArray::DEFINITION,
        RigSample::DEFINITION,
        ExcitationState::DEFINITION,
        HarmonicPhasors::DEFINITION,
        IdentifiedParameters::DEFINITION,
        AxisSample::DEFINITION,
        GapDiagnosis::DEFINITION,
    ];
    let manifest = json!({
        "msg_files": defs.iter().map(|d| msg_file(d, root)).collect::<Vec<_>>(),
        "constants": {
            "forcemap_msgs/msg/RigSample": {
                "BASE_DISPLACEMENT": RigSample::BASE_DISPLACEMENT,
                "RELATIVE_DISPLACEMENT": RigSample::RELATIVE_DISPLACEMENT,
                "MASS_ACCELERATION": RigSample::MASS_ACCELERATION,
                "MASS_DISPLACEMENT": RigSample::MASS_DISPLACEMENT,
                "BASE_ACCELERATION": RigSample::BASE_ACCELERATION,
                "FORCE": RigSample::FORCE,
                "DRIVE_POINT_DISPLACEMENT": RigSample::DRIVE_POINT_DISPLACEMENT,
            },
            "forcemap_msgs/msg/ExcitationState": {
                "SINE": ExcitationState::SINE,
                "RANDOM": ExcitationState::RANDOM,
                "IDLE": ExcitationState::IDLE,
                "SWEEP_LINEAR": ExcitationState::SWEEP_LINEAR,
                "SWEEP_LOG": ExcitationState::SWEEP_LOG,
                "MULTISINE": ExcitationState::MULTISINE,
            },
            "diagnostic_msgs/msg/DiagnosticStatus": {
                "OK": DiagnosticStatus::OK,
                "WARN": DiagnosticStatus::WARN,
                "ERROR": DiagnosticStatus::ERROR,
                "STALE": DiagnosticStatus::STALE,
            },
        },
        "cases": c.cases,
    });
    std::fs::write(
        dir.join("manifest.json"),
        serde_json::to_string_pretty(&manifest).unwrap(),
    )
    .unwrap();
}

#[test]
fn rosbags_reads_what_rust_writes() {
    let Some(python) = std::env::var_os("FORCEMAP_PYTHON") else {
        // CI installs rosbags (.ci/run): there a missing interpreter is a failure.
        assert!(
            std::env::var_os("CI").is_none(),
            "CI is set but FORCEMAP_PYTHON is not: the independent reader did not run"
        );
        println!(
            "SKIPPED rosbags_reads_what_rust_writes: set FORCEMAP_PYTHON to a python with rosbags \
             installed (e.g. FORCEMAP_PYTHON=/work/venv-msgs/bin/python)"
        );
        return;
    };
    let tmp;
    let dir = match std::env::var_os("FORCEMAP_CDR_DIR") {
        Some(d) => {
            std::fs::create_dir_all(&d).unwrap();
            PathBuf::from(d)
        }
        None => {
            tmp = tempfile::tempdir().unwrap();
            tmp.path().to_path_buf()
        }
    };
    write_cases(&dir);
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/check_cdr.py");
    let out = Command::new(&python)
        .arg(&script)
        .env("FORCEMAP_CDR_DIR", &dir)
        .output()
        .unwrap_or_else(|e| panic!("cannot run FORCEMAP_PYTHON={python:?}: {e}"));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    println!("{stdout}");
    eprintln!("{stderr}");
    assert!(
        out.status.success(),
        "check_cdr.py failed ({}):\n{stdout}\n{stderr}",
        out.status
    );
}
