//! forcemap_msgs/msg/AxisSample: round trip, CDR bytes worked out by hand, and schema text.
use forcemap_msgs::RosMessage;
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::msg::{ALL, AXIS_SAMPLE_DEF, AxisSample};
use forcemap_msgs::std_msgs::Header;
use forcemap_msgs::{ENCAPSULATION_CDR_LE, SEPARATOR};

fn sample() -> AxisSample {
    AxisSample {
        header: Header::new(
            Time {
                sec: 1_541_462_400,
                nanosec: 1_000_000,
            },
            "emps",
        ),
        position_m: 0.25,
        velocity_mps: f64::NAN,
        acceleration_mps2: f64::NAN,
        reference_position_m: -0.5,
        force_n: 70.0,
        drive_input: 2.0,
    }
}

#[test]
fn golden_bytes() {
    let mut expected = vec![0, 1, 0, 0];
    expected.extend_from_slice(&1_541_462_400i32.to_le_bytes()); // stamp.sec (body 0)
    expected.extend_from_slice(&1_000_000u32.to_le_bytes()); // stamp.nanosec (4)
    expected.extend_from_slice(&[5, 0, 0, 0, b'e', b'm', b'p', b's', 0]); // frame_id (8..17)
    expected.extend_from_slice(&[0; 7]); // pad to 24 for the first float64
    for v in [0.25, f64::NAN, f64::NAN, -0.5, 70.0, 2.0] {
        expected.extend_from_slice(&v.to_le_bytes());
    }
    assert_eq!(expected.len(), 4 + 24 + 48);
    let bytes = sample().to_cdr();
    assert_eq!(bytes, expected);
    assert_eq!(&bytes[..4], &ENCAPSULATION_CDR_LE);
}

#[test]
fn round_trip_keeps_nan_and_values() {
    let s = sample();
    let back = AxisSample::from_cdr(&s.to_cdr()).unwrap();
    // NaN != NaN: compare the bits.
    assert_eq!(back.header, s.header);
    for (a, b) in [
        (back.position_m, s.position_m),
        (back.velocity_mps, s.velocity_mps),
        (back.acceleration_mps2, s.acceleration_mps2),
        (back.reference_position_m, s.reference_position_m),
        (back.force_n, s.force_n),
        (back.drive_input, s.drive_input),
    ] {
        assert_eq!(a.to_bits(), b.to_bits());
    }
    let finite = AxisSample {
        velocity_mps: 0.1,
        acceleration_mps2: -3.0,
        ..sample()
    };
    assert_eq!(AxisSample::from_cdr(&finite.to_cdr()).unwrap(), finite);
    // Truncated bytes are an error, not garbage.
    let bytes = finite.to_cdr();
    assert!(AxisSample::from_cdr(&bytes[..bytes.len() - 3]).is_err());
}

#[test]
fn new_is_all_nan() {
    let s = AxisSample::new(Header::default());
    for v in [
        s.position_m,
        s.velocity_mps,
        s.acceleration_mps2,
        s.reference_position_m,
        s.force_n,
        s.drive_input,
    ] {
        assert!(v.is_nan());
    }
}

#[test]
fn schema_text() {
    assert_eq!(AxisSample::TYPE_NAME, "forcemap_msgs/msg/AxisSample");
    assert_eq!(AXIS_SAMPLE_DEF.type_name(), AxisSample::TYPE_NAME);
    assert!(ALL.contains(&AXIS_SAMPLE_DEF));
    let msg = include_str!("../msg/AxisSample.msg");
    let schema = AxisSample::schema();
    let expected = format!(
        "{}\n{SEPARATOR}\nMSG: std_msgs/Header\n{}\n{SEPARATOR}\nMSG: builtin_interfaces/Time\n{}\n",
        msg.trim_end(),
        include_str!("../deps/std_msgs/msg/Header.msg").trim_end(),
        include_str!("../deps/builtin_interfaces/msg/Time.msg").trim_end(),
    );
    assert_eq!(schema, expected);
    // The fields, in order, as the Rust struct has them.
    let fields: Vec<&str> = msg
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .collect();
    assert_eq!(
        fields,
        [
            "std_msgs/Header header",
            "float64 position_m",
            "float64 velocity_mps",
            "float64 acceleration_mps2",
            "float64 reference_position_m",
            "float64 force_n",
            "float64 drive_input",
        ]
    );
}
