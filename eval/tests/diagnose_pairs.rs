//! Two effects planted together in the wide forms' world: the second is searched on what the
//! first leaves (fitted jointly with it), so both are the two best-ranked and the verdict names
//! the pair; one effect alone is not reported as a pair. When the top candidate is a neighbour
//! of a planted effect, the exchange step puts the planted effect in its place.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how they report failure"
)]

mod common;

use forcemap_eval::diagnose_eval::world::{Term, WorldEffect, WorldKind};
use forcemap_math::diagnose::{Diagnosis, Effect, Verdict};

/// Coulomb friction of `level_n`, 20 % stronger in one direction than the other (wider than
/// the candidate's symmetric form).
fn coulomb(level_n: f64) -> WorldEffect {
    WorldEffect::of_terms(
        "coulomb_friction",
        WorldKind::Library,
        [
            Some(Term::Coulomb {
                level_n,
                asymmetry: 0.2,
            }),
            None,
        ],
    )
}

/// A hardening spring of `force_n` at 6 mm, 95 % x^3 and 5 % x^5 (the candidate is x^3).
fn cubic(force_n: f64) -> WorldEffect {
    let x = 0.006f64;
    common::hardening_spring(0.95 * force_n / x.powi(3), 0.05 * force_n / x.powi(5))
}

fn diagnosed(effects: &[WorldEffect], snr_db: f64, seed: u64) -> Diagnosis {
    let names: Vec<&str> = effects.iter().map(|e| e.name).collect();
    common::diagnose_world(&names.join(" + "), effects, snr_db, seed).0
}

#[test]
fn coulomb_friction_with_cubic_stiffness_is_named_as_the_pair() {
    let d = diagnosed(&[coulomb(10.0), cubic(3.0)], 30.0, 7);
    let top = common::top_two(&d);
    assert!(
        top.contains(&Effect::CoulombFriction) && top.contains(&Effect::CubicStiffness),
        "{top:?}"
    );
    assert_eq!(d.findings.verdict, Verdict::Explained);
    let h = d.findings.headline();
    assert!(
        h.starts_with("explained by coulomb_friction together with cubic_stiffness")
            || h.starts_with("explained by cubic_stiffness together with coulomb_friction"),
        "{h}"
    );
}

/// `coef sgn(u) |u|^exponent` of the displacement or the velocity.
fn power(name: &'static str, coef: f64, exponent: f64, on_velocity: bool) -> WorldEffect {
    WorldEffect::of_terms(
        name,
        WorldKind::Library,
        [
            Some(Term::OddPower {
                coef,
                exponent,
                on_velocity,
            }),
            None,
        ],
    )
}

/// `diagnose-eval --forms wide --seed 1` case 44: a spring of about 34 N at 6 mm growing as
/// x^2.09 with a damper of about 20 N at 0.1 m/s growing as v^2.18. Free play alone fits the
/// spring best (the gap it searches stands in for the exponent), so the pair search with free
/// play on top found quadratic damping beside it but not quadratic stiffness; the exchange
/// step tries the rivals of free play beside quadratic damping, and the planted pair wins.
#[test]
fn the_exchange_step_replaces_a_neighbour_on_top_by_the_planted_effect() {
    let d = diagnosed(
        &[
            power("quadratic_stiffness", 1.450_188_578e6, 2.086_278_185, false),
            power("quadratic_damping", 2_988.111_023, 2.180_387_963, true),
        ],
        30.0,
        14_425_615_679_580_274_233,
    );
    assert_eq!(
        common::top_two(&d),
        [Effect::QuadraticStiffness, Effect::QuadraticDamping]
    );
    assert_eq!(
        d.findings.headline().split(':').next(),
        Some("explained by quadratic_stiffness together with quadratic_damping")
    );
}

#[test]
fn one_effect_alone_is_not_named_as_a_pair() {
    for (effects, name) in [
        (vec![cubic(20.0)], "cubic_stiffness"),
        (vec![coulomb(8.0)], "coulomb_friction"),
    ] {
        let d = diagnosed(&effects, 30.0, 7);
        assert_eq!(d.findings.verdict, Verdict::Explained);
        assert_eq!(
            d.findings
                .top_effect
                .map(forcemap_math::diagnose::Effect::name),
            Some(name)
        );
        assert_eq!(d.findings.second_effect, None, "{}", d.findings.headline());
    }
}
