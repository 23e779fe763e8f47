//! What the identifier's and the diagnoser's tests share: the committed rig bag's phasor
//! messages and a core fed with them, and the messages of a simulated step.
#![allow(
    dead_code,
    clippy::unwrap_used,
    reason = "test helpers: each test file uses some; a panic is how a test reports failure"
)]

use std::path::Path;

use forcemap_io::params::{ParamValue, Params};
use forcemap_io::rig_bag::{DEFAULT_RUN_START, read_rig_bag};
use forcemap_math::identify::{FdMultiOptions, Method};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::phasor::{MultisineOptions, PhasorOptions, analyse_multisine, analyse_record};
use forcemap_math::pipeline::identify_records;
use forcemap_math::recipe::Setup;
use forcemap_math::record::{Channel, Excitation, Record};
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::DiagnosticStatus;
use forcemap_msgs::msg::{ExcitationState, HarmonicPhasors, IdentifiedParameters};
use forcemap_msgs::std_msgs::Header;
use forcemap_nodes::node::identifier::{IdentifierCore, Input, Output, RecipeParameters, Setting};

pub const RUN_START: Time = DEFAULT_RUN_START;

pub fn rig_bag() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../bags/rig_40db")
}

/// The phasor messages the harmonic node publishes for the bag's sine steps.
pub fn phasor_messages() -> Vec<HarmonicPhasors> {
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

pub fn params(entries: &[(&str, ParamValue)]) -> Params {
    let mut p = Params::new();
    for (k, v) in entries {
        p.set(k, v.clone());
    }
    p
}

pub fn core(p: &Params) -> IdentifierCore {
    let rp = RecipeParameters::from_params(p).unwrap();
    IdentifierCore::new(rp, "/rig/identifier: identification", None, RUN_START)
        .unwrap()
        .0
}

pub fn thetas(outputs: &[Output]) -> Vec<&IdentifiedParameters> {
    outputs
        .iter()
        .filter_map(|o| match o {
            Output::Theta(t) => Some(t),
            _ => None,
        })
        .collect()
}

pub fn statuses(outputs: &[Output]) -> Vec<&DiagnosticStatus> {
    outputs
        .iter()
        .filter_map(|o| match o {
            Output::Status(s) => Some(s),
            _ => None,
        })
        .collect()
}

/// The identifier fed every phasor message, returning the last theta it published.
pub fn fed(c: &mut IdentifierCore, messages: &[HarmonicPhasors]) -> Option<IdentifiedParameters> {
    let mut last = None;
    for ph in messages {
        let o = c
            .handle(Input::Phasors(Box::new(ph.clone())), RUN_START)
            .unwrap();
        last = thetas(&o).last().map(|t| (*t).clone()).or(last);
    }
    last
}

pub fn assert_same_values(a: &IdentifiedParameters, b: &IdentifiedParameters, rel: f64) {
    assert_eq!(a.parameter_names, b.parameter_names);
    for ((n, x), y) in a.parameter_names.iter().zip(&a.values).zip(&b.values) {
        let d = (x - y).abs() / y.abs().max(f64::MIN_POSITIVE);
        assert!(d <= rel, "{n}: {x} vs {y} (relative {d:e})");
    }
}

pub fn rig_params(extra: &[(&str, ParamValue)]) -> Params {
    let mut entries = vec![
        ("model", ParamValue::String("coulomb".into())),
        ("mass_kg", ParamValue::Double(36.0)),
    ];
    entries.extend(extra.iter().cloned());
    params(&entries)
}

pub fn setting(name: &str, value: &str) -> Setting {
    Setting::parse(name, &ParamValue::String(value.into())).unwrap()
}

/// Parameter names and values.
pub type Entries = Vec<(&'static str, ParamValue)>;

/// theta of `model` identified offline (fd-multi, the rig's 36 kg) on the committed rig bag:
/// what the live identifier must publish.
pub fn offline_rig_theta(model: &str) -> Vec<f64> {
    let bag = read_rig_bag(&rig_bag()).unwrap();
    let model = Model::by_name(model, &ModelOptions::default()).unwrap();
    identify_records(
        &model,
        &Setup::BaseExcited { mass_kg: 36.0 },
        Method::FdMulti,
        &bag.records,
        &PhasorOptions::for_identification(),
        &FdMultiOptions::default(),
    )
    .unwrap()
    .theta()
}

/// What the harmonic node and the sensor publish for `r`: a sine step's phasors, or a
/// multisine's state (its lines not carried) and the bins of its averaged period.
pub fn step_messages(r: &Record) -> (Option<ExcitationState>, HarmonicPhasors) {
    let header = Header::new(RUN_START, "rig");
    match &r.excitation {
        Excitation::Multisine { rms, .. } => {
            let an = analyse_multisine(r, &MultisineOptions::default()).unwrap();
            let mut ph =
                HarmonicPhasors::from_analysis(&an.as_harmonic_analysis(*rms), RUN_START, header);
            ph.harmonic_cap = HarmonicPhasors::MULTISINE_CAP;
            let state = ExcitationState::from_excitation(
                Header::new(RUN_START, "rig"),
                r.step,
                RUN_START.add_secs_f64(r.start_time_s),
                &r.excitation,
                Channel::ForceN,
                r.len(),
            );
            (Some(state), ph)
        }
        _ => {
            let an = analyse_record(r, &PhasorOptions::for_identification()).unwrap();
            (None, HarmonicPhasors::from_analysis(&an, RUN_START, header))
        }
    }
}

/// `records` renumbered in the order given and placed one after the other in time: one run.
pub fn one_run<'a>(records: impl IntoIterator<Item = &'a Record>) -> Vec<Record> {
    let mut t = 0.0;
    records
        .into_iter()
        .enumerate()
        .map(|(step, r)| {
            let mut r = r.clone();
            r.step = step;
            r.start_time_s = t;
            t += r.len() as f64 / r.sample_rate_hz;
            r
        })
        .collect()
}

/// The committed rig bag's steps as final phasors, and a core that identifies them.
pub fn rig_core(factor: f64) -> IdentifierCore {
    core(&rig_params(&[(
        "forgetting_per_step",
        ParamValue::Double(factor),
    )]))
}
