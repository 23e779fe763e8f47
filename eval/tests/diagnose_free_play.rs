//! Free play with unequal gaps, planted in the wide forms' world (its own element, not the
//! candidate's dead zone): the free_play family searches each contact point, so the top effect
//! is free play with its contact points near the world's, and a centred gap is still found
//! centred, with one shape parameter.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how they report failure"
)]

mod common;

use common::searched;
use forcemap_math::diagnose::{Diagnosis, Effect, RankedEffect, Verdict};

fn top(d: &Diagnosis) -> &RankedEffect {
    &d.ranked_effects[0]
}

/// Contact at +4.0 mm and -1.2 mm, a 5 kN/m stop, 30 dB: named free_play with the contact
/// points within 0.5 mm of the world's (found: +4.43 and -1.36 mm with 4.75 kN/m, leaving the
/// true model's held-out NMSE, 0.53 against 0.52 %: a later contact with a softer stop and the
/// refitted k trade off against each other).
#[test]
fn unequal_gaps_are_found_with_their_contact_points() {
    let (d, _) = common::diagnose_world(
        "free play +4.0 / -1.2 mm",
        &[common::free_play_effect(0.0012, 0.0040, 5000.0)],
        30.0,
        3,
    );
    let r = top(&d);
    assert_eq!(r.effect, Effect::FreePlay, "{}", d.findings.headline());
    assert_eq!(
        d.findings.verdict,
        Verdict::Explained,
        "{}",
        d.findings.headline()
    );
    let pos = searched(r, "contact_pos_m").unwrap();
    let neg = searched(r, "contact_neg_m").unwrap();
    assert!((pos - 0.0040).abs() < 0.5e-3, "contact at +{pos}");
    assert!((neg + 0.0012).abs() < 0.5e-3, "contact at {neg}");
    assert_eq!(r.extra_parameters, 3);
    let h = d.findings.headline();
    assert!(h.contains("contact at +") && h.contains("mm and -"), "{h}");
}

/// Equal gaps of 2 mm, the same stop: still named free_play, centred (one shape parameter, the
/// width, within 0.4 mm of 4 mm).
#[test]
fn a_centred_gap_is_still_found_centred() {
    let (d, _) = common::diagnose_world(
        "free play +/-2.0 mm",
        &[common::free_play_effect(0.0020, 0.0020, 5000.0)],
        30.0,
        3,
    );
    let r = top(&d);
    assert_eq!(r.effect, Effect::FreePlay, "{}", d.findings.headline());
    let gap = searched(r, "gap_m").unwrap_or_else(|| panic!("{:?}", r.added_parameters));
    assert!((gap - 0.0040).abs() < 0.4e-3, "gap {gap}");
    assert_eq!(r.extra_parameters, 2);
}
