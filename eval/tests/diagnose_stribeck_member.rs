//! The verdict names the Stribeck member it found: its excess, velocity and shape exponent.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how they report failure"
)]

mod common;

use forcemap_math::diagnose::Effect;
use forcemap_math::diagnose::findings::Verdict;

/// A Gaussian Stribeck excess of 15 N at vs 20 mm/s on a linear rig at 30 dB (the wide forms'
/// world, seed of wide seed 2 case 89): named, and the verdict's member gives the fitted excess,
/// velocity and exponent, the candidate's own parameters after its output-error refit, and
/// does not rule out the planted Gaussian shape. Found: 14.9 N at 20.1 mm/s, exponent 2, 2.06 %
/// left against the truth's 2.51 % (with the velocity held on the phasor grid: 14.0 N at
/// 36.3 mm/s, 3.18 %). Before the refit updated the member, the verdict gave the phasor fit's
/// 8.3 N beside a refitted fs of 14.0 N (the test fails so).
#[test]
fn the_stribeck_member_is_named_with_its_excess_and_velocity() {
    let planted = common::stribeck_effect(15.0, 0.020, 2.0);
    let (d, _) = common::diagnose_world(
        "Gaussian Stribeck",
        &[planted],
        30.0,
        3_927_716_169_463_501_672,
    );
    assert_eq!(
        d.findings.verdict,
        Verdict::Explained,
        "{}",
        d.findings.headline()
    );
    let top = &d.ranked_effects[0];
    assert_eq!(top.effect, Effect::StribeckFriction);
    let member = top.member.as_deref().unwrap_or_default();
    println!("{}", d.findings.headline());
    let number_after = |label: &str| -> f64 {
        member
            .split(label)
            .nth(1)
            .and_then(|s| s.split_whitespace().next())
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("{label} in {member}"))
    };
    assert!(
        member.starts_with("Stribeck excess ") && member.contains(", exponent "),
        "{member}"
    );
    let parameter = |name: &str| {
        top.added_parameters
            .iter()
            .find(|p| p.name == name)
            .map(|p| p.value)
            .unwrap_or_else(|| panic!("{name} in {:?}", top.added_parameters))
    };
    assert!(
        (number_after("excess ") - parameter("fs")).abs() < 0.051,
        "{member} {:?}",
        top.added_parameters
    );
    assert!(
        (number_after("vs ") - 1e3 * parameter("stribeck_velocity_mps")).abs() < 0.051,
        "{member}"
    );
    assert!(parameter("fs") > 0.0);
    // The planted Gaussian shape is not ruled out: found, or among those predicting alike.
    let named = common::stribeck_exponents_named(member);
    assert!(named.contains(&2.0), "{member}");
    assert!(d.findings.headline().ends_with(&format!("({member})")));
}
