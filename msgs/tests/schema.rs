//! MCAP "ros2msg" schema text: top-level .msg text, then each dependency once after a line of
//! 80 '=' and "MSG: pkg/Type".
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus, KeyValue};
use forcemap_msgs::msg::{ExcitationState, HarmonicPhasors, IdentifiedParameters, RigSample};
use forcemap_msgs::std_msgs::Header;
use forcemap_msgs::{RosMessage, SCHEMA_ENCODING, SEPARATOR};

/// Splits a schema into (top text, [(MSG name, text)]) and checks the separator lines.
fn split(schema: &str) -> (String, Vec<(String, String)>) {
    let lines: Vec<&str> = schema.lines().collect();
    let mut sections: Vec<(Option<String>, Vec<&str>)> = vec![(None, vec![])];
    let mut i = 0;
    while i < lines.len() {
        let l = lines[i];
        if l.starts_with("==") {
            assert_eq!(l.len(), 80, "separator line must be 80 characters: {l:?}");
            assert!(l.chars().all(|c| c == '='), "separator: {l:?}");
            let name = lines
                .get(i + 1)
                .and_then(|m| m.strip_prefix("MSG: "))
                .unwrap_or_else(|| panic!("no 'MSG: ' line after the separator at line {i}"));
            sections.push((Some(name.to_string()), vec![]));
            i += 2;
        } else {
            sections.last_mut().unwrap().1.push(l);
            i += 1;
        }
    }
    let top = sections[0].1.join("\n");
    let deps = sections[1..]
        .iter()
        .map(|(n, ls)| (n.clone().unwrap(), ls.join("\n")))
        .collect();
    (top, deps)
}

fn dep_names<T: RosMessage>() -> Vec<String> {
    let (top, deps) = split(&T::schema());
    assert_eq!(
        top.trim_end(),
        T::DEFINITION.text.trim_end(),
        "{}: top-level text must be the .msg text",
        T::TYPE_NAME
    );
    let names: Vec<String> = deps.iter().map(|(n, _)| n.clone()).collect();
    let mut unique = names.clone();
    unique.sort();
    unique.dedup();
    assert_eq!(
        unique.len(),
        names.len(),
        "{}: duplicate dependency",
        T::TYPE_NAME
    );
    names
}

fn sorted(mut v: Vec<String>) -> Vec<String> {
    v.sort();
    v
}

#[test]
fn separator_constant_is_80_equals() {
    assert_eq!(SEPARATOR.len(), 80);
    assert!(SEPARATOR.bytes().all(|b| b == b'='));
    assert_eq!(SCHEMA_ENCODING, "ros2msg");
}

#[test]
fn dependencies_appear_once_each() {
    let hdr = ["builtin_interfaces/Time", "std_msgs/Header"];
    assert!(dep_names::<Time>().is_empty());
    assert!(dep_names::<KeyValue>().is_empty());
    assert_eq!(dep_names::<Header>(), ["builtin_interfaces/Time"]);
    assert_eq!(sorted(dep_names::<RigSample>()), hdr);
    // Time is used by the header and by a field: still once.
    assert_eq!(sorted(dep_names::<ExcitationState>()), hdr);
    assert_eq!(sorted(dep_names::<HarmonicPhasors>()), hdr);
    assert_eq!(sorted(dep_names::<IdentifiedParameters>()), hdr);
    assert_eq!(
        dep_names::<DiagnosticStatus>(),
        ["diagnostic_msgs/KeyValue"]
    );
    assert_eq!(
        sorted(dep_names::<DiagnosticArray>()),
        [
            "builtin_interfaces/Time",
            "diagnostic_msgs/DiagnosticStatus",
            "diagnostic_msgs/KeyValue",
            "std_msgs/Header"
        ]
    );
}

#[test]
fn exact_schema_of_header() {
    let expected = format!(
        "{}\n{}\nMSG: builtin_interfaces/Time\n{}\n",
        include_str!("../deps/std_msgs/msg/Header.msg").trim_end(),
        "=".repeat(80),
        include_str!("../deps/builtin_interfaces/msg/Time.msg").trim_end()
    );
    assert_eq!(Header::schema(), expected);
}

#[test]
fn dependency_texts_are_the_msg_files() {
    let (_, deps) = split(&HarmonicPhasors::schema());
    for (name, text) in deps {
        let file = match name.as_str() {
            "std_msgs/Header" => include_str!("../deps/std_msgs/msg/Header.msg"),
            "builtin_interfaces/Time" => include_str!("../deps/builtin_interfaces/msg/Time.msg"),
            other => panic!("unexpected dependency {other}"),
        };
        assert_eq!(text.trim_end(), file.trim_end());
    }
    assert_eq!(
        RigSample::DEFINITION.text,
        include_str!("../msg/RigSample.msg")
    );
}

/// Every field type that names a message must be in the schema (so a reader can resolve it).
#[test]
fn every_referenced_type_is_defined() {
    fn check<T: RosMessage>() {
        let schema = T::schema();
        let (top, deps) = split(&schema);
        let mut sections = vec![(T::DEFINITION.name.to_string(), top)];
        sections.extend(deps);
        let defined: Vec<&str> = sections.iter().map(|(n, _)| n.as_str()).collect();
        for (name, text) in &sections {
            let pkg = name.split('/').next().unwrap();
            for line in text.lines() {
                let line = line.split('#').next().unwrap().trim();
                let Some(ty) = line.split_whitespace().next() else {
                    continue;
                };
                if line.contains('=') {
                    continue; // constant
                }
                let ty = ty.split('[').next().unwrap();
                let builtin = [
                    "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16",
                    "uint16", "int32", "uint32", "int64", "uint64", "string", "wstring",
                ];
                if builtin.contains(&ty) {
                    continue;
                }
                let full = if ty.contains('/') {
                    ty.to_string()
                } else {
                    format!("{pkg}/{ty}")
                };
                assert!(
                    defined.contains(&full.as_str()),
                    "{}: {full} used in {name} is not in the schema",
                    T::TYPE_NAME
                );
            }
        }
    }
    check::<RigSample>();
    check::<ExcitationState>();
    check::<HarmonicPhasors>();
    check::<IdentifiedParameters>();
    check::<forcemap_msgs::msg::GapDiagnosis>();
    check::<DiagnosticArray>();
}
