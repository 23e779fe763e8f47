//! Writes the seed inputs of the fuzz targets: `cargo run --example gen_seeds -- OUT_DIR`
//! writes OUT_DIR/{cdr_decode,bag_read,csv_import}/*. Run by `fuzz/run.sh`.
use std::fs;
use std::path::{Path, PathBuf};

use forcemap_msgs::RosMessage;
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus, KeyValue};
use forcemap_msgs::msg::{
    AxisSample, ExcitationState, HarmonicPhasors, IdentifiedParameters, RigSample,
};
use forcemap_msgs::std_msgs::Header;
use forcemap_io::bag::{BagWriter, BagWriterOptions, TopicSpec};

fn write(dir: &Path, name: &str, bytes: &[u8]) {
    fs::create_dir_all(dir).unwrap();
    fs::write(dir.join(name), bytes).unwrap();
}

fn header() -> Header {
    Header::new(
        Time {
            sec: 1_700_000_000,
            nanosec: 250_000_000,
        },
        "rig",
    )
}

fn rig_sample() -> RigSample {
    let mut m = RigSample::new(header(), 3);
    m.present_channels = 0b111;
    m.base_displacement_m = 1e-3;
    m.relative_displacement_m = -2e-5;
    m.mass_acceleration_mps2 = 0.25;
    m
}

fn excitation_state() -> ExcitationState {
    ExcitationState {
        header: header(),
        step: 3,
        start_time: Time { sec: 12, nanosec: 5 },
        kind: ExcitationState::SINE,
        driven_channel: "base_displacement_m".into(),
        frequency_hz: 12.5,
        amplitude: 0.002,
        band_low_hz: f64::NAN,
        band_high_hz: f64::NAN,
        sample_count: 1300,
    }
}

fn harmonic_phasors() -> HarmonicPhasors {
    HarmonicPhasors {
        header: header(),
        step: 3,
        frequency_hz: 12.5,
        amplitude: 0.002,
        harmonic_orders: vec![0, 1, 2],
        channel_names: vec![
            "base_displacement_m".into(),
            "relative_displacement_m".into(),
        ],
        phasor_real: vec![0.0, 1e-3, 2e-5, 0.0, 4e-4, 1e-6],
        phasor_imag: vec![0.0, -1e-4, 3e-6, 0.0, 2e-4, -1e-7],
        noise_std: vec![1e-8; 6],
        residual_rms: vec![1e-7, 2e-7],
        periods_used: 10,
        periods_available: 12,
        first_settled_sample: 160,
        samples_used: 800,
        harmonic_cap: 2,
        settled: true,
        t_ref: Time { sec: 14, nanosec: 0 },
    }
}

fn identified_parameters() -> IdentifiedParameters {
    IdentifiedParameters {
        header: header(),
        model: "sdof".into(),
        method: "lstsq".into(),
        parameter_names: vec!["m".into(), "k".into()],
        values: vec![1.5, 2.0e4],
        standard_deviations: vec![0.01, 50.0],
        covariance: vec![1e-4, 0.1, 0.1, 2500.0],
        r_percent: vec![0.6, 0.25],
        equations: 40,
        condition_number: 123.0,
        residual_rms: 1e-6,
        steps_used: vec![0, 1, 2],
        warnings: vec!["few steps".into()],
    }
}

fn diagnostic_array() -> DiagnosticArray {
    DiagnosticArray {
        header: header(),
        status: vec![
            DiagnosticStatus::new(DiagnosticStatus::WARN, "rig: daq", "late samples", "daq0")
                .with_value("late", 3)
                .with_value("rate_hz", 1000.0),
        ],
    }
}

/// The same message with a big-endian encapsulation (the decoder accepts both).
fn big_endian<T: serde::Serialize>(msg: &T) -> Vec<u8> {
    let mut v = vec![0x00, 0x00, 0x00, 0x00];
    v.extend(cdr_encoding::to_vec::<T, byteorder::BigEndian>(msg).unwrap());
    v
}

fn cdr_seeds(dir: &Path) {
    write(dir, "time.cdr", &Time { sec: -2, nanosec: 300_000_000 }.to_cdr());
    write(dir, "header.cdr", &header().to_cdr());
    write(dir, "key_value.cdr", &KeyValue::new("late", "3").to_cdr());
    let status = diagnostic_array().status.remove(0);
    write(dir, "diagnostic_status.cdr", &status.to_cdr());
    write(dir, "diagnostic_array.cdr", &diagnostic_array().to_cdr());
    write(dir, "rig_sample.cdr", &rig_sample().to_cdr());
    write(dir, "excitation_state.cdr", &excitation_state().to_cdr());
    write(dir, "harmonic_phasors.cdr", &harmonic_phasors().to_cdr());
    write(dir, "identified_parameters.cdr", &identified_parameters().to_cdr());
    let axis = AxisSample {
        header: header(),
        position_m: 0.1,
        velocity_mps: f64::NAN,
        acceleration_mps2: f64::NAN,
        reference_position_m: 0.1002,
        force_n: 12.0,
        drive_input: 0.34,
    };
    write(dir, "axis_sample.cdr", &axis.to_cdr());
    write(dir, "rig_sample_be.cdr", &big_endian(&rig_sample()));
    write(dir, "harmonic_phasors_be.cdr", &big_endian(&harmonic_phasors()));
}

/// A bag with three topics (short schemas so the file stays small); returns its .mcap.
fn small_bag(tmp: &Path, name: &str, zstd: bool, real_schemas: bool) -> PathBuf {
    let dir = tmp.join(name);
    let mut w = BagWriter::create_with(
        &dir,
        BagWriterOptions {
            zstd,
            max_chunk_age: None,
            ros_distro: "jazzy".into(),
            ..BagWriterOptions::default()
        },
    )
    .unwrap();
    let schema = |full: String| if real_schemas { full } else { "float64 x\n".to_string() };
    let rig = w
        .add_topic(&TopicSpec::new(
            "/rig/sample",
            RigSample::TYPE_NAME,
            &schema(RigSample::schema()),
        ))
        .unwrap();
    let exc = w
        .add_topic(&TopicSpec::new(
            "/rig/excitation",
            ExcitationState::TYPE_NAME,
            &schema(ExcitationState::schema()),
        ))
        .unwrap();
    let diag = w
        .add_topic(&TopicSpec::new(
            "/diagnostics",
            DiagnosticArray::TYPE_NAME,
            &schema(DiagnosticArray::schema()),
        ))
        .unwrap();
    let t0 = 1_700_000_000_000_000_000u64;
    w.write(exc, t0, t0, &excitation_state().to_cdr()).unwrap();
    for i in 0..4u64 {
        let t = t0 + i * 1_000_000;
        // one message out of log-time order
        let t = if i == 2 { t - 1_500_000 } else { t };
        w.write(rig, t, t - 1000, &rig_sample().to_cdr()).unwrap();
        if i == 1 {
            w.flush_chunk().unwrap();
        }
    }
    w.write(diag, t0 + 5_000_000, t0 + 5_000_000, &diagnostic_array().to_cdr())
        .unwrap();
    let out = w.finish().unwrap();
    let mcap: Vec<PathBuf> = fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "mcap"))
        .collect();
    assert_eq!(mcap.len(), 1, "one .mcap in {}", out.display());
    mcap[0].clone()
}

fn bag_seeds(dir: &Path) {
    let tmp = tempfile::tempdir().unwrap();
    let plain = fs::read(small_bag(tmp.path(), "plain", false, false)).unwrap();
    let zstd = fs::read(small_bag(tmp.path(), "zstd", true, false)).unwrap();
    let real = fs::read(small_bag(tmp.path(), "real", true, true)).unwrap();
    write(dir, "plain.mcap", &plain);
    write(dir, "zstd.mcap", &zstd);
    write(dir, "real_schemas.mcap", &real);
    // A recorder that died: no summary or footer (the recover path and the scanning reader).
    write(dir, "plain_cut.mcap", &plain[..plain.len() * 2 / 3]);
    write(dir, "zstd_cut.mcap", &zstd[..zstd.len() * 2 / 3]);
}

fn csv_seeds(dir: &Path) {
    // Rig profile, two sine steps, 1 kHz, fixed-decimals time, an ignored column.
    let mut rig = String::from(
        "time_s,step,frequency_hz,base_displacement_m,relative_displacement_m,mass_acceleration_mps2,comment\n",
    );
    for i in 0..8 {
        let step = i / 4;
        let f = if step == 0 { "10" } else { "12.5" };
        let x = (i as f64 * 0.3).sin() * 1e-3;
        rig += &format!("{:.6},{step},{f},{x},1e-5,-0.25,ok\n", i as f64 / 1000.0);
    }
    write(dir, "rig.csv", rig.as_bytes());
    // Drive-point profile, one random step (empty frequency), optional force column order.
    let mut dp = String::from(
        "time_s,step,frequency_hz,force_n,relative_displacement_m,drive_point_displacement_m\n",
    );
    for i in 0..5 {
        let x = (i as f64 * 0.7).cos();
        dp += &format!("{},{},,{x},{},{}\n", i as f64 * 0.002, 3, x * 1e-4, -x * 2e-4);
    }
    write(dir, "drive_point.csv", dp.as_bytes());
    // Every channel column, one sine step, CRLF line ends and quoted cells.
    let mut all = String::from(
        "\"time_s\",step,frequency_hz,base_displacement_m,relative_displacement_m,mass_acceleration_mps2,mass_displacement_m,base_acceleration_mps2,force_n,drive_point_displacement_m\r\n",
    );
    for i in 0..3 {
        all += &format!(
            "{},0,\"5\",1e-3,{},0.5,-1e-3,2.0,{},0\r\n",
            i as f64 * 0.01,
            i as f64 * 1e-6,
            i as f64
        );
    }
    write(dir, "all_channels.csv", all.as_bytes());
}

fn main() {
    let out = PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "seeds".into()));
    cdr_seeds(&out.join("cdr_decode"));
    bag_seeds(&out.join("bag_read"));
    csv_seeds(&out.join("csv_import"));
    // Check the seeds are what they claim: every one decodes / opens / imports.
    for (name, bytes) in [
        ("rig.csv", fs::read(out.join("csv_import/rig.csv")).unwrap()),
        ("drive_point.csv", fs::read(out.join("csv_import/drive_point.csv")).unwrap()),
        ("all_channels.csv", fs::read(out.join("csv_import/all_channels.csv")).unwrap()),
    ] {
        if let Err(e) = forcemap_io::csv_export::read_csv_from(&bytes[..], Path::new(name)) {
            panic!("seed {name} does not import: {e}");
        }
    }
    for name in ["plain.mcap", "zstd.mcap", "real_schemas.mcap"] {
        let bag = forcemap_io::bag::BagReader::open(out.join("bag_read").join(name))
            .unwrap_or_else(|e| panic!("seed {name} does not open: {e}"));
        assert_eq!(bag.summary().message_count, 6, "{name}");
    }
    for (name, ok) in [
        ("time.cdr", Time::from_cdr(&fs::read(out.join("cdr_decode/time.cdr")).unwrap()).is_ok()),
        (
            "harmonic_phasors_be.cdr",
            HarmonicPhasors::from_cdr(&fs::read(out.join("cdr_decode/harmonic_phasors_be.cdr")).unwrap())
                .is_ok(),
        ),
        (
            "identified_parameters.cdr",
            IdentifiedParameters::from_cdr(
                &fs::read(out.join("cdr_decode/identified_parameters.cdr")).unwrap(),
            )
            .is_ok(),
        ),
    ] {
        assert!(ok, "seed {name} does not decode");
    }
    println!("seeds written to {}", out.display());
}
