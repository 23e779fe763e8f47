//! Errors of the EMPS importer on small MAT v5 files written here (uncompressed, little
//! endian): each names the file and the variable, and no bag is left behind.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::path::{Path, PathBuf};

use forcemap_io::emps::{self, EmpsError};

enum Var<'a> {
    Double(&'a str, Vec<usize>, Vec<f64>),
    Single(&'a str, Vec<usize>, Vec<f32>),
}

fn pad8(v: &mut Vec<u8>) {
    while !v.len().is_multiple_of(8) {
        v.push(0);
    }
}

fn element(out: &mut Vec<u8>, ty: u32, data: &[u8]) {
    out.extend_from_slice(&ty.to_le_bytes());
    out.extend_from_slice(&(data.len() as u32).to_le_bytes());
    out.extend_from_slice(data);
    pad8(out);
}

/// A MAT v5 file with the given numeric matrices (the format's miMATRIX elements).
fn write_mat(path: &Path, vars: &[Var]) {
    let mut out = Vec::new();
    let mut text = b"MATLAB 5.0 MAT-file, written by the forcemap EMPS tests".to_vec();
    text.resize(116, b' ');
    out.extend_from_slice(&text);
    out.extend_from_slice(&[0; 8]);
    out.extend_from_slice(&0x0100u16.to_le_bytes());
    out.extend_from_slice(b"IM");
    for v in vars {
        let (name, dims, class, data_ty, data): (&str, &[usize], u32, u32, Vec<u8>) = match v {
            Var::Double(n, d, x) => (n, d, 6, 9, x.iter().flat_map(|f| f.to_le_bytes()).collect()),
            Var::Single(n, d, x) => (n, d, 7, 7, x.iter().flat_map(|f| f.to_le_bytes()).collect()),
        };
        let mut body = Vec::new();
        let flags: Vec<u8> = [class, 0u32].iter().flat_map(|f| f.to_le_bytes()).collect();
        element(&mut body, 6, &flags);
        let d: Vec<u8> = dims
            .iter()
            .flat_map(|d| (*d as i32).to_le_bytes())
            .collect();
        element(&mut body, 5, &d);
        element(&mut body, 1, name.as_bytes());
        element(&mut body, data_ty, &data);
        element(&mut out, 14, &body);
    }
    std::fs::write(path, out).unwrap();
}

fn good_vars() -> Vec<Var<'static>> {
    let n = 50;
    let t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-3).collect();
    let q: Vec<f64> = t.iter().map(|t| 0.1 * t).collect();
    vec![
        Var::Double("t", vec![n, 1], t.clone()),
        Var::Double("qm", vec![n, 1], q.clone()),
        Var::Double("qg", vec![1, n], q),
        Var::Double("vir", vec![n, 1], t.iter().map(|t| t.sin()).collect()),
        Var::Double("gtau", vec![1, 1], vec![35.0]),
        Var::Double("kp", vec![1, 1], vec![160.0]),
        Var::Double("kv", vec![1, 1], vec![243.0]),
    ]
}

fn run(
    vars: Vec<Var>,
) -> (
    tempfile::TempDir,
    PathBuf,
    Result<emps::EmpsData, EmpsError>,
) {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("case.mat");
    write_mat(&path, &vars);
    let r = emps::read_emps(&path);
    (tmp, path, r)
}

fn replace(name: &str, var: Var<'static>) -> Vec<Var<'static>> {
    let mut v = good_vars();
    let i = v
        .iter()
        .position(|x| matches!(x, Var::Double(n, ..) | Var::Single(n, ..) if *n == name))
        .unwrap();
    v[i] = var;
    v
}

#[test]
fn a_small_valid_file_imports() {
    let (tmp, path, r) = run(good_vars());
    let d = r.unwrap();
    assert_eq!(d.len(), 50);
    assert_eq!(d.force_n[10], 35.0 * d.drive_input[10]);
    assert!(d.extra.is_empty());
    let out = tmp.path().join("bag");
    let s = emps::import_emps(&path, &out).unwrap();
    assert_eq!(s.samples, 50);
    assert!((s.sample_rate_hz - 1000.0).abs() < 1e-6);
    let bag = forcemap_io::bag::BagReader::open(&out).unwrap();
    assert_eq!(bag.summary().message_count, 51);
}

#[test]
fn missing_variable_is_named_with_the_file() {
    let mut vars = good_vars();
    vars.retain(|v| !matches!(v, Var::Double("vir", ..)));
    let (_tmp, path, r) = run(vars);
    let e = r.unwrap_err();
    let text = e.to_string();
    assert!(
        matches!(&e, EmpsError::Missing { variable, .. } if variable == "vir"),
        "{e:?}"
    );
    assert!(text.contains(&path.display().to_string()), "{text}");
    assert!(text.contains("'vir' is missing"), "{text}");
    assert!(text.contains("t, qm, qg, gtau, kp, kv"), "{text}");
}

#[test]
fn wrong_class_is_named() {
    let (_tmp, _path, r) = run(replace("kp", Var::Single("kp", vec![1, 1], vec![160.0])));
    let text = r.unwrap_err().to_string();
    assert!(
        text.contains("'kp' is single, expected real double"),
        "{text}"
    );
}

#[test]
fn wrong_shapes_are_named() {
    let (_tmp, _path, r) = run(replace("qm", Var::Double("qm", vec![49, 1], vec![0.0; 49])));
    let text = r.unwrap_err().to_string();
    assert!(
        text.contains("'qm' has shape [49, 1], expected 50 x 1 or 1 x 50"),
        "{text}"
    );

    let (_tmp, _path, r) = run(replace(
        "gtau",
        Var::Double("gtau", vec![1, 2], vec![1.0, 2.0]),
    ));
    let text = r.unwrap_err().to_string();
    assert!(
        text.contains("'gtau' has shape [1, 2], expected 1 x 1"),
        "{text}"
    );

    let (_tmp, _path, r) = run(replace("t", Var::Double("t", vec![25, 2], vec![0.0; 50])));
    let text = r.unwrap_err().to_string();
    assert!(text.contains("'t' has shape [25, 2]"), "{text}");
}

#[test]
fn non_finite_and_non_increasing_time_are_refused() {
    let mut q = vec![0.0; 50];
    q[7] = f64::NAN;
    let (_tmp, _path, r) = run(replace("qm", Var::Double("qm", vec![50, 1], q)));
    let text = r.unwrap_err().to_string();
    assert!(text.contains("'qm' holds NaN at index 8"), "{text}");

    let mut t: Vec<f64> = (0..50).map(|i| i as f64 * 1e-3).collect();
    t[20] = t[19];
    let (_tmp, _path, r) = run(replace("t", Var::Double("t", vec![50, 1], t)));
    let text = r.unwrap_err().to_string();
    assert!(text.contains("'t' does not increase at index 21"), "{text}");
}

#[test]
fn not_a_mat_file_and_absent_file() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("junk.mat");
    std::fs::write(&path, b"time,qm\n0,0\n").unwrap();
    let text = emps::read_emps(&path).unwrap_err().to_string();
    assert!(
        text.contains("junk.mat: not a readable MATLAB v5 .mat file"),
        "{text}"
    );
    let out = tmp.path().join("bag");
    assert!(emps::import_emps(&path, &out).is_err());
    assert!(!out.exists());
    assert_eq!(
        std::fs::read_dir(tmp.path()).unwrap().count(),
        1,
        "no partial bag left"
    );

    let text = emps::read_emps(tmp.path().join("nope.mat"))
        .unwrap_err()
        .to_string();
    assert!(text.contains("nope.mat: cannot read"), "{text}");
}
