//! `--ros-args -p name:=value` overrides.

use forcemap_io::params::{ParamValue, Params, ParamsError, read_params};

#[test]
fn override_values_are_parsed_as_yaml_scalars() {
    let mut p = Params::new();
    p.set_from_override("mass_kg:=40").unwrap();
    p.set_from_override("model:=coulomb").unwrap();
    p.set_from_override("rig.stiffness:=1.5e4").unwrap();
    p.set_from_override("verbose:=true").unwrap();
    p.set_from_override("label:='36'").unwrap();
    p.set_from_override("band_hz:=[1.0, 200]").unwrap();
    p.set_from_override("note:=a:=b").unwrap();
    p.set_from_override("neg:=-2").unwrap();
    assert_eq!(p.get("mass_kg"), Some(&ParamValue::Integer(40)));
    assert_eq!(p.get_f64("mass_kg").unwrap(), 40.0);
    assert_eq!(p.get_str("model").unwrap(), "coulomb");
    assert_eq!(p.get_f64("rig.stiffness").unwrap(), 1.5e4);
    assert!(p.get_bool("verbose").unwrap());
    assert_eq!(p.get("label"), Some(&ParamValue::String("36".into())));
    assert_eq!(p.get_f64_array("band_hz").unwrap(), vec![1.0, 200.0]);
    assert_eq!(p.get_str("note").unwrap(), "a:=b");
    assert_eq!(p.get_i64("neg").unwrap(), -2);
}

#[test]
fn override_replaces_the_file_value_and_type_errors_name_the_override() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rig.yaml");
    std::fs::write(
        &path,
        "/**:\n  ros__parameters:\n    mass_kg: 36.0\n    model: coulomb\n",
    )
    .unwrap();
    let mut p = read_params(&path, Some("forcemap_analyzer")).unwrap();
    p.set_from_override("model:=bouc_wen").unwrap();
    assert_eq!(p.get_str("model").unwrap(), "bouc_wen");
    assert_eq!(p.get_f64("mass_kg").unwrap(), 36.0);
    assert!(p.origin("mass_kg").unwrap().contains("rig.yaml"));

    p.set_from_override("mass_kg:=heavy").unwrap();
    let msg = p.get_f64("mass_kg").unwrap_err().to_string();
    assert!(
        msg.contains("mass_kg:=heavy") && msg.contains("expected double") && msg.contains("string"),
        "{msg}"
    );
}

#[test]
fn malformed_overrides_are_rejected() {
    let mut p = Params::new();
    for (text, part) in [
        ("mass_kg=40", "':='"),
        (":=40", "empty parameter name"),
        ("mass_kg:=", "empty value"),
        ("mass kg:=1", "whitespace"),
        ("m:={a: 1}", "mapping"),
        ("m:=~", "null"),
        ("m:=[1, [2]]", "one type"),
        ("m:=[1, 2", "YAML"),
    ] {
        let err = p.set_from_override(text).unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains(part), "{text:?}: {msg}");
        if !matches!(err, ParamsError::UnsupportedValue { .. }) {
            assert!(matches!(err, ParamsError::BadOverride { .. }), "{err:?}");
        }
    }
    assert!(p.is_empty());
}
