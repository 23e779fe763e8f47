//! The diagnoser's state machine without DDS: fed the phasors of the committed rig bag (a
//! Coulomb damper), it names the friction a linear baseline misses and calls the Coulomb
//! baseline adequate, as the graph test sees it through DDS.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::path::Path;

use forcemap_io::params::{ParamValue, Params};
use forcemap_io::rig_bag::{DEFAULT_RUN_START, read_rig_bag};
use forcemap_math::phasor::{PhasorOptions, analyse_record};
use forcemap_math::record::Excitation;
use forcemap_msgs::diagnostic_msgs::DiagnosticStatus;
use forcemap_msgs::msg::{GapDiagnosis, HarmonicPhasors};
use forcemap_msgs::std_msgs::Header;
use forcemap_nodes::node::diagnoser::{DiagnoserCore, Output};
use forcemap_nodes::node::setup_gate::Input;

fn last_diagnosis(baseline: &str) -> (GapDiagnosis, DiagnosticStatus) {
    let bag =
        read_rig_bag(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../bags/rig_40db")).unwrap();
    let mut p = Params::new();
    p.set("baseline", ParamValue::String(baseline.into()));
    let mut core = DiagnoserCore::from_params(&p, "/rig/diagnoser: gap diagnosis").unwrap();
    let mut out = core
        .handle(Input::RigMass(36.0), DEFAULT_RUN_START)
        .unwrap();
    for r in bag
        .records
        .iter()
        .filter(|r| matches!(r.excitation, Excitation::Sine { .. }))
    {
        let a = analyse_record(r, &PhasorOptions::for_identification()).unwrap();
        let ph = HarmonicPhasors::from_analysis(
            &a,
            DEFAULT_RUN_START,
            Header::new(DEFAULT_RUN_START, "rig"),
        );
        out.extend(
            core.handle(Input::Phasors(Box::new(ph)), DEFAULT_RUN_START)
                .unwrap(),
        );
    }
    let diagnosis = out.iter().rev().find_map(|o| match o {
        Output::Diagnosis(d) => Some(d.clone()),
        _ => None,
    });
    let status = out.iter().rev().find_map(|o| match o {
        Output::Status(s) => Some(s.clone()),
        _ => None,
    });
    (diagnosis.unwrap(), status.unwrap())
}

#[test]
fn a_linear_baseline_misses_the_coulomb_friction() {
    let (d, status) = last_diagnosis("linear");
    assert_eq!(d.steps, 10);
    assert_eq!(d.verdict, "explained");
    assert_eq!(d.top_effect, "coulomb_friction");
    assert!(
        d.gap_before_percent > 10.0 && d.gap_after_percent < 1.5,
        "{d:?}"
    );
    assert_eq!(status.level, DiagnosticStatus::WARN);
    assert!(
        status.message.contains("misses coulomb_friction"),
        "{}",
        status.message
    );
}

#[test]
fn the_coulomb_baseline_is_adequate() {
    let (d, status) = last_diagnosis("coulomb");
    assert_eq!(d.verdict, "adequate");
    assert_eq!(status.level, DiagnosticStatus::OK);
}
