//! The identifier's state machine without DDS: fed the phasors of the committed rig bag, it
//! gives the theta of `forcemap identify` on the same bag, waits for the rig's mass, skips
//! replayed steps, publishes the recipe it runs and refuses what it cannot run.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::path::Path;

use forcemap_io::params::{ParamValue, Params};
use forcemap_io::rig_bag::{DEFAULT_RUN_START, read_rig_bag};
use forcemap_math::identify::{FdMultiOptions, Method, Weighting};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::phasor::{PhasorOptions, analyse_record};
use forcemap_math::pipeline::identify_records;
use forcemap_math::recipe::Setup;
use forcemap_math::recipe::{Recipe, SetupSpec};
use forcemap_math::record::Excitation;
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::DiagnosticStatus;
use forcemap_msgs::msg::{HarmonicPhasors, IdentifiedParameters};
use forcemap_msgs::std_msgs::Header;
use forcemap_nodes::node::identifier::{
    IdentifierCore, IdentifierState, Input, Output, RecipeParameters, Setting,
};

const RUN_START: Time = DEFAULT_RUN_START;

fn rig_bag() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../bags/rig_40db")
}

/// The phasor messages the harmonic node publishes for the bag's sine steps.
fn phasor_messages() -> Vec<HarmonicPhasors> {
    let bag = read_rig_bag(&rig_bag()).unwrap();
    bag.records
        .iter()
        .filter(|r| matches!(r.excitation, Excitation::Sine { .. }))
        .map(|r| {
            let a = analyse_record(r, &PhasorOptions::for_identification()).unwrap();
            HarmonicPhasors::from_analysis(&a, RUN_START, Header::new(RUN_START, "rig"))
        })
        .collect()
}

fn params(entries: &[(&str, ParamValue)]) -> Params {
    let mut p = Params::new();
    for (k, v) in entries {
        p.set(k, v.clone());
    }
    p
}

fn core(p: &Params) -> IdentifierCore {
    let rp = RecipeParameters::from_params(p).unwrap();
    IdentifierCore::new(rp, "/rig/identifier: identification", None, RUN_START)
        .unwrap()
        .0
}

fn thetas(outputs: &[Output]) -> Vec<&IdentifiedParameters> {
    outputs
        .iter()
        .filter_map(|o| match o {
            Output::Theta(t) => Some(t),
            _ => None,
        })
        .collect()
}

fn statuses(outputs: &[Output]) -> Vec<&DiagnosticStatus> {
    outputs
        .iter()
        .filter_map(|o| match o {
            Output::Status(s) => Some(s),
            _ => None,
        })
        .collect()
}

#[test]
fn live_theta_equals_the_offline_identification() {
    let mut c = core(&params(&[("model", ParamValue::String("coulomb".into()))]));
    let mut out = Vec::new();
    // No mass yet: every step waits.
    for ph in phasor_messages() {
        let o = c.handle(Input::Phasors(Box::new(ph)), RUN_START).unwrap();
        assert!(thetas(&o).is_empty());
        out.extend(o);
    }
    assert!(
        out.iter()
            .any(|o| matches!(o, Output::Log(l) if l.contains("waiting for the rig's mass")))
    );
    let o = c.handle(Input::RigMass(36.0), RUN_START).unwrap();
    let live = thetas(&o);
    assert_eq!(live.len(), 10, "one theta per waiting step");
    let last = live.last().unwrap();

    let bag = read_rig_bag(&rig_bag()).unwrap();
    let model = Model::by_name("coulomb", &ModelOptions::default()).unwrap();
    let offline = identify_records(
        &model,
        &Setup::BaseExcited { mass_kg: 36.0 },
        Method::FdMulti,
        &bag.records,
        &PhasorOptions::for_identification(),
        &FdMultiOptions::default(),
    )
    .unwrap();
    assert_eq!(last.parameter_names, vec!["k", "c", "fd"]);
    for (live, off) in last.values.iter().zip(offline.theta()) {
        assert!(
            ((live - off) / off).abs() < 1e-9,
            "live {live} offline {off}"
        );
    }
    // The status carries the recipe it ran.
    let status = statuses(&o).last().copied().unwrap();
    let recipe_json = &status
        .values
        .iter()
        .find(|kv| kv.key == "recipe")
        .unwrap()
        .value;
    let recipe: Option<Recipe> = serde_json::from_str(recipe_json).unwrap();
    let recipe = recipe.unwrap();
    assert_eq!(recipe.setup, SetupSpec::BaseExcited { mass_kg: 36.0 });
    assert_eq!(recipe.model.name, "coulomb");
    assert_eq!(recipe.method, Method::FdMulti);
    assert_eq!(recipe.weighting, Weighting::Noise);
    assert_eq!(c.recipe(), Some(&recipe));
}

#[test]
fn replayed_steps_are_skipped_and_the_parameter_mass_wins() {
    let mut c = core(&params(&[
        ("model", ParamValue::String("linear".into())),
        ("mass_kg", ParamValue::Double(36.0)),
    ]));
    let phs = phasor_messages();
    let first = c
        .handle(Input::Phasors(Box::new(phs[0].clone())), RUN_START)
        .unwrap();
    assert!(first.contains(&Output::Persist));
    // The topic's mass does not override the parameter's.
    let o = c.handle(Input::RigMass(40.0), RUN_START).unwrap();
    assert!(o.is_empty(), "{o:?}");
    let again = c
        .handle(Input::Phasors(Box::new(phs[0].clone())), RUN_START)
        .unwrap();
    assert!(thetas(&again).is_empty());
    assert!(again.iter().any(
        |o| matches!(o, Output::Log(l) if l.contains("already in the accumulated equations"))
    ));
    assert_eq!(c.state().unwrap().accumulator.steps_added(), 1);
    assert_eq!(
        c.recipe().unwrap().setup,
        SetupSpec::BaseExcited { mass_kg: 36.0 }
    );
}

#[test]
fn what_the_identifier_cannot_run_is_refused_with_the_reason() {
    for (key, value, expect) in [
        ("method", "td", "never keeps"),
        ("method", "output-error", "never keeps"),
        ("method", "fd-mult", "expected fd, fd-multi"),
        ("weighting", "equal", "expected noise or uniform"),
        ("model", "quadratic", "unknown model 'quadratic'"),
        ("model", "coulomb-atan", "atan slope M"),
    ] {
        let p = params(&[(key, ParamValue::String(value.into()))]);
        let e = RecipeParameters::from_params(&p).unwrap_err();
        assert!(format!("{e:#}").contains(expect), "{key} = {value}: {e:#}");
    }
    let p = params(&[("mass_kg", ParamValue::Double(-3.0))]);
    let e = RecipeParameters::from_params(&p).unwrap_err();
    assert!(
        e.to_string()
            .contains("the rig's mass must be a positive number of kg"),
        "{e}"
    );
}

#[test]
fn phasors_of_no_setup_are_refused_without_stopping_the_node() {
    let mut c = core(&params(&[("mass_kg", ParamValue::Double(36.0))]));
    let mut ph = phasor_messages().remove(0);
    // Only the relative displacement: neither the rig's nor the drive point's channels.
    let keep = ph
        .channel_names
        .iter()
        .position(|n| n == "relative_displacement_m")
        .unwrap();
    let orders = ph.harmonic_orders.len();
    let cells = keep * orders..(keep + 1) * orders;
    ph.channel_names = vec![ph.channel_names[keep].clone()];
    ph.phasor_real = ph.phasor_real[cells.clone()].to_vec();
    ph.phasor_imag = ph.phasor_imag[cells.clone()].to_vec();
    ph.noise_std = ph.noise_std[cells].to_vec();
    ph.residual_rms = vec![ph.residual_rms[keep]];
    let out = c.handle(Input::Phasors(Box::new(ph)), RUN_START).unwrap();
    assert!(thetas(&out).is_empty());
    assert!(
        out.iter().any(|o| matches!(o, Output::Log(l) if l.contains("phasors refused") && l.contains("relative_displacement_m"))),
        "{out:?}"
    );
    // The next good step is identified as usual.
    let out = c
        .handle(
            Input::Phasors(Box::new(phasor_messages().remove(1))),
            RUN_START,
        )
        .unwrap();
    assert_eq!(thetas(&out).len(), 1, "the next step gives theta");
    assert_eq!(c.state().unwrap().accumulator.steps_added(), 1);
}

/// The phasor messages of a simulated damper on a dyno (the element setup).
fn damper_phasor_messages() -> (Vec<forcemap_math::record::Record>, Vec<HarmonicPhasors>) {
    use forcemap_math::sim::{ElementDrive, RunSpec, StepSpec};
    let element = RunSpec::damper_dyno(None, 0).element;
    let steps = [1.0, 2.0, 4.0, 8.0]
        .iter()
        .flat_map(|&f| {
            [0.005, 0.02].map(|a| StepSpec::Sine {
                frequency_hz: f,
                amplitude: a,
            })
        })
        .collect();
    let run = RunSpec {
        snr_db: Some(40.0),
        seed: 3,
        ..RunSpec::element_test(
            ElementDrive::Displacement,
            0.8,
            element,
            steps,
            1000.0,
            4000,
        )
    };
    let records = run.simulate().unwrap();
    let messages = records
        .iter()
        .map(|r| {
            let a = analyse_record(r, &PhasorOptions::for_identification()).unwrap();
            HarmonicPhasors::from_analysis(&a, RUN_START, Header::new(RUN_START, "dyno"))
        })
        .collect();
    (records, messages)
}

/// An element test live: with its moving mass given, and with it identified (no mass given:
/// no wait, the mass is a parameter `m` after the model's), theta equals the offline one.
#[test]
fn an_element_test_is_identified_live_as_offline() {
    let (records, messages) = damper_phasor_messages();
    let model = Model::by_name("damper", &ModelOptions::default()).unwrap();
    for (mass, names) in [
        (Some(0.8), vec!["offset", "k", "c", "ca", "fd"]),
        (None, vec!["offset", "k", "c", "ca", "fd", "m"]),
    ] {
        let mut entries = vec![("model", ParamValue::String("damper".into()))];
        if let Some(m) = mass {
            entries.push(("mass_kg", ParamValue::Double(m)));
        }
        let mut c = core(&params(&entries));
        let mut last = None;
        for ph in &messages {
            let o = c
                .handle(Input::Phasors(Box::new(ph.clone())), RUN_START)
                .unwrap();
            last = thetas(&o).last().map(|t| (*t).clone()).or(last);
        }
        let last = last.unwrap();
        assert_eq!(last.parameter_names, names);
        let offline = identify_records(
            &model,
            &Setup::Element {
                moving_mass_kg: mass,
            },
            Method::FdMulti,
            &records,
            &PhasorOptions::for_identification(),
            &FdMultiOptions::default(),
        )
        .unwrap();
        for (live, off) in last.values.iter().zip(offline.theta()) {
            assert!(
                ((live - off) / off).abs() < 1e-9,
                "mass {mass:?}: live {live} offline {off}"
            );
        }
        let recipe = c.recipe().unwrap();
        assert_eq!(
            recipe.setup,
            SetupSpec::Element {
                moving_mass_kg: mass
            }
        );
    }
}

#[test]
fn a_tracking_identifier_gives_the_offline_track_step_by_step() {
    let mut c = core(&params(&[
        ("model", ParamValue::String("coulomb".into())),
        ("mass_kg", ParamValue::Double(36.0)),
        ("forgetting_per_step", ParamValue::Double(0.7)),
    ]));
    let mut live = Vec::new();
    for ph in phasor_messages() {
        let o = c.handle(Input::Phasors(Box::new(ph)), RUN_START).unwrap();
        live.extend(thetas(&o).into_iter().cloned());
    }
    assert_eq!(
        c.recipe().unwrap().tracking.factor_per_step(),
        0.7,
        "the recipe says it tracks"
    );
    let bag = read_rig_bag(&rig_bag()).unwrap();
    let model = Model::by_name("coulomb", &ModelOptions::default()).unwrap();
    let analyses: Vec<_> = bag
        .records
        .iter()
        .filter(|r| matches!(r.excitation, Excitation::Sine { .. }))
        .map(|r| analyse_record(r, &PhasorOptions::for_identification()).unwrap())
        .collect();
    let setup = Setup::BaseExcited { mass_kg: 36.0 };
    let track = forcemap_math::identify::track_steps(
        &model,
        &setup,
        Method::FdMulti,
        &analyses,
        &FdMultiOptions::default(),
        0.7,
    )
    .unwrap();
    assert_eq!(live.len(), track.len());
    for (l, t) in live.iter().zip(&track) {
        for (a, b) in l.values.iter().zip(&t.parameters) {
            assert!(
                (a - b.value).abs() <= 1e-9 * b.value.abs(),
                "{a} vs {}",
                b.value
            );
        }
    }
    // Forgetting changes theta from the converged one: the last steps weigh more.
    let converged = forcemap_math::identify::track_steps(
        &model,
        &setup,
        Method::FdMulti,
        &analyses,
        &FdMultiOptions::default(),
        1.0,
    )
    .unwrap();
    let (a, b) = (
        &track.last().unwrap().parameters,
        &converged.last().unwrap().parameters,
    );
    assert!(a.iter().zip(b).any(|(x, y)| x.value != y.value));
}

#[test]
fn a_forgetting_factor_outside_zero_to_one_is_refused() {
    let p = params(&[("forgetting_per_step", ParamValue::Double(1.5))]);
    let e = RecipeParameters::from_params(&p).unwrap_err().to_string();
    assert!(e.contains("forgetting_per_step = 1.5"), "{e}");
}

/// The identifier fed every phasor message, returning the last theta it published.
fn fed(c: &mut IdentifierCore, messages: &[HarmonicPhasors]) -> Option<IdentifiedParameters> {
    let mut last = None;
    for ph in messages {
        let o = c
            .handle(Input::Phasors(Box::new(ph.clone())), RUN_START)
            .unwrap();
        last = thetas(&o).last().map(|t| (*t).clone()).or(last);
    }
    last
}

fn assert_same_values(a: &IdentifiedParameters, b: &IdentifiedParameters, rel: f64) {
    assert_eq!(a.parameter_names, b.parameter_names);
    for ((n, x), y) in a.parameter_names.iter().zip(&a.values).zip(&b.values) {
        let d = (x - y).abs() / y.abs().max(f64::MIN_POSITIVE);
        assert!(d <= rel, "{n}: {x} vs {y} (relative {d:e})");
    }
}

fn rig_params(extra: &[(&str, ParamValue)]) -> Params {
    let mut entries = vec![
        ("model", ParamValue::String("coulomb".into())),
        ("mass_kg", ParamValue::Double(36.0)),
    ];
    entries.extend(extra.iter().cloned());
    params(&entries)
}

fn setting(name: &str, value: &str) -> Setting {
    Setting::parse(name, &ParamValue::String(value.into())).unwrap()
}

/// Parameter names and values.
type Entries = Vec<(&'static str, ParamValue)>;

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
        assert_eq!(status.level, DiagnosticStatus::OK, "{status:?}");
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
    let bag = read_rig_bag(&rig_bag()).unwrap();
    let model = Model::by_name("coulomb-cubic", &ModelOptions::default()).unwrap();
    let offline = identify_records(
        &model,
        &Setup::BaseExcited { mass_kg: 36.0 },
        Method::FdMulti,
        &bag.records,
        &PhasorOptions::for_identification(),
        &FdMultiOptions::default(),
    )
    .unwrap();
    let live = thetas(&out)[0];
    assert_eq!(live.parameter_names, vec!["k", "c", "fd", "s"]);
    for (l, o) in live.values.iter().zip(offline.theta()) {
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
    let mut c = core(&rig_params(&[forgetting.clone()]));
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
