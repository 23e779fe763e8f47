//! The paper's suspension rig (36 kg, Coulomb truth k 6380 N/m, c 184 N s/m, F_d 12.3 N) with a
//! Bouc-Wen loop of the one-parameter law (yield 5 mm, saturated at 20 N), as `forcemap
//! simulate` makes it with [`SIMULATE_ARGS`]: its truth, checked against an identification's
//! parameters and simulated on a record (the floor the noise leaves).

use forcemap_math::diagnose::effects::Transform;
use forcemap_math::diagnose::fitted_element::FittedElement;
use forcemap_math::diagnose::score::predict_record;
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::record::Record;
use forcemap_math::signal::bouc_wen::HysteresisLaw;

/// `forcemap simulate`'s options that plant the loop.
pub const SIMULATE_ARGS: [&str; 6] = [
    "--bouc-wen-alpha-n-per-m",
    "4000",
    "--bouc-wen-beta-per-m-pow-n",
    "100",
    "--bouc-wen-gamma-per-m-pow-n",
    "100",
];

const ALPHA_N_PER_M: f64 = 4000.0;
const YIELD_M: f64 = 0.005;

/// The truth of `coulomb+hysteresis`'s parameters, by name.
pub const TRUTH: [(&str, f64); 5] = [
    ("k", 6380.0),
    ("c", 184.0),
    ("fd", 12.3),
    ("alpha", ALPHA_N_PER_M),
    ("yield_m", YIELD_M),
];

/// Each of `parameters` (an identification's `--json` list) within `tolerance` (relative) of
/// the truth, printed with its error.
pub fn assert_parameters_within(parameters: &serde_json::Value, tolerance: f64) {
    for (name, t) in TRUTH {
        let found = crate::common::parameter_value(parameters, name);
        eprintln!(
            "{name}: {found:.6e} (truth {t}, {:+.2} %)",
            100.0 * (found / t - 1.0)
        );
        assert!(
            (found / t - 1.0).abs() < tolerance,
            "{name}: {found} against {t}"
        );
    }
}

/// The held-out NMSE [%] of the mass acceleration the truth leaves on `record`, simulated
/// under its measured base: the floor its noise sets.
pub fn truth_nmse_percent(record: &Record) -> f64 {
    let coulomb = Model::by_name("coulomb", &ModelOptions::default()).unwrap();
    let element = FittedElement::new(
        coulomb.terms.clone(),
        TRUTH[..3].iter().map(|(_, t)| *t).collect(),
        Some((ALPHA_N_PER_M, HysteresisLaw::yield_law(YIELD_M))),
        None,
        None,
    );
    predict_record(&element, 36.0, record, &Transform::default())
        .unwrap()
        .nmse_percent
}
