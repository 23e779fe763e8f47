//! The identifier's state machine without DDS: fed the phasors of the committed rig bag, it
//! gives the theta of `forcemap identify` on the same bag, waits for the rig's mass, skips
//! replayed steps, publishes the recipe it runs and refuses what it cannot run.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use forcemap_io::params::ParamValue;
use forcemap_io::rig_bag::read_rig_bag;
use forcemap_math::identify::{FdMultiOptions, Method, Weighting};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::phasor::{PhasorOptions, analyse_record};
use forcemap_math::pipeline::identify_records;
use forcemap_math::recipe::Setup;
use forcemap_math::recipe::{Recipe, SetupSpec};
use forcemap_math::record::Excitation;
use forcemap_msgs::msg::HarmonicPhasors;
use forcemap_msgs::std_msgs::Header;
use forcemap_nodes::node::identifier::{Input, Output, RecipeParameters};

mod common;

use common::*;

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

    let offline = offline_rig_theta("coulomb");
    assert_eq!(last.parameter_names, vec!["k", "c", "fd"]);
    for (live, off) in last.values.iter().zip(&offline) {
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
    assert_eq!(recipe.weighting, Weighting::Robust);
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
        ("weighting", "equal", "expected robust, noise or uniform"),
        ("model", "quadratic", "unknown model 'quadratic'"),
        ("model", "coulomb-atan", "atan slope M"),
        (
            "model",
            "damper+hysteresis",
            "a hysteresis state is fitted offline",
        ),
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

/// `records` without their acceleration channel.
fn without_acceleration(records: &mut [forcemap_math::record::Record]) {
    for r in records {
        r.channels
            .retain(|(c, _)| *c != forcemap_math::record::Channel::MassAccelerationMps2);
    }
}

/// The phasor messages of `records`' harmonic analyses, in frame `frame`.
fn phasors_of(records: &[forcemap_math::record::Record], frame: &str) -> Vec<HarmonicPhasors> {
    records
        .iter()
        .map(|r| {
            let a = analyse_record(r, &PhasorOptions::for_identification()).unwrap();
            HarmonicPhasors::from_analysis(&a, RUN_START, Header::new(RUN_START, frame))
        })
        .collect()
}

/// `forcemap identify`'s fd-multi theta of an element test's `records`.
fn offline_element(
    model: &Model,
    moving_mass_kg: Option<f64>,
    records: &[forcemap_math::record::Record],
) -> forcemap_math::identify::Identification {
    identify_records(
        model,
        &Setup::Element {
            moving_mass_kg,
            drive: None,
        },
        Method::FdMulti,
        records,
        &PhasorOptions::for_identification(),
        &FdMultiOptions::default(),
    )
    .unwrap()
}

/// The phasor messages of a simulated damper on a dyno (the element setup), with or without
/// its acceleration channel.
fn damper_phasor_messages(
    acceleration: bool,
) -> (Vec<forcemap_math::record::Record>, Vec<HarmonicPhasors>) {
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
    let mut records = run.simulate().unwrap();
    if !acceleration {
        without_acceleration(&mut records);
    }
    let messages = phasors_of(&records, "dyno");
    (records, messages)
}

/// An element test live: with its moving mass given, and with it identified (no mass given:
/// no wait, the mass is a parameter `m` after the model's), theta equals the offline one; so
/// too without the acceleration channel (the mass within 2 % of the dyno's 0.8 kg).
#[test]
fn an_element_test_is_identified_live_as_offline() {
    let model = Model::by_name("damper", &ModelOptions::default()).unwrap();
    for (mass, acceleration, names) in [
        (Some(0.8), true, vec!["offset", "k", "c", "ca", "fd"]),
        (None, true, vec!["offset", "k", "c", "ca", "fd", "m"]),
        (None, false, vec!["offset", "k", "c", "ca", "fd", "m"]),
    ] {
        let (records, messages) = damper_phasor_messages(acceleration);
        let mut entries = vec![("model", ParamValue::String("damper".into()))];
        if let Some(m) = mass {
            entries.push(("mass_kg", ParamValue::Double(m)));
        }
        let mut c = core(&params(&entries));
        let last = fed(&mut c, &messages).unwrap();
        assert_eq!(last.parameter_names, names);
        let offline = offline_element(&model, mass, &records);
        for (live, off) in last.values.iter().zip(offline.theta()) {
            assert!(
                ((live - off) / off).abs() < 1e-9,
                "mass {mass:?}, acceleration {acceleration}: live {live} offline {off}"
            );
        }
        if !acceleration {
            let m = *last.values.last().unwrap();
            assert!((m / 0.8 - 1.0).abs() < 0.02, "m {m}");
        }
        let recipe = c.recipe().unwrap();
        assert_eq!(
            recipe.setup,
            SetupSpec::Element {
                moving_mass_kg: mass,
                drive: None
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

/// A multisine step's phasors (`harmonic_cap` MULTISINE_CAP: the bins of its averaged period)
/// are never taken as a sine step's harmonics: they wait for their step's ExcitationState, and
/// phasors that cannot be an averaged period (here a sine step's, marked) are refused then.
#[test]
fn multisine_phasors_are_not_taken_for_a_sine_step() {
    let mut c = core(&params(&[
        ("model", ParamValue::String("coulomb".into())),
        ("mass_kg", ParamValue::Double(36.0)),
    ]));
    let mut ph = phasor_messages().remove(0);
    ph.harmonic_cap = HarmonicPhasors::MULTISINE_CAP;
    let state = forcemap_msgs::msg::ExcitationState {
        kind: forcemap_msgs::msg::ExcitationState::MULTISINE,
        step: ph.step,
        start_time: RUN_START,
        frequency_hz: ph.frequency_hz,
        driven_channel: "base_displacement_m".into(),
        ..forcemap_msgs::msg::ExcitationState::idle(
            Header::new(RUN_START, "rig"),
            0,
            RUN_START,
            forcemap_math::record::Channel::BaseDisplacementM,
        )
    };
    let o = c.handle(Input::Phasors(Box::new(ph)), RUN_START).unwrap();
    assert!(thetas(&o).is_empty());
    assert!(
        o.iter().any(|o| matches!(o, Output::Log(l) if l.contains("multisine phasors waiting for the ExcitationState"))),
        "{o:?}"
    );
    let o = c
        .handle(Input::Excitation(Box::new(state)), RUN_START)
        .unwrap();
    assert!(thetas(&o).is_empty());
    assert!(
        o.iter().any(|o| matches!(o, Output::Log(l) if l.contains("phasors refused: step 0: not the averaged period of a multisine"))),
        "{o:?}"
    );
    assert!(c.state().is_none(), "no equations added");
}

/// The force-driven shaker (cubic spring, 2 kg) without its acceleration channel and with its
/// mass unknown: fd-multi weighs each harmonic's rows with the differentiated displacement's
/// noise times the mass of a first-harmonic fit of the steps so far, and the live identifier
/// writes every kept step afresh when that mass changes, so that theta after the last step
/// equals `forcemap identify`'s on the same steps (within 1e-9) and every parameter is within
/// 0.1 % of the truth (k 20 kN/m, c 60 N s/m, s 5e7 N/m^3, m 2 kg).
#[test]
fn an_unknown_moving_mass_without_an_accelerometer_is_weighted_live_as_offline() {
    use forcemap_math::sim::RunSpec;
    let mut records = RunSpec::shaker_sdof(Some(40.0), 1).simulate().unwrap();
    without_acceleration(&mut records);
    let mut c = core(&params(&[("model", ParamValue::String("cubic".into()))]));
    let last = fed(&mut c, &phasors_of(&records, "shaker")).unwrap();
    let hint = c.state().unwrap().moving_mass_hint_kg.unwrap();
    assert!((hint / 2.0 - 1.0).abs() < 0.05, "hint {hint}");
    let offline = offline_element(
        &Model::by_name("cubic", &ModelOptions::default()).unwrap(),
        None,
        &records,
    );
    assert_eq!(offline.method, "fd-multi");
    for ((live, off), truth) in last
        .values
        .iter()
        .zip(offline.theta())
        .zip([2e4, 60.0, 5e7, 2.0])
    {
        assert!(
            ((live - off) / off).abs() < 1e-9,
            "live {live} offline {off}"
        );
        assert!(
            (live / truth - 1.0).abs() < 1e-3,
            "live {live} truth {truth}"
        );
    }
}
