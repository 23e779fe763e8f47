//! The identifier's state machine on periodic multisine steps, without DDS: a mixed run of the
//! force-driven cubic single DOF (sine steps, a multisine, more sine steps, another multisine)
//! gives the theta and standard deviations of `forcemap identify`'s pipeline on the same
//! records, with each multisine's lines found on the driven channel its ExcitationState names;
//! the same after a restart from the state file and after a live change of method; a
//! multisine whose state is missing is held, then refused; tracking refuses multisines.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use forcemap_io::params::ParamValue;
use forcemap_math::identify::{FdMultiOptions, Identification, Method};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::phasor::PhasorOptions;
use forcemap_math::pipeline::identify_records;
use forcemap_math::recipe::Setup;
use forcemap_math::record::{Excitation, Record};
use forcemap_math::sim::RunSpec;
use forcemap_msgs::msg::IdentifiedParameters;
use forcemap_nodes::node::identifier::{
    IdentifierCore, IdentifierState, Input, Output, RecipeParameters,
};

mod common;

use common::*;

const SEED: u64 = 3;

/// Sine steps 0-5 of the shaker's grid, its first multisine, sine steps 6-11, its second
/// multisine, renumbered in that order and placed one after the other in time (30 dB).
fn mixed_run() -> Vec<Record> {
    let sines = RunSpec::shaker_sdof(Some(30.0), SEED).simulate().unwrap();
    let multisines = RunSpec::shaker_sdof_multisine(Some(30.0), SEED)
        .simulate()
        .unwrap();
    let order = sines[..6]
        .iter()
        .chain([&multisines[0]])
        .chain(&sines[6..])
        .chain([&multisines[1]]);
    one_run(order)
}

fn offline(records: &[Record], method: Method) -> Identification {
    let model = Model::by_name("cubic", &ModelOptions::default()).unwrap();
    identify_records(
        &model,
        &Setup::Element {
            moving_mass_kg: None,
            drive: None,
        },
        method,
        records,
        &PhasorOptions::for_identification(),
        &FdMultiOptions::default(),
    )
    .unwrap()
}

fn assert_same(live: &IdentifiedParameters, offline: &Identification) {
    let names: Vec<&str> = offline.parameters.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(live.parameter_names, names);
    for (i, p) in offline.parameters.iter().enumerate() {
        for (what, a, b) in [
            ("value", live.values[i], p.value),
            ("std", live.standard_deviations[i], p.std),
        ] {
            let d = (a - b).abs() / b.abs();
            assert!(d < 1e-9, "{} {what}: live {a} offline {b} ({d:e})", p.name);
        }
    }
    assert_eq!(live.equations as usize, offline.equations);
}

fn logs(out: &[Output]) -> Vec<&str> {
    out.iter()
        .filter_map(|o| match o {
            Output::Log(l) => Some(l.as_str()),
            _ => None,
        })
        .collect()
}

/// The core fed the whole run in order (each multisine's state before its phasors); the
/// outputs of every input.
fn feed(c: &mut IdentifierCore, records: &[Record]) -> Vec<Output> {
    let mut out = Vec::new();
    for r in records {
        let (state, ph) = step_messages(r);
        if let Some(s) = state {
            out.extend(c.handle(Input::Excitation(Box::new(s)), RUN_START).unwrap());
        }
        out.extend(c.handle(Input::Phasors(Box::new(ph)), RUN_START).unwrap());
    }
    out
}

fn cubic() -> IdentifierCore {
    core(&params(&[("model", ParamValue::String("cubic".into()))]))
}

#[test]
fn a_mixed_run_live_gives_the_offline_theta_and_std() {
    let records = mixed_run();
    let mut c = cubic();
    let out = feed(&mut c, &records);
    let live = thetas(&out);
    // One theta per step (the first sine step's harmonics determine the four parameters).
    assert_eq!(live.len(), records.len(), "{:?}", logs(&out));
    let want = offline(&records, Method::FdMulti);
    assert_same(live.last().unwrap(), &want);
    // The multisines' equations come after the sine steps', live as offline.
    let used: Vec<usize> = (0..6).chain(7..13).chain([6, 13]).collect();
    assert_eq!(want.steps_used, used);
    let live_used: Vec<usize> = live
        .last()
        .unwrap()
        .steps_used
        .iter()
        .map(|s| *s as usize)
        .collect();
    assert_eq!(live_used, used);
    // After the first multisine (step 6) too: the same solve on the records so far.
    assert_same(live[6], &offline(&records[..7], Method::FdMulti));
    // The lines found on the force are the designed ones.
    let st = c.state().unwrap();
    for r in records.iter().filter(|r| r.step == 6 || r.step == 13) {
        let Excitation::Multisine { lines, .. } = &r.excitation else {
            panic!("step {} is no multisine", r.step)
        };
        assert_eq!(&st.multisine_lines[&(r.step as u32)], lines);
    }
    assert_eq!(st.steps_added(), records.len());

    // A restart from the state file resumes the same theta.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("state.json");
    st.save(&path).unwrap();
    let resumed = IdentifierState::load(&path).unwrap().unwrap();
    let rp =
        RecipeParameters::from_params(&params(&[("model", ParamValue::String("cubic".into()))]))
            .unwrap();
    let (_, said) =
        IdentifierCore::new(rp, "id", Some((resumed, "the file".into())), RUN_START).unwrap();
    assert_same(thetas(&said)[0], &want);

    // A live change of method re-solves the kept phasors, multisines included.
    let out = c
        .reconfigure(&[setting("method", "fd")], RUN_START)
        .unwrap();
    assert_same(thetas(&out)[0], &offline(&records, Method::Fd));
}

#[test]
fn a_multisine_waits_for_its_state_and_is_refused_without_it() {
    let records = mixed_run();
    let mut c = cubic();
    feed(&mut c, &records[..6]);
    let (state, ph) = step_messages(&records[6]);
    // Phasors before the state: held.
    let o = c.handle(Input::Phasors(Box::new(ph)), RUN_START).unwrap();
    assert!(thetas(&o).is_empty());
    assert!(
        logs(&o)
            .iter()
            .any(|l| l.contains("step 6: multisine phasors waiting for the ExcitationState")),
        "{o:?}"
    );
    let o = c
        .handle(Input::Excitation(Box::new(state.unwrap())), RUN_START)
        .unwrap();
    assert_same(thetas(&o)[0], &offline(&records[..7], Method::FdMulti));

    // The second multisine's state never comes: the next step's phasors let it go.
    let mut c = cubic();
    feed(&mut c, &records[..13]);
    let (_, ph) = step_messages(&records[13]);
    c.handle(Input::Phasors(Box::new(ph)), RUN_START).unwrap();
    let mut later = records[7].clone();
    later.step = 14;
    later.start_time_s += 1000.0;
    let (_, ph) = step_messages(&later);
    let o = c.handle(Input::Phasors(Box::new(ph)), RUN_START).unwrap();
    assert!(
        logs(&o).iter().any(|l| l.contains(
            "step 13: multisine phasors refused: no MULTISINE ExcitationState of this step"
        )),
        "{o:?}"
    );
    assert_eq!(thetas(&o).len(), 1, "step 14 is identified");
}

#[test]
fn tracking_refuses_multisine_steps_as_offline_tracking_does() {
    let records = mixed_run();
    let mut c = core(&params(&[
        ("model", ParamValue::String("cubic".into())),
        ("forgetting_per_step", ParamValue::Double(0.9)),
    ]));
    let out = feed(&mut c, &records[..7]);
    assert!(
        logs(&out)
            .iter()
            .any(|l| l.starts_with("step 6: no equations: tracking forgets per sine step")),
        "{:?}",
        logs(&out)
    );
    assert_eq!(c.state().unwrap().steps_added(), 6);
}
