//! A wide pair's members scored alone: each member planted alone on the pair's own rig, and
//! the pair rate over pairs whose members each cause at least 2 % alone counting only those.

use forcemap_eval::diagnose_eval::world::World;
use forcemap_eval::diagnose_eval::world::draw::draw;
use forcemap_eval::diagnose_eval::{CaseResult, CaseSpec, Planted, RankedCandidate, summarise};
use forcemap_math::diagnose::Verdict;
use forcemap_math::sim::TruthElement;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

#[test]
fn a_member_alone_keeps_the_pairs_rig_and_baseline_and_only_its_own_terms() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let coulomb = draw("coulomb_friction", &mut rng).expect("a library family");
    let sensor = draw("sensor_lowpass", &mut rng).expect("a library family");
    let cubic = draw("cubic_stiffness", &mut rng).expect("a library family");
    let pair = [coulomb, sensor];
    let whole = World::of(&pair);
    assert_eq!(whole.baseline, "linear");

    let sensor_alone = World::with_only(&pair, 1);
    // On the pair's linear rig against its linear baseline, not on the Coulomb rig that
    // World::of gives the sensor filter alone.
    assert_eq!(sensor_alone.element.base, whole.element.base);
    assert_ne!(
        World::of(&pair[1..]).element.base,
        whole.element.base,
        "the check needs a rig that differs"
    );
    assert_eq!(sensor_alone.baseline, "linear");
    assert!(sensor_alone.element.terms.is_empty());
    assert_eq!(sensor_alone.sensors, whole.sensors);

    let coulomb_alone = World::with_only(&pair, 0);
    assert_eq!(coulomb_alone, World::of(&pair[..1]));
    assert!(coulomb_alone.sensors.is_empty());

    let other = [cubic, sensor];
    let cubic_alone = World::with_only(&other, 0);
    assert_eq!(cubic_alone.element.base, TruthElement::rig_coulomb());
    assert_eq!(cubic_alone.baseline, "coulomb");
    assert_eq!(cubic_alone.element.terms, World::of(&other).element.terms);
    assert!(cubic_alone.sensors.is_empty() && cubic_alone.exciter.is_none());
}

fn pair_case(index: usize, ranked: [&str; 2], member_gap_percent: [f64; 2]) -> CaseResult {
    let mut rng = ChaCha8Rng::seed_from_u64(index as u64);
    let effects = [
        draw("cubic_stiffness", &mut rng).expect("a library family"),
        draw("stribeck_friction", &mut rng).expect("a library family"),
    ];
    CaseResult {
        case: CaseSpec {
            generator_seed: 1,
            index,
            seed: 1,
            planted: Planted::WidePair { effects },
            snr_db: 30.0,
        },
        label: "cubic_stiffness+stribeck_friction".into(),
        verdict: Verdict::Explained,
        named: ranked[0].into(),
        gap_before_percent: 20.0,
        gap_after_percent: 1.0,
        truth_nmse_percent: 0.5,
        effect_gap_percent: 19.5,
        member_gap_percent: Some(member_gap_percent),
        noise_floor_percent: 0.3,
        baseline_cv_percent: None,
        second: Some(ranked[1].into()),
        second_named: None,
        ranked: ranked
            .iter()
            .map(|n| RankedCandidate {
                effect: n.to_string(),
                gap_after_percent: 1.0,
                score_percent: 1.0,
                step_cv_percent: None,
                output_error_misfit: None,
            })
            .collect(),
        baseline_output_error_misfit: None,
        notes: Vec::new(),
        best_pair: None,
    }
}

#[test]
fn pairs_with_a_member_too_small_alone_are_left_out_of_the_qualifying_rate() {
    let cases = [
        // Both found, both large: counted, a hit.
        pair_case(0, ["cubic_stiffness", "stribeck_friction"], [15.0, 3.0]),
        // Friction missed but it causes 0.4 % alone: in the all-pairs rate only.
        pair_case(1, ["cubic_stiffness", "quadratic_stiffness"], [15.0, 0.4]),
        // Friction missed though it causes 2.5 % alone: counted, a miss.
        pair_case(2, ["cubic_stiffness", "free_play"], [15.0, 2.5]),
    ]
    .map(Ok);
    let s = summarise(&cases, 30.0);
    assert_eq!((s.pairs_both_top_two.hits, s.pairs_both_top_two.of), (1, 3));
    assert_eq!(
        (
            s.pairs_qualifying_both_top_two.hits,
            s.pairs_qualifying_both_top_two.of
        ),
        (1, 2)
    );
}
