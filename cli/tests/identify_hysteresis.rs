//! `forcemap identify --model NAME+hysteresis` at its edges: listed by `forcemap models`, refused
//! with a reason on a rig's data and with options it does not take; its figures on real dampers
//! are in `real_data_suite` (`hysteresis_models_against_the_least_squares_with_the_same_state`).
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use std::path::Path;

fn arts(file: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../data/real/friction_damper_arts")
        .join(file)
        .display()
        .to_string()
}

#[test]
fn a_hysteresis_model_is_listed_and_refused_where_it_is_not_fitted() {
    let models = common::forcemap(&["models"]);
    let listed = String::from_utf8_lossy(&models.stdout);
    let line = listed
        .lines()
        .find(|l| l.starts_with("NAME+hysteresis"))
        .unwrap_or_else(|| panic!("{listed}"));
    // One line of prose after the name's column: no run of spaces inside it.
    assert!(
        !line
            .trim_start_matches("NAME+hysteresis")
            .trim_start()
            .contains("  "),
        "{line}"
    );
    // A rig's export: the hysteresis is fitted on element tests only.
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("rig.csv");
    let sim = common::forcemap(&["simulate", "--csv", csv.to_str().unwrap()]);
    assert!(sim.status.success(), "{}", common::stderr(&sim));
    let o = common::forcemap(&[
        "identify",
        csv.to_str().unwrap(),
        "--model",
        "linear+hysteresis",
        "--mass-kg",
        "36",
    ]);
    assert!(!o.status.success());
    let e = common::stderr(&o);
    assert!(
        e.contains("is fitted on element tests") && e.contains("a rig setup"),
        "{e}"
    );
    // An option it does not take is named.
    let map = arts("map.yaml");
    let plots = dir.path().join("plots");
    let o = common::forcemap(&[
        "identify",
        &arts("1Hz30lbtension0.5amplitude.json"),
        &arts("1Hz30lbtension1.5amplitude.json"),
        "--channels",
        &map,
        "--model",
        "linear+hysteresis",
        "--plot",
        plots.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let e = common::stderr(&o);
    assert!(
        e.contains("--plot is not available with a hysteresis state"),
        "{e}"
    );
    assert!(!plots.exists());
    // An unknown baseline is the model error it always is.
    let o = common::forcemap(&[
        "identify",
        &arts("1Hz30lbtension0.5amplitude.json"),
        "--channels",
        &map,
        "--model",
        "bogus+hysteresis",
    ]);
    assert!(!o.status.success());
    assert!(
        common::stderr(&o).contains("unknown model 'bogus'"),
        "{}",
        common::stderr(&o)
    );
}
