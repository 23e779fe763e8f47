//! Live parameters of the identifier's state machine: a new model, method, weighting or
//! forgetting factor re-solves the kept phasors as a fresh identifier would; what cannot be
//! applied is refused with the reason and changes nothing; the phasors survive the state file.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use std::path::Path;

use common::*;
use forcemap_io::params::ParamValue;
use forcemap_msgs::diagnostic_msgs::DiagnosticStatus;
use forcemap_nodes::node::identifier::{
    IdentifierCore, IdentifierState, Output, RecipeParameters, Setting,
};

/// A new model, method, weighting or forgetting factor set live re-solves the kept phasors and
/// gives what a fresh identifier started with those values gives on the same steps (and, for
/// the model, what `forcemap identify --model NEW` gives).
#[test]
fn reconfigure_equals_a_fresh_identifier_with_the_new_values() {
    let messages = phasor_messages();
    let cases: Vec<(Entries, Vec<Setting>, Entries)> = vec![
        (
            vec![],
            vec![setting("model", "coulomb-cubic")],
            vec![("model", ParamValue::String("coulomb-cubic".into()))],
        ),
        (
            vec![],
            vec![setting("method", "fd"), setting("model", "linear")],
            vec![
                ("method", ParamValue::String("fd".into())),
                ("model", ParamValue::String("linear".into())),
            ],
        ),
        // Tracking: the re-solve applies the same per-step weights.
        (
            vec![("forgetting_per_step", ParamValue::Double(0.7))],
            vec![setting("weighting", "uniform"), setting("model", "cubic")],
            vec![
                ("forgetting_per_step", ParamValue::Double(0.7)),
                ("weighting", ParamValue::String("uniform".into())),
                ("model", ParamValue::String("cubic".into())),
            ],
        ),
        (
            vec![],
            vec![Setting::parse("forgetting_per_step", &ParamValue::Double(0.8)).unwrap()],
            vec![("forgetting_per_step", ParamValue::Double(0.8))],
        ),
    ];
    for (start, settings, fresh_params) in cases {
        let mut c = core(&rig_params(&start));
        fed(&mut c, &messages).unwrap();
        let out = c.reconfigure(&settings, RUN_START).unwrap();
        let th = thetas(&out);
        assert_eq!(th.len(), 1, "{settings:?}: theta at once: {out:?}");
        assert!(out.contains(&Output::Persist));
        let status = statuses(&out).last().copied().unwrap();
        // OK, or the wrong-form warning where the new model is not the rig's (linear).
        assert!(
            status.level == DiagnosticStatus::OK
                || status
                    .message
                    .contains("the model explains the data far worse than its noise allows"),
            "{status:?}"
        );
        let mut fresh = core(&rig_params(&fresh_params));
        let expected = fed(&mut fresh, &messages).unwrap();
        assert_same_values(th[0], &expected, 1e-12);
        assert_eq!(c.recipe(), fresh.recipe(), "{settings:?}");
        // The next step goes on with the new recipe as the fresh identifier does.
        let more = fed(&mut c, &messages[..1]);
        assert!(more.is_none(), "a replayed step is skipped");
    }

    // Independently of the node: the model set live equals the offline identification.
    let mut c = core(&rig_params(&[]));
    fed(&mut c, &messages).unwrap();
    let out = c
        .reconfigure(&[setting("model", "coulomb-cubic")], RUN_START)
        .unwrap();
    let offline = offline_rig_theta("coulomb-cubic");
    let live = thetas(&out)[0];
    assert_eq!(live.parameter_names, vec!["k", "c", "fd", "s"]);
    for (l, o) in live.values.iter().zip(&offline) {
        assert!(((l - o) / o).abs() < 1e-9, "live {l} offline {o}");
    }
}

/// What cannot be applied is refused with a reason naming the parameter and value, and the
/// identifier stays as it was (same state, no theta).
#[test]
fn a_set_that_cannot_be_applied_is_refused_and_changes_nothing() {
    for (name, value, expect) in [
        (
            "model",
            ParamValue::String("quadratic".into()),
            "model = 'quadratic': unknown model",
        ),
        (
            "method",
            ParamValue::String("output-error".into()),
            "method = 'output-error': output error refits",
        ),
        (
            "method",
            ParamValue::String("td".into()),
            "method = 'td': the time-domain FSM needs the samples",
        ),
        (
            "weighting",
            ParamValue::String("equal".into()),
            "weighting = 'equal'",
        ),
        (
            "model",
            ParamValue::Double(3.0),
            "model must be a string (got a double)",
        ),
        (
            "forgetting_per_step",
            ParamValue::String("0.9".into()),
            "forgetting_per_step must be a double (got a string)",
        ),
        (
            "forgetting_per_step",
            ParamValue::Double(0.0),
            "forgetting_per_step = 0",
        ),
        (
            "mass_kg",
            ParamValue::Double(40.0),
            "parameter 'mass_kg' cannot change while the identifier runs",
        ),
    ] {
        let e = Setting::parse(name, &value).unwrap_err();
        assert!(e.reason.contains(expect), "{name} = {value:?}: {e}");
    }
    // A model that needs an option the node was not started with.
    let mut c = core(&rig_params(&[]));
    fed(&mut c, &phasor_messages()).unwrap();
    let before = c.state().cloned();
    let recipe = c.recipe().cloned();
    let e = c
        .reconfigure(&[setting("model", "coulomb-atan")], RUN_START)
        .unwrap_err();
    assert!(e.reason.starts_with("model = 'coulomb-atan': "), "{e}");
    assert!(e.reason.contains("atan slope M"), "{e}");
    assert_eq!(c.state().cloned(), before);
    assert_eq!(c.recipe().cloned(), recipe);
    assert_eq!(c.parameters().model.name, "coulomb");
}

/// Set before the first step: nothing to re-solve, the steps are taken with the new recipe.
#[test]
fn a_set_before_the_first_step_applies_to_the_steps_to_come() {
    let messages = phasor_messages();
    let mut c = core(&rig_params(&[]));
    let out = c
        .reconfigure(&[setting("model", "linear")], RUN_START)
        .unwrap();
    assert!(thetas(&out).is_empty());
    let live = fed(&mut c, &messages).unwrap();
    let mut fresh = core(&rig_params(&[(
        "model",
        ParamValue::String("linear".into()),
    )]));
    assert_same_values(&live, &fed(&mut fresh, &messages).unwrap(), 0.0);
}

/// The kept phasors survive the state file, so a resumed identifier re-solves as one that ran
/// the steps itself; a version-1 file (no phasors) resumes but refuses a re-solve by name.
#[test]
fn a_resumed_state_re_solves_from_its_file_and_a_version_one_file_refuses() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("state.json");
    let messages = phasor_messages();
    let mut c = core(&rig_params(&[]));
    fed(&mut c, &messages).unwrap();
    c.state().unwrap().save(&path).unwrap();
    let resume = |path: &Path| {
        let st = IdentifierState::load(path).unwrap().unwrap();
        let rp = RecipeParameters::from_params(&rig_params(&[])).unwrap();
        IdentifierCore::new(rp, "x", Some((st, "file".into())), RUN_START)
            .unwrap()
            .0
    };
    let mut resumed = resume(&path);
    let out = resumed
        .reconfigure(&[setting("model", "coulomb-cubic")], RUN_START)
        .unwrap();
    let mut fresh = core(&rig_params(&[(
        "model",
        ParamValue::String("coulomb-cubic".into()),
    )]));
    assert_same_values(thetas(&out)[0], &fed(&mut fresh, &messages).unwrap(), 1e-12);

    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    let obj = v.as_object_mut().unwrap();
    obj.remove("phasors");
    obj.remove("setup_spec");
    obj.insert("version".into(), 1.into());
    std::fs::write(&path, v.to_string()).unwrap();
    let mut old = resume(&path);
    let before = old.state().cloned();
    let e = old
        .reconfigure(&[setting("model", "coulomb-cubic")], RUN_START)
        .unwrap_err();
    assert!(e.reason.contains("version-1 state file"), "{e}");
    assert_eq!(old.state().cloned(), before);
    assert_eq!(old.parameters().model.name, "coulomb");
}

/// A set as the parameter services deliver it: each value on its own, or all or nothing.
#[test]
fn parameter_sets_apply_each_value_or_all_together() {
    let messages = phasor_messages();
    let set = vec![
        (
            "model".to_string(),
            ParamValue::String("coulomb-cubic".into()),
        ),
        (
            "method".to_string(),
            ParamValue::String("output-error".into()),
        ),
        ("forgetting_per_step".to_string(), ParamValue::Integer(1)),
    ];
    let mut c = core(&rig_params(&[]));
    fed(&mut c, &messages).unwrap();
    let before = c.state().cloned();
    let (done, out) = c.apply_parameters(&set, true, RUN_START);
    assert_eq!(done.results.len(), 1);
    assert!(
        done.results[0]
            .as_ref()
            .unwrap_err()
            .contains("method = 'output-error'")
    );
    assert!(done.applied.is_empty());
    assert!(thetas(&out).is_empty(), "a refused set publishes no theta");
    assert_eq!(c.state().cloned(), before);

    let (done, out) = c.apply_parameters(&set, false, RUN_START);
    assert!(done.results[0].is_ok());
    assert!(
        done.results[1]
            .as_ref()
            .unwrap_err()
            .contains("output error refits")
    );
    assert!(done.results[2].is_ok());
    assert_eq!(
        done.applied,
        vec![
            (
                "model".to_string(),
                ParamValue::String("coulomb-cubic".into())
            ),
            ("forgetting_per_step".to_string(), ParamValue::Double(1.0)),
        ]
    );
    // One theta per applied value, the last of the new model.
    let th = thetas(&out);
    assert_eq!(th.len(), 2);
    assert_eq!(th[1].parameter_names, vec!["k", "c", "fd", "s"]);
    assert!(out.iter().any(
        |o| matches!(o, Output::Log(l) if l.starts_with("parameter set refused: method = 'output-error'"))
    ));
}

/// With forgetting, the phasors of steps whose weight F^age fell below 1e-16 are let go: the
/// state stays small, and a re-solve from the rest still gives the full track's theta.
#[test]
fn a_tracking_identifier_keeps_only_the_phasors_that_still_weigh() {
    let messages = phasor_messages();
    // ln(1e-16) / ln(0.001) = 5.3: the newest step and 5 before it weigh at least 1e-16.
    let forgetting = ("forgetting_per_step", ParamValue::Double(0.001));
    let mut c = core(&rig_params(std::slice::from_ref(&forgetting)));
    fed(&mut c, &messages).unwrap();
    let st = c.state().unwrap();
    assert_eq!(st.phasors.len(), 6);
    assert_eq!(st.phasors[0].step, messages[4].step);
    let out = c
        .reconfigure(&[setting("model", "linear")], RUN_START)
        .unwrap();
    let mut fresh = core(&rig_params(&[
        forgetting,
        ("model", ParamValue::String("linear".into())),
    ]));
    assert_same_values(thetas(&out)[0], &fed(&mut fresh, &messages).unwrap(), 1e-12);
}

/// Restarted with another model on a state file of the old one, the identifier re-solves the
/// file's phasors for the new model instead of starting afresh.
#[test]
fn a_restart_with_another_model_re_solves_the_state_files_phasors() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("state.json");
    let messages = phasor_messages();
    let mut c = core(&rig_params(&[]));
    fed(&mut c, &messages).unwrap();
    c.state().unwrap().save(&path).unwrap();
    let cubic = rig_params(&[("model", ParamValue::String("coulomb-cubic".into()))]);
    let st = IdentifierState::load(&path).unwrap().unwrap();
    let rp = RecipeParameters::from_params(&cubic).unwrap();
    let (mut resumed, out) =
        IdentifierCore::new(rp, "x", Some((st, "the file".into())), RUN_START).unwrap();
    assert!(out.iter().any(|o| matches!(o, Output::Log(l)
        if l.contains("the file holds equations of model 'coulomb'") && l.contains("re-solving the phasors of its 10 steps"))));
    let mut fresh = core(&cubic);
    let expected = fed(&mut fresh, &messages).unwrap();
    assert_same_values(thetas(&out)[0], &expected, 1e-12);
    // The steps it has are skipped when the phasor history is replayed to it.
    assert!(fed(&mut resumed, &messages).is_none());
    assert_eq!(resumed.state().unwrap().phasors.len(), 10);
}
