//! Out-of-library cases scored: a confident name counts as a wrong name, a name "in part"
//! is counted apart, and "unexplained" or "adequate" count as neither.

use forcemap_eval::diagnose_eval::world::draw::draw;
use forcemap_eval::diagnose_eval::{CaseResult, CaseSpec, Planted, RankedCandidate, summarise};
use forcemap_math::diagnose::Verdict;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn cogging_case(index: usize, verdict: Verdict, named: &str) -> CaseResult {
    let mut rng = ChaCha8Rng::seed_from_u64(index as u64);
    let effect = draw("cogging", &mut rng).expect("an out-of-library family");
    CaseResult {
        case: CaseSpec {
            generator_seed: 1,
            index,
            seed: 1,
            planted: Planted::Wide { effect },
            snr_db: 30.0,
        },
        label: "out_of_library:cogging".into(),
        verdict,
        named: named.into(),
        gap_before_percent: 7.0,
        gap_after_percent: 4.0,
        truth_nmse_percent: 0.5,
        effect_gap_percent: 6.5,
        member_gap_percent: None,
        noise_floor_percent: 0.3,
        baseline_cv_percent: None,
        second: None,
        second_named: None,
        ranked: vec![RankedCandidate {
            effect: "stribeck_friction".into(),
            gap_after_percent: 4.0,
            score_percent: 4.0,
            step_cv_percent: None,
            output_error_misfit: None,
        }],
        baseline_output_error_misfit: None,
        notes: Vec::new(),
        best_pair: None,
    }
}

#[test]
fn out_of_library_names_in_part_are_counted_apart_from_confident_ones() {
    let cases = [
        cogging_case(0, Verdict::Explained, "stribeck_friction"),
        cogging_case(1, Verdict::ExplainedInPart, "stribeck_friction in part"),
        cogging_case(2, Verdict::ExplainedInPart, "series_compliance in part"),
        cogging_case(3, Verdict::Unexplained, "unexplained"),
        cogging_case(4, Verdict::Adequate, "adequate"),
    ]
    .map(Ok);
    let s = summarise(&cases, 30.0);
    assert_eq!(
        (s.out_of_library_named.hits, s.out_of_library_named.of),
        (1, 5)
    );
    assert_eq!(
        (
            s.out_of_library_named_in_part.hits,
            s.out_of_library_named_in_part.of
        ),
        (2, 5)
    );
    assert_eq!(s.false_alarms.of, 0, "no case without an effect");
}
