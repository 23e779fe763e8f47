//! CDR bytes worked out by hand (XCDR1 little endian: 4-byte header 00 01 00 00, each field
//! aligned to its size counted after the header, strings as u32 length with NUL + bytes + NUL).
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use forcemap_msgs::RosMessage;
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::{DiagnosticStatus, KeyValue};
use forcemap_msgs::msg::{ExcitationState, RigSample};
use forcemap_msgs::std_msgs::Header;

fn check<T: RosMessage + PartialEq + std::fmt::Debug>(msg: &T, expected: &[u8]) {
    let bytes = msg.to_cdr();
    assert_eq!(bytes, expected, "{}: encoded bytes differ", T::TYPE_NAME);
    assert_eq!(&T::from_cdr(expected).unwrap(), msg);
}

#[test]
fn time() {
    // 500_000_000 = 0x1DCD6500
    check(
        &Time {
            sec: 1,
            nanosec: 500_000_000,
        },
        &[0, 1, 0, 0, 1, 0, 0, 0, 0x00, 0x65, 0xCD, 0x1D],
    );
}

#[test]
fn header_short_frame_id() {
    // -2 s + 0.3 s; 300_000_000 = 0x11E1A300; "rig" = length 4 (with NUL).
    check(
        &Header::new(
            Time {
                sec: -2,
                nanosec: 300_000_000,
            },
            "rig",
        ),
        &[
            0, 1, 0, 0, // encapsulation
            0xFE, 0xFF, 0xFF, 0xFF, // sec
            0x00, 0xA3, 0xE1, 0x11, // nanosec
            4, 0, 0, 0, b'r', b'i', b'g', 0, // frame_id
        ],
    );
}

#[test]
fn key_value_with_padding() {
    check(
        &KeyValue::new("k", "v1"),
        &[
            0, 1, 0, 0, // encapsulation
            2, 0, 0, 0, b'k', 0, // key (body offset 0..6)
            0, 0, // pad to 8
            3, 0, 0, 0, b'v', b'1', 0, // value
        ],
    );
}

#[test]
fn diagnostic_status_byte_then_strings() {
    let mut s = DiagnosticStatus::new(DiagnosticStatus::WARN, "a", "", "h");
    s.values.push(KeyValue::new("k", "v"));
    check(
        &s,
        &[
            0, 1, 0, 0, // encapsulation
            1, // level WARN (body 0)
            0, 0, 0, // pad to 4
            2, 0, 0, 0, b'a', 0, // name
            0, 0, // pad to 12
            1, 0, 0, 0, 0, // message "" = length 1, NUL
            0, 0, 0, // pad to 20
            2, 0, 0, 0, b'h', 0, // hardware_id
            0, 0, // pad to 28
            1, 0, 0, 0, // values: 1 element
            2, 0, 0, 0, b'k', 0, // key
            0, 0, // pad to 40
            2, 0, 0, 0, b'v', 0, // value
        ],
    );
}

#[test]
fn excitation_state_padding_before_float64() {
    let msg = ExcitationState {
        header: Header::new(Time { sec: 7, nanosec: 0 }, "ab"),
        step: 3,
        start_time: Time { sec: 5, nanosec: 1 },
        kind: ExcitationState::RANDOM,
        driven_channel: "force_n".into(),
        frequency_hz: 0.0,
        amplitude: 2.0,
        band_low_hz: 0.5,
        band_high_hz: 1.5,
        sample_count: 1300,
    };
    let expected: &[u8] = &[
        0, 1, 0, 0, // encapsulation
        7, 0, 0, 0, 0, 0, 0, 0, // header.stamp (body 0..8)
        3, 0, 0, 0, b'a', b'b', 0, // frame_id (8..15)
        0, // pad to 16
        3, 0, 0, 0, // step
        5, 0, 0, 0, 1, 0, 0, 0, // start_time (20..28)
        1, // kind RANDOM (28)
        0, 0, 0, // pad to 32
        8, 0, 0, 0, b'f', b'o', b'r', b'c', b'e', b'_', b'n', 0, // driven_channel (32..44)
        0, 0, 0, 0, // pad to 48
        0, 0, 0, 0, 0, 0, 0, 0, // frequency_hz 0.0
        0, 0, 0, 0, 0, 0, 0, 0x40, // amplitude 2.0
        0, 0, 0, 0, 0, 0, 0xE0, 0x3F, // band_low_hz 0.5
        0, 0, 0, 0, 0, 0, 0xF8, 0x3F, // band_high_hz 1.5
        0x14, 0x05, 0, 0, // sample_count 1300 (4-aligned after a float64)
    ];
    check(&msg, expected);
}

#[test]
fn rig_sample_nan_for_absent_channels() {
    use forcemap_math::record::Channel;
    let msg = RigSample::new(Header::new(Time::ZERO, "ab"), 1)
        .with(Channel::RelativeDisplacementM, -1.0)
        .with(Channel::ForceN, 2.0);
    let nan = [0, 0, 0, 0, 0, 0, 0xF8, 0x7F];
    let mut expected: Vec<u8> = vec![
        0,
        1,
        0,
        0, // encapsulation
        0,
        0,
        0,
        0,
        0,
        0,
        0,
        0, // stamp
        3,
        0,
        0,
        0,
        b'a',
        b'b',
        0, // frame_id (body 8..15)
        0, // pad to 16
        1,
        0,
        0,
        0, // step
        2 | 32,
        0,
        0,
        0, // present_channels (24 is aligned for float64)
    ];
    expected.extend(nan); // base_displacement_m
    expected.extend([0, 0, 0, 0, 0, 0, 0xF0, 0xBF]); // relative_displacement_m -1.0
    expected.extend(nan); // mass_acceleration_mps2
    expected.extend(nan); // mass_displacement_m
    expected.extend(nan); // base_acceleration_mps2
    expected.extend([0, 0, 0, 0, 0, 0, 0, 0x40]); // force_n 2.0
    expected.extend(nan); // drive_point_displacement_m
    assert_eq!(msg.to_cdr(), expected);
    let back = RigSample::from_cdr(&expected).unwrap();
    assert_eq!(
        back.present_channels,
        RigSample::RELATIVE_DISPLACEMENT | RigSample::FORCE
    );
    assert_eq!(back.channel(Channel::ForceN), Some(2.0));
    assert_eq!(back.channel(Channel::MassAccelerationMps2), None);
    assert!(back.mass_acceleration_mps2.is_nan());
}
