//! Every message type encodes and decodes back to itself (NaN compared by bits).

mod common;

use forcemap_msgs::RosMessage;
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus, KeyValue};
use forcemap_msgs::msg::{ExcitationState, HarmonicPhasors, IdentifiedParameters, RigSample};
use forcemap_msgs::std_msgs::Header;

/// Decodes, checks the result with `same`, and checks re-encoding gives the same bytes.
fn round_trip<T: RosMessage + std::fmt::Debug>(msg: &T, same: impl Fn(&T, &T) -> bool) {
    let bytes = msg.to_cdr();
    assert_eq!(&bytes[..4], &[0, 1, 0, 0]);
    let back = T::from_cdr(&bytes).unwrap_or_else(|e| panic!("{}: {e}", T::TYPE_NAME));
    assert!(same(msg, &back), "{}: {msg:?} != {back:?}", T::TYPE_NAME);
    assert_eq!(
        back.to_cdr(),
        bytes,
        "{}: re-encoding differs",
        T::TYPE_NAME
    );
}

fn eq<T: PartialEq>(a: &T, b: &T) -> bool {
    a == b
}

fn f64_bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn rig_same(a: &RigSample, b: &RigSample) -> bool {
    let f = |s: &RigSample| {
        f64_bits(&[
            s.base_displacement_m,
            s.relative_displacement_m,
            s.mass_acceleration_mps2,
            s.mass_displacement_m,
            s.base_acceleration_mps2,
            s.force_n,
            s.drive_point_displacement_m,
        ])
    };
    a.header == b.header
        && a.step == b.step
        && a.present_channels == b.present_channels
        && f(a) == f(b)
}

fn excitation_same(a: &ExcitationState, b: &ExcitationState) -> bool {
    a.header == b.header
        && a.step == b.step
        && a.start_time == b.start_time
        && a.kind == b.kind
        && a.driven_channel == b.driven_channel
        && a.sample_count == b.sample_count
        && f64_bits(&[a.frequency_hz, a.amplitude, a.band_low_hz, a.band_high_hz])
            == f64_bits(&[b.frequency_hz, b.amplitude, b.band_low_hz, b.band_high_hz])
}

#[test]
fn time() {
    for t in [
        Time::ZERO,
        Time {
            sec: i32::MIN,
            nanosec: 999_999_999,
        },
        Time {
            sec: i32::MAX,
            nanosec: 1,
        },
    ] {
        round_trip(&t, eq);
    }
}

#[test]
fn header() {
    round_trip(&common::header("rig"), eq);
    round_trip(&Header::default(), eq);
    round_trip(&common::header("frame with ünïcode"), eq);
}

#[test]
fn diagnostics() {
    round_trip(&KeyValue::new("", ""), eq);
    round_trip(&KeyValue::new("key", "value"), eq);
    round_trip(&common::diagnostic_array().status[0], eq);
    round_trip(&common::diagnostic_array(), eq);
    round_trip(&DiagnosticArray::default(), eq);
    round_trip(&DiagnosticStatus::default(), eq);
}

#[test]
fn rig_sample() {
    round_trip(&common::rig_sample(), rig_same);
    round_trip(&common::three_dof_sample(), rig_same);
    round_trip(&RigSample::new(Header::default(), u32::MAX), rig_same);
}

#[test]
fn excitation_state() {
    round_trip(&common::excitation_sine(), excitation_same);
    round_trip(&common::excitation_random(), excitation_same);
}

#[test]
fn harmonic_phasors() {
    round_trip(&common::harmonic_phasors(), eq);
    let mut empty = common::harmonic_phasors();
    empty.harmonic_orders.clear();
    empty.channel_names.clear();
    empty.phasor_real.clear();
    empty.phasor_imag.clear();
    empty.noise_std.clear();
    empty.residual_rms.clear();
    empty.settled = false;
    round_trip(&empty, eq);
}

#[test]
fn identified_parameters() {
    round_trip(&common::identified_parameters(), eq);
    let mut m = common::identified_parameters();
    m.warnings.clear();
    m.steps_used.clear();
    round_trip(&m, eq);
}

#[test]
fn big_endian_input_decodes() {
    // The same Header as in golden.rs, written big endian with header 00 00 00 00.
    let be = [
        0, 0, 0, 0, 0xFF, 0xFF, 0xFF, 0xFE, 0x11, 0xE1, 0xA3, 0x00, 0, 0, 0, 4, b'r', b'i', b'g', 0,
    ];
    let h = Header::from_cdr(&be).unwrap();
    assert_eq!(
        h,
        Header::new(
            Time {
                sec: -2,
                nanosec: 300_000_000
            },
            "rig"
        )
    );
}

#[test]
fn trailing_padding_up_to_three_bytes_is_accepted() {
    let mut bytes = KeyValue::new("k", "v1").to_cdr(); // 19 bytes
    bytes.push(0);
    assert_eq!(
        KeyValue::from_cdr(&bytes).unwrap(),
        KeyValue::new("k", "v1")
    );
}

#[test]
fn type_names() {
    assert_eq!(RigSample::TYPE_NAME, "forcemap_msgs/msg/RigSample");
    assert_eq!(
        ExcitationState::TYPE_NAME,
        "forcemap_msgs/msg/ExcitationState"
    );
    assert_eq!(
        HarmonicPhasors::TYPE_NAME,
        "forcemap_msgs/msg/HarmonicPhasors"
    );
    assert_eq!(
        IdentifiedParameters::TYPE_NAME,
        "forcemap_msgs/msg/IdentifiedParameters"
    );
    assert_eq!(Time::TYPE_NAME, "builtin_interfaces/msg/Time");
    assert_eq!(Header::TYPE_NAME, "std_msgs/msg/Header");
    assert_eq!(
        DiagnosticArray::TYPE_NAME,
        "diagnostic_msgs/msg/DiagnosticArray"
    );
    assert_eq!(
        DiagnosticStatus::TYPE_NAME,
        "diagnostic_msgs/msg/DiagnosticStatus"
    );
    assert_eq!(KeyValue::TYPE_NAME, "diagnostic_msgs/msg/KeyValue");
    assert_eq!(RigSample::DEFINITION.type_name(), RigSample::TYPE_NAME);
    assert_eq!(
        DiagnosticArray::DEFINITION.type_name(),
        DiagnosticArray::TYPE_NAME
    );
}

#[test]
fn diagnostic_levels() {
    assert_eq!(
        [
            DiagnosticStatus::OK,
            DiagnosticStatus::WARN,
            DiagnosticStatus::ERROR,
            DiagnosticStatus::STALE
        ],
        [0u8, 1, 2, 3]
    );
}
