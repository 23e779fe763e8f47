//! The gap diagnosis on simulated rigs with a planted effect it is not told: known effects get
//! named, no effect gives "adequate", an effect outside the library gets no confident name, and
//! the live phasor-only diagnosis agrees on the paper's story.
#![allow(
    clippy::unwrap_used,
    reason = "test and bench helpers outside #[test] fns: a panic is how they report failure"
)]

use forcemap_eval::diagnose_eval::{CaseSpec, Planted, run_case, simulate_case};
use forcemap_math::diagnose::{Effect, PhasorDiagnosis, Verdict};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::phasor::PhasorOptions;
use forcemap_math::phasor::analyse_record;
use forcemap_math::recipe::Setup;
use forcemap_math::record::Excitation;

fn case(planted: Planted, seed: u64) -> CaseSpec {
    CaseSpec {
        // Built here, not drawn by a generator.
        generator_seed: 0,
        index: 0,
        seed,
        planted,
        snr_db: 30.0,
    }
}

fn named(effect: Effect, severity: u8, seed: u64) {
    let r = run_case(&case(Planted::One { effect, severity }, seed)).unwrap();
    println!(
        "{}: {} ({:.2} % -> {:.2} %, truth {:.2} %)",
        effect.name(),
        r.named,
        r.gap_before_percent,
        r.gap_after_percent,
        r.truth_nmse_percent
    );
    assert_eq!(r.named, effect.name(), "{r:?}");
    assert!(r.gap_after_percent < 0.5 * r.gap_before_percent, "{r:?}");
}

#[test]
fn coulomb_friction_is_named_against_the_linear_baseline() {
    named(Effect::CoulombFriction, 3, 11);
}

#[test]
fn cubic_stiffness_is_named() {
    named(Effect::CubicStiffness, 2, 12);
}

#[test]
fn asymmetric_damping_is_named() {
    named(Effect::AsymmetricDamping, 3, 13);
}

#[test]
fn exciter_delay_is_named() {
    named(Effect::ExciterDelay, 2, 14);
}

#[test]
fn hysteresis_is_named() {
    named(Effect::Hysteresis, 3, 15);
}

#[test]
fn free_play_is_named() {
    named(Effect::FreePlay, 3, 16);
}

#[test]
fn no_effect_is_adequate() {
    for seed in [21, 22] {
        let r = run_case(&case(Planted::None, seed)).unwrap();
        println!(
            "none: {} ({:.2} %, floor {:.2} %)",
            r.named, r.gap_before_percent, r.noise_floor_percent
        );
        assert_eq!(r.verdict, Verdict::Adequate, "{r:?}");
    }
}

/// The exact forms' compressible oil (a 3 kN/m spring in series with the damper) was out of
/// the library until series_compliance joined it; it is now named so, with its spring.
#[test]
fn compressible_oil_is_named_series_compliance() {
    let r = run_case(&case(
        Planted::CompressibleOil {
            oil_stiffness_n_per_m: 3000.0,
        },
        31,
    ))
    .unwrap();
    println!(
        "compressible oil: {} ({:.2} % -> {:.2} %)",
        r.named, r.gap_before_percent, r.gap_after_percent
    );
    assert!(
        r.gap_before_percent > 1.0,
        "the planted effect must open a gap: {r:?}"
    );
    assert_eq!(r.verdict, Verdict::Explained, "{r:?}");
    assert_eq!(r.named, "series_compliance", "{r:?}");
    assert_eq!(r.label, "series_compliance");
}

#[test]
fn live_phasor_diagnosis_names_coulomb_friction_and_passes_the_clean_rig() {
    for (planted, baseline, expect) in [
        (
            Planted::One {
                effect: Effect::CoulombFriction,
                severity: 3,
            },
            "linear",
            Some(Effect::CoulombFriction),
        ),
        (Planted::None, "coulomb", None),
    ] {
        let (_, records) = simulate_case(&case(planted, 41)).unwrap();
        let model = Model::by_name(baseline, &ModelOptions::default()).unwrap();
        let mut live = PhasorDiagnosis::new(Setup::BaseExcited { mass_kg: 36.0 }, model);
        for r in records
            .iter()
            .filter(|r| matches!(r.excitation, Excitation::Sine { .. }))
        {
            live.push(analyse_record(r, &PhasorOptions::for_identification()).unwrap());
        }
        let f = live.findings().unwrap();
        println!(
            "{}: {:?} {:?} ({:.2} % -> {:.2} %, floor {:.2} %)",
            planted.label(),
            f.findings.verdict,
            f.findings.top_effect,
            f.findings.gap_before_percent,
            f.findings.gap_after_percent,
            f.findings.floor_percent
        );
        assert_eq!(f.findings.top_effect, expect, "{f:?}");
        if expect.is_none() {
            assert_eq!(f.findings.verdict, Verdict::Adequate);
        }
    }
}

/// Strong Stribeck friction sticks the element through the slowest steps (the base force never
/// reaches breakaway): those steps are left out of the fits, and the friction is named. Case 73
/// of `forcemap diagnose-eval --seed 1` (30 dB).
#[test]
fn stribeck_friction_is_named_despite_stuck_steps() {
    let c = forcemap_eval::diagnose_eval::generate_cases(200, 1, 30.0)[73];
    assert!(
        matches!(
            c.planted,
            Planted::One {
                effect: Effect::StribeckFriction,
                ..
            }
        ),
        "{c:?}"
    );
    let r = run_case(&c).unwrap();
    println!(
        "stribeck_friction: {} ({:.2} % -> {:.2} %, truth {:.2} %)",
        r.named, r.gap_before_percent, r.gap_after_percent, r.truth_nmse_percent
    );
    assert_eq!(r.named, "stribeck_friction", "{r:?}");
}

/// Case `index` of the evaluation in docs/diagnosis.md (`diagnose-eval --cases 200 --seed 1`),
/// checked to plant `effect`.
fn eval_case(index: usize, effect: Effect) -> CaseSpec {
    eval_case_of_seed(1, index, effect)
}

fn eval_case_of_seed(seed: u64, index: usize, effect: Effect) -> CaseSpec {
    let c = forcemap_eval::diagnose_eval::generate_cases(200, seed, 30.0)[index];
    assert!(
        matches!(c.planted, Planted::One { effect: e, .. } if e == effect),
        "{c:?}"
    );
    c
}

#[test]
fn sensor_lowpass_is_named_with_the_cutoff_nearest_the_truth() {
    // Planted: a 4 Hz first-order low-pass on every channel (severity 3), 30 dB. Before the
    // model force was compared through the low-pass (instead of the low-pass being undone on
    // the measured force), the amplified noise of the high harmonics picked the highest cutoff
    // and the case came out "unexplained".
    let c = eval_case(101, Effect::SensorLowpass);
    let (truth, records) = simulate_case(&c).unwrap();
    let baseline = Model::by_name(truth.baseline, &ModelOptions::default()).unwrap();
    let setup = Setup::BaseExcited {
        mass_kg: forcemap_math::sim::rig::PAPER_RIG_MASS_KG,
    };
    let d = forcemap_math::diagnose::diagnose(
        &setup,
        &baseline,
        &records,
        &[],
        &forcemap_math::diagnose::DiagnoseOptions::default(),
    )
    .unwrap()
    .diagnosis;
    assert_eq!(d.findings.top_effect, Some(Effect::SensorLowpass), "{d:#?}");
    let cutoff = d.ranked_effects[0]
        .added_parameters
        .iter()
        .find(|p| p.name == "cutoff_hz")
        .unwrap()
        .value;
    // The searched grid is 0.75, 1, 1.5, 2, ... times the top step frequency (3.4 Hz): the
    // neighbours of 4 Hz are 3.4 and 5.1 Hz.
    assert!((3.4..=5.1).contains(&cutoff), "cutoff {cutoff} Hz");
}

#[test]
fn quadratic_stiffness_is_not_taken_for_free_play() {
    // The held-out records cannot tell x|x| from a dead-zone spring (1.93 against 1.87 %, both
    // near the true model's 1.94 %); the sine steps' harmonics can (cross-validated force error
    // 1.1 against 6.3 %).
    let r = run_case(&eval_case(110, Effect::QuadraticStiffness)).unwrap();
    assert_eq!(r.named, "quadratic_stiffness", "{r:?}");
    assert!(r.gap_after_percent < 0.2 * r.gap_before_percent, "{r:?}");
}

#[test]
fn strong_cubic_stiffness_is_not_taken_for_quadratic_stiffness() {
    // 40 dB; the true model's held-out NMSE (3.3 %) is above the quadratic candidate's (2.4 %):
    // the random records' prediction is biased for so strong a spring, the steps are not.
    let r = run_case(&eval_case(125, Effect::CubicStiffness)).unwrap();
    assert_eq!(r.named, "cubic_stiffness", "{r:?}");
    assert!(
        (r.gap_after_percent - r.truth_nmse_percent).abs() < 0.1,
        "{r:?}"
    );
}

#[test]
fn the_sine_steps_overrule_a_held_out_ranking_the_true_model_cannot_match() {
    // 40 dB, cubic stiffness with the rig's Coulomb friction: the true model itself leaves
    // 6.5 % on the random records (each breakaway's timing is that sensitive), x|x| + x^2 leaves
    // 2.4 %; on the sine steps x^3 leaves 0.55 % cross-validated, x|x| + x^2 7.0 %.
    let r = run_case(&eval_case_of_seed(2, 171, Effect::CubicStiffness)).unwrap();
    assert_eq!(r.named, "cubic_stiffness", "{r:?}");
    assert!(r.truth_nmse_percent > 3.0, "{r:?}");
}

/// Strong Stribeck friction whose excess the phasor fits underestimate (they leave out the
/// slow-slip phase where it acts: 5 N fitted for the 15 N planted): scored with its phasor fit
/// it leaves 3.45 % of a 3.93 % gap and ranks third, behind sensor_lowpass, and the verdict was
/// "adequate". Refitted by output error on the sine steps it leaves 2.3 %, is significant and
/// named. Case 139 of `forcemap diagnose-eval --seed 2` (30 dB).
#[test]
fn stribeck_friction_refitted_by_output_error_is_named() {
    let c = eval_case_of_seed(2, 139, Effect::StribeckFriction);
    let r = run_case(&c).unwrap();
    println!(
        "stribeck_friction: {} ({:.2} % -> {:.2} %, truth {:.2} %)",
        r.named, r.gap_before_percent, r.gap_after_percent, r.truth_nmse_percent
    );
    assert_eq!(r.named, "stribeck_friction", "{r:?}");
    assert!(r.gap_after_percent < 2.6, "{r:?}");
}

/// An exciter with its own resonance (10.4 Hz, damping ratio 0.23; out of the library)
/// amplifies the base the rig receives below its resonance, 1.11 times at 3.4 Hz. A delay
/// fitted to the kinematic identity's phases makes the rig's prediction good enough to name
/// exciter_delay with confidence (3.44 % -> 0.87 %); a delay never amplifies, so the candidate
/// is not offered and the gap stays unexplained. Case 172 of `forcemap diagnose-eval
/// --forms wide --seed 1`.
#[test]
fn an_exciter_resonance_is_not_named_exciter_delay() {
    let c = forcemap_eval::diagnose_eval::generate_wide_cases(300, 1)[172];
    assert_eq!(c.planted.label(), "out_of_library:exciter_resonance");
    let r = run_case(&c).unwrap();
    println!(
        "exciter resonance: {} ({:.2} % -> {:.2} %)",
        r.named, r.gap_before_percent, r.gap_after_percent
    );
    assert_ne!(r.verdict, Verdict::Explained, "{r:?}");
    assert!(
        r.ranked.iter().all(|c| c.effect != "exciter_delay"),
        "{r:?}"
    );
}

/// An exciter resonance is not named "in part" by a friction refit that fits the sine steps
/// no better than the baseline. Case 167 of `forcemap diagnose-eval --forms wide --seed 2`:
/// its Stribeck candidate, refitted by output error to a misfit of 3.192 noise std against the
/// baseline's 3.179, predicted the held-out records better (7.02 -> 4.11 %) and the verdict was
/// "explained in part by stribeck_friction". The refit is now credited only when it fits the
/// steps better; the note says why it was not, and the gap is unexplained.
#[test]
fn an_exciter_resonance_is_not_named_in_part_by_a_refit_that_fits_no_better() {
    let c = forcemap_eval::diagnose_eval::generate_wide_cases(300, 2)[167];
    assert_eq!(c.planted.label(), "out_of_library:exciter_resonance");
    let r = run_case(&c).unwrap();
    println!(
        "exciter resonance: {} ({:.2} % -> {:.2} %); notes {:?}",
        r.named, r.gap_before_percent, r.gap_after_percent, r.notes
    );
    assert_eq!(r.verdict, Verdict::Unexplained, "{r:?}");
    assert!(
        r.notes.iter().any(|n| n.starts_with(
            "stribeck_friction: its output-error refit fits the sine steps no better"
        )),
        "{:?}",
        r.notes
    );
    assert!(
        r.notes.iter().any(|n| n.contains("amplified")),
        "the amplified base is named: {:?}",
        r.notes
    );
}
