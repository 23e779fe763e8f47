//! The dynamic decoder against forcemap_msgs' generated types (serde + cdr-encoding, an
//! independent encoder), in both byte orders; the parser on the corners of the language.

use byteorder::BigEndian;
use forcemap_msgs::RosMessage;
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::DiagnosticStatus;
use forcemap_msgs::msg::{HarmonicPhasors, RigSample};
use forcemap_msgs::std_msgs::Header;
use serde::Serialize;

use super::parse::{ArrayKind, FieldType, Primitive};
use super::*;

fn big_endian<T: Serialize>(msg: &T) -> Vec<u8> {
    let mut out = forcemap_msgs::ENCAPSULATION_CDR_BE.to_vec();
    out.extend(cdr_encoding::to_vec::<T, BigEndian>(msg).unwrap());
    out
}

fn registry_of<M: RosMessage>() -> Registry {
    let reg = Registry::parse_schema(M::TYPE_NAME, &M::schema()).unwrap();
    reg.check(M::TYPE_NAME).unwrap();
    reg
}

fn num(v: &Value, path: &str) -> f64 {
    path.parse::<FieldPath>().unwrap().get(v).unwrap()
}

fn phasors() -> HarmonicPhasors {
    HarmonicPhasors {
        header: Header::new(Time { sec: 7, nanosec: 9 }, "rig"),
        step: 3,
        frequency_hz: 2.5,
        amplitude: 0.01,
        harmonic_orders: vec![1, 3, 5],
        channel_names: vec!["a".into(), "bc".into()],
        phasor_real: (0..6).map(|i| i as f64 * 0.5).collect(),
        phasor_imag: (0..6).map(|i| -(i as f64)).collect(),
        noise_std: vec![1e-3, 2e-3],
        residual_rms: vec![0.1, 0.2],
        periods_used: 11,
        periods_available: 12,
        first_settled_sample: 40,
        samples_used: 1000,
        harmonic_cap: 9,
        settled: true,
        t_ref: Time {
            sec: -2,
            nanosec: 999,
        },
    }
}

#[test]
fn rig_samples_decode_in_both_byte_orders() {
    let reg = registry_of::<RigSample>();
    let mut s = RigSample::new(Header::new(Time { sec: 5, nanosec: 6 }, "rig_frame"), 4);
    s.present_channels = 7;
    s.base_displacement_m = 0.25;
    s.force_n = -3.5;
    for bytes in [s.to_cdr(), big_endian(&s)] {
        let v = decode(&reg, RigSample::TYPE_NAME, &bytes).unwrap();
        assert_eq!(header_stamp_ns(&v), Some(5_000_000_006));
        assert_eq!(num(&v, "step"), 4.0);
        assert_eq!(num(&v, "present_channels"), 7.0);
        assert_eq!(num(&v, "base_displacement_m"), 0.25);
        assert_eq!(num(&v, "force_n"), -3.5);
        assert!(num(&v, "mass_displacement_m").is_nan());
        assert_eq!(
            v.field("header").and_then(|h| h.field("frame_id")),
            Some(&Value::String("rig_frame".into()))
        );
    }
    assert!(has_header(&reg, RigSample::TYPE_NAME));
}

#[test]
fn sequences_strings_and_bools_decode_in_both_byte_orders() {
    let reg = registry_of::<HarmonicPhasors>();
    let m = phasors();
    for bytes in [m.to_cdr(), big_endian(&m)] {
        let v = decode(&reg, HarmonicPhasors::TYPE_NAME, &bytes).unwrap();
        assert_eq!(num(&v, "harmonic_orders[2]"), 5.0);
        assert_eq!(num(&v, "phasor_imag[5]"), -5.0);
        assert_eq!(num(&v, "residual_rms[1]"), 0.2);
        assert_eq!(num(&v, "samples_used"), 1000.0);
        assert_eq!(num(&v, "t_ref.sec"), -2.0);
        assert_eq!(num(&v, "t_ref.nanosec"), 999.0);
        assert_eq!(v.field("settled"), Some(&Value::Bool(true)));
        assert_eq!(
            v.field("channel_names"),
            Some(&Value::Array(vec![
                Value::String("a".into()),
                Value::String("bc".into())
            ]))
        );
    }
    let status = DiagnosticStatus::new(DiagnosticStatus::OK, "n", "m", "hw")
        .with_value("mass_kg", 36.0)
        .with_value("k", "v");
    let reg = registry_of::<DiagnosticStatus>();
    for bytes in [status.to_cdr(), big_endian(&status)] {
        let v = decode(&reg, DiagnosticStatus::TYPE_NAME, &bytes).unwrap();
        let Some(Value::Array(values)) = v.field("values") else {
            panic!("{v:?}")
        };
        assert_eq!(values.len(), 2);
        assert_eq!(values[0].field("value"), Some(&Value::String("36".into())));
    }
}

#[test]
fn every_prefix_of_a_message_is_an_error_not_a_panic() {
    let reg = registry_of::<HarmonicPhasors>();
    let bytes = phasors().to_cdr();
    for n in 0..bytes.len() - 3 {
        assert!(
            decode(&reg, HarmonicPhasors::TYPE_NAME, &bytes[..n]).is_err(),
            "{n}"
        );
    }
    let mut long = bytes.clone();
    long.extend([0u8; 8]);
    assert!(matches!(
        decode(&reg, HarmonicPhasors::TYPE_NAME, &long),
        Err(DecodeError::TrailingBytes { count: 8, .. })
    ));
    let mut bad = bytes;
    bad[1] = 7;
    assert!(matches!(
        decode(&reg, HarmonicPhasors::TYPE_NAME, &bad),
        Err(DecodeError::BadEncapsulation { .. })
    ));
}

#[test]
fn a_huge_sequence_length_is_refused_before_allocating() {
    let mut reg = Registry::new();
    reg.insert(parse_msg("p/Big", "float64[] data").unwrap());
    let bytes = [0, 1, 0, 0, 0xff, 0xff, 0xff, 0xff, 0, 0, 0, 0];
    assert!(matches!(
        decode(&reg, "p/msg/Big", &bytes),
        Err(DecodeError::Truncated { .. })
    ));
}

#[test]
fn padding_follows_xcdr1_alignment() {
    // uint8, then float64 at body offset 8 (7 bytes of padding), then a string, then int16.
    let mut reg = Registry::new();
    reg.insert(parse_msg("p/Pad", "uint8 a\nfloat64 b\nstring c\nint16 d").unwrap());
    let mut bytes = vec![0, 1, 0, 0, 9, 0, 0, 0, 0, 0, 0, 0];
    bytes.extend(1.5f64.to_le_bytes());
    bytes.extend(3u32.to_le_bytes());
    bytes.extend(b"hi\0");
    bytes.push(0); // pad to 2
    bytes.extend((-4i16).to_le_bytes());
    let v = decode(&reg, "p/msg/Pad", &bytes).unwrap();
    assert_eq!(num(&v, "a"), 9.0);
    assert_eq!(num(&v, "b"), 1.5);
    assert_eq!(v.field("c"), Some(&Value::String("hi".into())));
    assert_eq!(num(&v, "d"), -4.0);
}

#[test]
fn the_language_corners_parse() {
    let def = parse_msg(
        "bench/State",
        "# comment\nint32 MODE_A=1\nstring NAME = \"x # y\"\n\
         Header header\nstring<=8 label \"a # b\"  # default then comment\n\
         float64[3] xyz [0, 0, 0]\nint16[<=4] spare\nbench_msgs/Other[] others\nOther one\n",
    )
    .unwrap();
    assert_eq!(def.name, "bench/msg/State");
    let f: Vec<(&str, &FieldType, ArrayKind)> = def
        .fields
        .iter()
        .map(|f| (f.name.as_str(), &f.ty, f.array))
        .collect();
    assert_eq!(
        f,
        [
            (
                "header",
                &FieldType::Message("std_msgs/msg/Header".into()),
                ArrayKind::Single
            ),
            (
                "label",
                &FieldType::Primitive(Primitive::String(Some(8))),
                ArrayKind::Single
            ),
            (
                "xyz",
                &FieldType::Primitive(Primitive::Float64),
                ArrayKind::Fixed(3)
            ),
            (
                "spare",
                &FieldType::Primitive(Primitive::Int16),
                ArrayKind::Bounded(4)
            ),
            (
                "others",
                &FieldType::Message("bench_msgs/msg/Other".into()),
                ArrayKind::Unbounded
            ),
            (
                "one",
                &FieldType::Message("bench/msg/Other".into()),
                ArrayKind::Single
            ),
        ]
    );
    // An empty message has ROS 2's one uint8.
    assert_eq!(parse_msg("p/Empty", "# nothing\n").unwrap().fields.len(), 1);
    for bad in [
        "float64[0] x",
        "float64[] ",
        "float64 2x",
        "int32<=3 x",
        "float64 x\nfloat64 x",
        "float64[ x",
        "p/q/r/s x",
    ] {
        assert!(parse_msg("p/Bad", bad).is_err(), "{bad}");
    }
}

#[test]
fn the_builtin_definitions_all_resolve() {
    let reg = builtin_registry();
    for (name, _) in builtin::BUILTIN_DEFINITIONS {
        reg.check(name).unwrap();
    }
    assert!(has_header(&reg, "sensor_msgs/msg/JointState"));
    assert!(!has_header(&reg, "std_msgs/msg/Float64MultiArray"));
}

#[test]
fn missing_and_recursive_types_are_refused() {
    let mut reg = Registry::new();
    reg.insert(parse_msg("p/A", "B b").unwrap());
    assert!(matches!(
        reg.check("p/msg/A"),
        Err(MsgError::Unresolved { .. })
    ));
    reg.insert(parse_msg("p/B", "A[] a").unwrap());
    assert!(matches!(reg.check("p/msg/A"), Err(MsgError::Recursive(_))));
}

#[test]
fn joint_names_select_elements() {
    let reg = builtin_registry();
    let v = Value::Message(vec![
        (
            "name".into(),
            Value::Array(vec![Value::String("l".into()), Value::String("r".into())]),
        ),
        (
            "position".into(),
            Value::Array(vec![Value::Float(1.0), Value::Float(2.0)]),
        ),
    ]);
    assert_eq!(num(&v, "position[r]"), 2.0);
    let p: FieldPath = "position[x]".parse().unwrap();
    assert_eq!(p.get(&v).unwrap_err(), "no 'x' among name [l, r]");
    let p: FieldPath = "position[5]".parse().unwrap();
    assert!(
        p.get(&v)
            .unwrap_err()
            .contains("the message has 2 elements")
    );
    let js = "sensor_msgs/msg/JointState";
    assert!(
        "position[r]"
            .parse::<FieldPath>()
            .unwrap()
            .check(&reg, js)
            .is_ok()
    );
    assert!(
        "position"
            .parse::<FieldPath>()
            .unwrap()
            .check(&reg, js)
            .is_err()
    );
    assert!(
        "name[0]"
            .parse::<FieldPath>()
            .unwrap()
            .check(&reg, js)
            .is_err()
    );
    let wrench = "geometry_msgs/msg/WrenchStamped";
    assert!(
        "wrench.force.z"
            .parse::<FieldPath>()
            .unwrap()
            .check(&reg, wrench)
            .is_ok()
    );
    assert!(
        "wrench.force"
            .parse::<FieldPath>()
            .unwrap()
            .check(&reg, wrench)
            .is_err()
    );
    assert!(
        "wrench.force.z.q"
            .parse::<FieldPath>()
            .unwrap()
            .check(&reg, wrench)
            .is_err()
    );
    for bad in ["", "a..b", "a[", "a[-1]", "a[1][2]", "1a", "a[]"] {
        assert!(bad.parse::<FieldPath>().is_err(), "{bad}");
    }
}
