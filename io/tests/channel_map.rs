//! The channel map: both file forms read to the same map; each mistake is named with its
//! entry.

use forcemap_io::channel_map::ChannelMap;
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
            "missing field `field`",
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
            "/**:\n  ros__parameters:\n    channels:\n      force_n: {topic: /a, field: x, unit: N}\n",
            "'force_n': unknown key 'unit'",
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
