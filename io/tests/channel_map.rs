//! The channel map: both file forms read to the same map; each mistake is named with its
//! entry.

use forcemap_io::channel_map::{ChannelMap, MapFile};
use forcemap_io::table_map::{ColumnRef, Separator, TimeSource};
use forcemap_math::record::Channel;

const OWN_FILE: &str = "channels:
  force_n: {topic: /dyno/load_cell, field: wrench.force.z, offset: -1.5}
  relative_displacement_m: {topic: /dyno/stroke, field: 'data[0]', scale: 0.001}
  step: {topic: /dyno/state, field: step}
  frequency_hz: {topic: /dyno/state, field: frequency_hz}
";

const PARAMS_FILE: &str = "/**:
  ros__parameters:
    mass_kg: 36.0
    channels:
      force_n: {topic: /dyno/load_cell, field: wrench.force.z, offset: -1.5}
      relative_displacement_m: {topic: /dyno/stroke, field: 'data[0]', scale: 0.001}
      step: {topic: /dyno/state, field: step}
      frequency_hz: {topic: /dyno/state, field: frequency_hz}
";

#[test]
fn both_forms_read_to_the_same_map() {
    let a = ChannelMap::from_yaml_str(OWN_FILE, "m").unwrap();
    let b = ChannelMap::from_yaml_str(PARAMS_FILE, "m").unwrap();
    assert_eq!(a, b);
    // Channel::ALL order, whatever the file's.
    let names: Vec<Channel> = a.channels.iter().map(|(c, _)| *c).collect();
    assert_eq!(names, [Channel::RelativeDisplacementM, Channel::ForceN]);
    let (_, stroke) = &a.channels[0];
    assert_eq!((stroke.scale, stroke.offset), (0.001, 0.0));
    assert_eq!(stroke.apply(2000.0), 2.0);
    assert_eq!(a.channels[1].1.apply(10.0), 8.5);
    assert_eq!(a.step.as_ref().unwrap().field.text, "step");
}

#[test]
fn definitions_resolve_against_the_maps_folder() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("map.yaml");
    std::fs::write(
        &path,
        format!("{OWN_FILE}definitions:\n  bench_msgs/msg/State: msg/State.msg\n"),
    )
    .unwrap();
    let map = ChannelMap::read(&path).unwrap();
    assert_eq!(
        map.definitions["bench_msgs/msg/State"],
        dir.path().join("msg/State.msg")
    );
}

fn error(text: &str) -> String {
    ChannelMap::from_yaml_str(text, "map.yaml")
        .expect_err("the map is refused")
        .to_string()
}

#[test]
fn mistakes_are_named_with_their_entry() {
    let cases = [
        (
            "channels:\n  force: {topic: /a, field: x}\n",
            "map.yaml: 'force': not a forcemap channel or label; expected one of base_displacement_m",
        ),
        (
            "channels:\n  force_n: {topic: a, field: x}\n",
            "'force_n': topic 'a' is not an absolute topic name",
        ),
        (
            "channels:\n  force_n: {topic: /a, field: 'x[-1]'}\n",
            "'force_n': field path 'x[-1]' is malformed",
        ),
        (
            "channels:\n  force_n: {topic: /a, field: x, scale: 0}\n",
            "'force_n': scale 0 must be finite and not 0",
        ),
        (
            "channels:\n  force_n: {topic: /a}\n",
            "'force_n': 'field' is missing",
        ),
        (
            "channels:\n  force_n: {topic: /a, field: x, gain: 2}\n",
            "unknown field `gain`",
        ),
        (
            "channels: {}\n",
            "map.yaml: no channels mapped under 'channels'",
        ),
        (
            "/**:\n  ros__parameters:\n    channels:\n      force_n: {topic: /a}\n",
            "'force_n': 'field' is missing",
        ),
        (
            "/**:\n  ros__parameters:\n    channels:\n      force_n: {topic: /a, field: 3}\n",
            "'force_n': 'field' must be a string, found integer",
        ),
        (
            "/**:\n  ros__parameters:\n    channels:\n      force_n: {topic: /a, field: x, gain: 2}\n",
            "'force_n': unknown key 'gain'",
        ),
        (
            "/**:\n  ros__parameters:\n    mass_kg: 3.0\n",
            "no channels mapped",
        ),
        (
            "channels:\n  force_n: {topic: /a, field: x}\ndefinitions:\n  Bad: x.msg\n",
            "'definitions.Bad'",
        ),
    ];
    for (text, expected) in cases {
        let e = error(text);
        assert!(e.contains(expected), "{text}\n-> {e}");
    }
}

#[test]
fn a_topic_entrys_unit_sets_its_scale() {
    let map = ChannelMap::from_yaml_str(
        "channels:\n  relative_displacement_m: {topic: /a, field: x, unit: mm}\n  \
         mass_acceleration_mps2: {topic: /a, field: y, unit: g, offset: 0.5}\n",
        "m",
    )
    .unwrap();
    assert_eq!(map.channels[0].1.scale, 0.001);
    assert_eq!(map.channels[1].1.apply(1.0), 9.80665 + 0.5);
    for (text, expected) in [
        (
            "channels:\n  force_n: {topic: /a, field: x, unit: mm}\n",
            "'force_n': unit 'mm' is not a unit of force_n (its SI unit is N)",
        ),
        (
            "channels:\n  force_n: {topic: /a, field: x, unit: V}\n",
            "'force_n': unit 'V' is not one forcemap knows",
        ),
        (
            "channels:\n  force_n: {topic: /a, field: x, unit: kN, scale: 1000}\n",
            "give 'unit' or 'scale', not both",
        ),
        (
            "channels:\n  force_n: {topic: /a, field: x, group: G}\n",
            "'group' applies to file columns",
        ),
        (
            "channels:\n  time_s: {topic: /a, field: t}\n  force_n: {topic: /a, field: x}\n",
            "'time_s': a bag's time is its messages' stamps",
        ),
    ] {
        let e = error(text);
        assert!(e.contains(expected), "{text}\n-> {e}");
    }
}

/// A map of file columns: names, positions, groups, units, and the forms of time.
#[test]
fn a_table_map_reads_columns_units_and_time() {
    let text = "channels:
  time_s: {channel: Timestamp, format: '%m/%d/%Y %H:%M:%S%.f'}
  relative_displacement_m: {channel: 2, unit: mm}
  force_n: {channel: 'Force (N)', offset: -1.5}
  mass_acceleration_mps2: {channel: Body_AccZ, group: Chassis}
table: {separator: whitespace, header: false, skip_lines: 3}
";
    let MapFile::Columns(map) = MapFile::from_yaml_str(text, "m.yaml").unwrap() else {
        panic!("a table map");
    };
    assert!(matches!(
        &map.time,
        Some(TimeSource::Column { source, format: Some(f) })
            if source.column == ColumnRef::Name("Timestamp".into()) && f == "%m/%d/%Y %H:%M:%S%.f"
    ));
    let names: Vec<Channel> = map.channels.iter().map(|(c, _)| *c).collect();
    assert_eq!(
        names,
        [
            Channel::RelativeDisplacementM,
            Channel::MassAccelerationMps2,
            Channel::ForceN
        ]
    );
    assert_eq!(map.channels[0].1.column, ColumnRef::Index(2));
    assert_eq!(map.channels[0].1.unit.as_deref(), Some("mm"));
    assert_eq!(map.channels[1].1.group.as_deref(), Some("Chassis"));
    assert_eq!(map.channels[2].1.offset, -1.5);
    assert_eq!(map.text.separator, Some(Separator::Whitespace));
    assert_eq!((map.text.header, map.text.skip_lines), (Some(false), 3));

    let rate = "channels:\n  time_s: {sample_rate_hz: 200}\n  force_n: {channel: 1, unit: N}\n";
    let MapFile::Columns(map) = MapFile::from_yaml_str(rate, "m").unwrap() else {
        panic!("a table map");
    };
    assert_eq!(
        map.time,
        Some(TimeSource::Rate {
            sample_rate_hz: 200.0
        })
    );

    // A table map is not a topic map.
    let e = ChannelMap::from_yaml_str(rate, "m")
        .unwrap_err()
        .to_string();
    assert!(e.contains("this map names file columns (channel:)"), "{e}");

    for (text, expected) in [
        (
            "channels:\n  force_n: {channel: false, unit: N}\n",
            "YAML reads this channel name as the boolean false: quote it",
        ),
        (
            "channels:\n  force_n: {channel: 0, unit: N}\n",
            "'force_n': column indices count from 1",
        ),
        (
            "channels:\n  force_n: {channel: Fz, unit: mm}\n",
            "'force_n': unit 'mm' is not a unit of force_n",
        ),
        (
            "channels:\n  force_n: {channel: Fz, sample_rate_hz: 10}\n",
            "'force_n': 'sample_rate_hz' and 'format' apply to time_s only",
        ),
        (
            "channels:\n  time_s: {channel: Count, sample_rate_hz: 10, unit: s}\n  force_n: {channel: Fz}\n",
            "a sample counter ('sample_rate_hz') takes no unit",
        ),
        (
            "channels:\n  time_s: {unit: s}\n  force_n: {channel: Fz}\n",
            "'time_s': give 'channel'",
        ),
        (
            "channels:\n  step: {channel: S}\n  force_n: {channel: Fz}\n",
            "mapped both or neither",
        ),
        (
            "channels:\n  force_n: {channel: Fz}\ntable: {separator: pipe}\n",
            "'table.separator': 'pipe' is not a separator",
        ),
        (
            "channels:\n  force_n: {channel: Fz, topic: /a}\n",
            "the map mixes topic entries",
        ),
    ] {
        let e = MapFile::from_yaml_str(text, "map.yaml")
            .expect_err("the map is refused")
            .to_string();
        assert!(e.contains(expected), "{text}\n-> {e}");
    }
}
