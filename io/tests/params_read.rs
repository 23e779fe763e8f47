//! ROS 2 params YAML files.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::path::PathBuf;

use forcemap_io::params::{ParamValue, ParamsError, read_params};

fn write(name: &str, text: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, text).unwrap();
    (dir, path)
}

const MERGE: &str = r#"
forcemap_analyzer:
  ros__parameters:
    model: bouc_wen          # node-specific wins, although it comes first in the file
    rig:
      mass_kg: 40
/**:
  ros__parameters:
    mass_kg: 36.0
    model: coulomb
    use_sim_time: false
    rig:
      mass_kg: 36.5
      stiffness_n_per_m: 1.2e4
    harmonics: [1, 3, 5]
    band_hz: [1, 2.5]
    labels: ["a", "b"]
    flags: [true, no]
    empty: []
    quoted_number: "36"
/other_node:
  ros__parameters:
    model: linear
"#;

#[test]
fn wildcard_and_node_specific_entries_merge() {
    let (_d, path) = write("rig_params.yaml", MERGE);
    let p = read_params(&path, Some("forcemap_analyzer")).unwrap();
    assert_eq!(p.get_str("model").unwrap(), "bouc_wen");
    assert_eq!(p.get_f64("mass_kg").unwrap(), 36.0);
    assert_eq!(p.get_f64("rig.mass_kg").unwrap(), 40.0);
    assert_eq!(p.get_f64("rig.stiffness_n_per_m").unwrap(), 1.2e4);
    assert!(!p.get_bool("use_sim_time").unwrap());
    assert_eq!(p.get_i64_array("harmonics").unwrap(), vec![1, 3, 5]);
    assert_eq!(p.get_f64_array("harmonics").unwrap(), vec![1.0, 3.0, 5.0]);
    assert_eq!(p.get_f64_array("band_hz").unwrap(), vec![1.0, 2.5]);
    assert_eq!(p.get_str_array("labels").unwrap(), vec!["a", "b"]);
    assert_eq!(p.get_bool_array("flags").unwrap(), vec![true, false]);
    assert!(p.get_f64_array("empty").unwrap().is_empty());
    assert_eq!(
        p.get("quoted_number"),
        Some(&ParamValue::String("36".into()))
    );
    assert_eq!(p.len(), 11);

    // Fully qualified name in the root namespace, same result.
    let q = read_params(&path, Some("/forcemap_analyzer")).unwrap();
    assert_eq!(q, p);

    // Another node gets the wildcard values plus its own.
    let o = read_params(&path, Some("other_node")).unwrap();
    assert_eq!(o.get_str("model").unwrap(), "linear");
    assert_eq!(o.get_f64("rig.mass_kg").unwrap(), 36.5);

    // No node name: only `/**`.
    let w = read_params(&path, None).unwrap();
    assert_eq!(w.get_str("model").unwrap(), "coulomb");
    assert_eq!(w.get_f64("rig.mass_kg").unwrap(), 36.5);

    // A node in a namespace does not match the root-namespace key, only the wildcard.
    let ns = read_params(&path, Some("/lab/forcemap_analyzer")).unwrap();
    assert_eq!(ns.get_str("model").unwrap(), "coulomb");
}

#[test]
fn namespaces_and_wildcards() {
    let text = r#"
/lab:
  forcemap_analyzer:
    ros__parameters:
      a: 1
/lab/*:
  ros__parameters:
    a: 0
    b: 2
/**/forcemap_analyzer:
  ros__parameters:
    c: 3
"#;
    let (_d, path) = write("ns.yaml", text);
    let p = read_params(&path, Some("/lab/forcemap_analyzer")).unwrap();
    assert_eq!(p.get_i64("a").unwrap(), 1);
    assert_eq!(p.get_i64("b").unwrap(), 2);
    assert_eq!(p.get_i64("c").unwrap(), 3);
    let q = read_params(&path, Some("/forcemap_analyzer")).unwrap();
    assert_eq!(q.names().collect::<Vec<_>>(), vec!["c"]);

    let err = read_params(&path, Some("/elsewhere/node")).unwrap_err();
    assert!(matches!(err, ParamsError::NoMatchingNode { .. }), "{err:?}");
    let msg = err.to_string();
    assert!(
        msg.contains("ns.yaml") && msg.contains("/lab/forcemap_analyzer"),
        "{msg}"
    );
}

#[test]
fn integer_is_accepted_for_a_double() {
    let (_d, path) = write("p.yaml", "/**:\n  ros__parameters:\n    mass_kg: 36\n");
    let p = read_params(&path, None).unwrap();
    assert_eq!(p.get("mass_kg"), Some(&ParamValue::Integer(36)));
    assert_eq!(p.get_f64("mass_kg").unwrap(), 36.0);
    assert_eq!(p.get_usize("mass_kg").unwrap(), 36);
}

#[test]
fn string_for_a_double_is_rejected_clearly() {
    let (_d, path) = write(
        "rig_params.yaml",
        "/**:\n  ros__parameters:\n    mass_kg: heavy\n",
    );
    let p = read_params(&path, None).unwrap();
    let err = p.get_f64("mass_kg").unwrap_err();
    assert!(
        matches!(
            err,
            ParamsError::WrongType {
                expected: "double",
                ..
            }
        ),
        "{err:?}"
    );
    let msg = err.to_string();
    for part in [
        "rig_params.yaml",
        "'mass_kg'",
        "expected double",
        "string \"heavy\"",
    ] {
        assert!(msg.contains(part), "{part:?} not in: {msg}");
    }
    // Quoted numbers are strings too.
    let (_d, path) = write(
        "q.yaml",
        "/**:\n  ros__parameters:\n    mass_kg: \"36.0\"\n",
    );
    let p = read_params(&path, None).unwrap();
    assert!(p.get_f64("mass_kg").is_err());
}

#[test]
fn other_type_errors() {
    let text =
        "/**:\n  ros__parameters:\n    n: -3\n    x: 1.5\n    flag: true\n    list: [1.5, 2]\n";
    let (_d, path) = write("t.yaml", text);
    let p = read_params(&path, None).unwrap();
    let msg = p.get_usize("n").unwrap_err().to_string();
    assert!(
        msg.contains("'n'") && msg.contains("non-negative integer") && msg.contains("-3"),
        "{msg}"
    );
    let msg = p.get_i64("x").unwrap_err().to_string();
    assert!(msg.contains("expected integer, found double 1.5"), "{msg}");
    let msg = p.get_str("flag").unwrap_err().to_string();
    assert!(msg.contains("expected string, found bool true"), "{msg}");
    let msg = p.get_bool("list").unwrap_err().to_string();
    assert!(msg.contains("found double_array [1.5, 2.0]"), "{msg}");
    let err = p.get_f64("absent").unwrap_err();
    assert!(matches!(err, ParamsError::Missing { .. }), "{err:?}");
    assert!(err.to_string().contains("t.yaml") && err.to_string().contains("'absent'"));
    assert_eq!(p.opt_f64("absent").unwrap(), None);
    assert_eq!(p.opt_f64("x").unwrap(), Some(1.5));
}

#[test]
fn file_not_found() {
    let dir = tempfile::tempdir().unwrap();
    let err = read_params(dir.path().join("nope.yaml"), None).unwrap_err();
    assert!(matches!(err, ParamsError::NotFound { .. }), "{err:?}");
    assert!(err.to_string().contains("nope.yaml"), "{err}");
}

#[test]
fn yaml_syntax_error_has_line_and_column() {
    let text = "/**:\n  ros__parameters:\n    mass_kg: 36.0\n    model: [coulomb\n";
    let (_d, path) = write("broken.yaml", text);
    let err = read_params(&path, None).unwrap_err();
    let ParamsError::Syntax { line, column, .. } = &err else {
        panic!("{err:?}")
    };
    let (line, column) = (line.unwrap(), column.unwrap());
    assert!((4..=5).contains(&line), "line {line}");
    assert!(column >= 1, "column {column}");
    let msg = err.to_string();
    assert!(
        msg.contains("broken.yaml") && msg.contains(&format!("line {line}")),
        "{msg}"
    );

    // Bad indentation.
    let (_d, path) = write(
        "indent.yaml",
        "/**:\n  ros__parameters:\n    a: 1\n   b: 2\n",
    );
    let err = read_params(&path, None).unwrap_err();
    assert!(
        matches!(err, ParamsError::Syntax { line: Some(_), .. }),
        "{err:?}"
    );
}

#[test]
fn missing_ros_parameters_key() {
    for text in [
        "mass_kg: 36.0\n",
        "/**:\n  ros_parameters:\n    mass_kg: 36.0\n",
        "",
        "- 1\n- 2\n",
    ] {
        let (_d, path) = write("flat.yaml", text);
        let err = read_params(&path, None).unwrap_err();
        assert!(
            matches!(err, ParamsError::NoRosParameters { .. }),
            "{text:?}: {err:?}"
        );
        let msg = err.to_string();
        assert!(
            msg.contains("flat.yaml") && msg.contains("ros__parameters"),
            "{msg}"
        );
    }
}

#[test]
fn structure_and_value_errors() {
    let cases = [
        ("/**:\n  ros__parameters: 3\n", "not a mapping"),
        ("/**:\n  ros__parameters:\n    a: 1\n  stray: 2\n", "stray"),
        ("/**:\n  ros__parameters:\n    a: ~\n", "'a'"),
        ("/**:\n  ros__parameters:\n    a: [1, x]\n", "one type"),
        ("/**:\n  ros__parameters:\n    a: [[1], [2]]\n", "one type"),
    ];
    for (text, part) in cases {
        let (_d, path) = write("s.yaml", text);
        let err = read_params(&path, None).unwrap_err();
        let msg = err.to_string();
        assert!(
            msg.contains("s.yaml") && msg.contains(part),
            "{text:?}: {msg}"
        );
    }
}
