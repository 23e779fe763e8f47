//! Table 1: the 3-DOF example simulated exactly, identified through the drive-point FRF of
//! substructure I (eq. 22).
#![allow(
    clippy::unwrap_used,
    reason = "test and bench helpers outside #[test] fns: a panic is how they report failure"
)]

use forcemap_eval::paper::TABLE1_TRUTH;
use forcemap_eval::reproduce::phasor_options;
use forcemap_math::frf::LinearSubstructure;
use forcemap_math::identify::{FdMultiOptions, Identification, Method};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::pipeline::identify_records;
use forcemap_math::recipe::Setup;
use forcemap_math::record::Record;
use forcemap_math::sim::excitation::derive_seed;
use forcemap_math::sim::noise::add_noise;
use forcemap_math::sim::{RunSpec, ThreeDofCase};
use std::sync::OnceLock;

fn case(which: &str) -> &'static Vec<Record> {
    static I: OnceLock<Vec<Record>> = OnceLock::new();
    static II: OnceLock<Vec<Record>> = OnceLock::new();
    let (cell, run) = if which == "I" {
        (&I, RunSpec::three_dof(ThreeDofCase::I, None, 0))
    } else {
        (&II, RunSpec::three_dof(ThreeDofCase::Ii, None, 0))
    };
    cell.get_or_init(|| run.simulate().expect("simulation runs"))
}

fn identify(which: &str, method: Method) -> Identification {
    let setup = Setup::DrivePoint {
        substructure: LinearSubstructure::paper_three_dof_substructure_i(),
    };
    let model = Model::by_name("coulomb-cubic", &ModelOptions::default()).unwrap();
    identify_records(
        &model,
        &setup,
        method,
        case(which),
        &phasor_options(),
        &FdMultiOptions::default(),
    )
    .expect("identifies")
}

fn errors(id: &Identification) -> [f64; 4] {
    let (k, c, fd, s) = TABLE1_TRUTH;
    let e = |n: &str, t: f64| (id.value(n).unwrap() / t - 1.0).abs();
    [e("k", k), e("c", c), e("fd", fd), e("s", s)]
}

#[test]
fn paper_method_is_good_in_case_ii_and_clearly_worse_in_case_i() {
    let e1 = errors(&identify("I", Method::Fd));
    let e2 = errors(&identify("II", Method::Fd));
    // CASE II within a few % on k, F_d and S (c within 15 %), as in the paper's Table 1.
    assert!(
        e2[0] < 0.06 && e2[2] < 0.05 && e2[3] < 0.07 && e2[1] < 0.15,
        "CASE II errors {e2:?}"
    );
    // CASE I: the element sticks for much of the cycle; first-harmonic sgn cannot describe it.
    let worst1 = e1.iter().copied().fold(0.0, f64::max);
    let worst2 = e2.iter().copied().fold(0.0, f64::max);
    assert!(
        worst1 > 0.3 && worst1 > 3.0 * worst2,
        "CASE I {e1:?} vs CASE II {e2:?}"
    );
}

#[test]
fn improved_method_noise_free_case_ii_within_half_percent() {
    let e = errors(&identify("II", Method::FdMulti));
    assert!(e.iter().all(|v| *v < 0.005), "CASE II errors {e:?}");
}

#[test]
fn improved_method_noise_free_case_i_within_two_percent() {
    let id = identify("I", Method::FdMulti);
    let e = errors(&id);
    assert!(e.iter().all(|v| *v < 0.02), "CASE I errors {e:?}");
    // the 5 N step never slips in steady state: it is left out and the user is told
    assert!(
        !id.steps_used.contains(&0),
        "steps used {:?}",
        id.steps_used
    );
    assert!(
        id.warnings
            .iter()
            .any(|w| w.contains("step 0") && w.contains("did not slip")),
        "{:?}",
        id.warnings
    );
}

#[test]
fn steep_atan_friction_is_treated_as_friction_and_agrees_with_sgn() {
    // The truth sticks whatever law the model smooths friction with: with M = 1e5 the atan model
    // must give what the sgn model gives, in CASE I where the element sticks for much of the cycle.
    let setup = Setup::DrivePoint {
        substructure: LinearSubstructure::paper_three_dof_substructure_i(),
    };
    let atan = Model::by_name(
        "coulomb-atan-cubic",
        &ModelOptions {
            atan_slope_s_per_m: Some(1e5),
            polynomial_order: None,
        },
    )
    .unwrap();
    let id = identify_records(
        &atan,
        &setup,
        Method::FdMulti,
        case("I"),
        &phasor_options(),
        &FdMultiOptions::default(),
    )
    .unwrap();
    let e = errors(&id);
    assert!(e.iter().all(|v| *v < 0.02), "CASE I atan(1e5) errors {e:?}");
}

#[test]
fn improved_method_at_40_db_over_three_noise_seeds() {
    let setup = Setup::DrivePoint {
        substructure: LinearSubstructure::paper_three_dof_substructure_i(),
    };
    let model = Model::by_name("coulomb-cubic", &ModelOptions::default()).unwrap();
    for seed in [0, 1, 2] {
        for (name, run, bound) in [
            // the acceptance target for CASE I is 5 %
            ("I", ThreeDofCase::I, 0.05),
            // fd-multi's scatter of c at 40 dB (std ~1.5 %) reaches 2.8 %; the 2 % target of
            // CASE II is met by the output-error refinement (tests below)
            ("II", ThreeDofCase::Ii, 0.03),
        ] {
            let records = RunSpec::three_dof(run, Some(40.0), seed)
                .simulate()
                .unwrap();
            let id = identify_records(
                &model,
                &setup,
                Method::FdMulti,
                &records,
                &phasor_options(),
                &FdMultiOptions::default(),
            )
            .unwrap();
            let e = errors(&id);
            assert!(
                e.iter().all(|v| *v < bound),
                "CASE {name} seed {seed}: errors {e:?}"
            );
            // the reported standard deviations are honest: each error is within 3 std
            let (k, c, fd, s) = TABLE1_TRUTH;
            for (p, truth) in id.parameters.iter().zip([k, c, fd, s]) {
                assert!(
                    (p.value - truth).abs() < 3.0 * p.std,
                    "CASE {name} seed {seed}: {} = {} +- {}",
                    p.name,
                    p.value,
                    p.std
                );
            }
        }
    }
}

/// The run's records with white measurement noise at `snr_db` as `simulate` adds it for `seed`
/// (the sine program does not depend on the seed, so the noise-free run is simulated once).
fn noisy(which: &str, snr_db: f64, seed: u64) -> Vec<Record> {
    let mut rec = case(which).clone();
    add_noise(&mut rec, Some(snr_db), derive_seed(seed, 1));
    rec
}

#[test]
fn noise_added_here_is_the_simulators_noise() {
    let direct = RunSpec::three_dof(ThreeDofCase::Ii, Some(40.0), 3)
        .simulate()
        .unwrap();
    assert_eq!(direct, noisy("II", 40.0, 3));
}

fn identify_on(records: &[Record], method: Method) -> Identification {
    let setup = Setup::DrivePoint {
        substructure: LinearSubstructure::paper_three_dof_substructure_i(),
    };
    let model = Model::by_name("coulomb-cubic", &ModelOptions::default()).unwrap();
    identify_records(
        &model,
        &setup,
        method,
        records,
        &phasor_options(),
        &FdMultiOptions::default(),
    )
    .expect("identifies")
}

#[test]
fn output_error_noise_free_within_a_tenth_of_a_percent() {
    for which in ["I", "II"] {
        let id = identify_on(case(which), Method::OutputError);
        let e = errors(&id);
        assert!(e.iter().all(|v| *v < 1e-3), "CASE {which} errors {e:?}");
        assert_eq!(id.method, "output-error");
    }
}

/// The 40 dB targets (CASE II every parameter within 2 %, CASE I within 5 %) over ten noise
/// seeds, and honest standard deviations: each error within 3.5 reported std, and the scatter
/// over the seeds of the same size as the reported std.
#[test]
fn output_error_at_40_db_over_ten_noise_seeds() {
    let (k, c, fd, s) = TABLE1_TRUTH;
    for (which, bound) in [("II", 0.02), ("I", 0.05)] {
        let mut c_err = Vec::new();
        let mut c_std = Vec::new();
        for seed in 0..10 {
            let id = identify_on(&noisy(which, 40.0, seed), Method::OutputError);
            let e = errors(&id);
            assert!(
                e.iter().all(|v| *v < bound),
                "CASE {which} seed {seed}: errors {e:?}"
            );
            for (p, truth) in id.parameters.iter().zip([k, c, fd, s]) {
                assert!(
                    (p.value - truth).abs() < 3.5 * p.std,
                    "CASE {which} seed {seed}: {} = {} +- {}",
                    p.name,
                    p.value,
                    p.std
                );
            }
            c_err.push(id.value("c").unwrap() / c - 1.0);
            c_std.push(id.parameters[1].std / c);
        }
        let rms = (c_err.iter().map(|e| e * e).sum::<f64>() / c_err.len() as f64).sqrt();
        let std = c_std.iter().sum::<f64>() / c_std.len() as f64;
        assert!(
            rms < 2.0 * std && rms > 0.3 * std,
            "CASE {which}: RMS error of c {rms:.2e} against reported std {std:.2e}"
        );
    }
}
