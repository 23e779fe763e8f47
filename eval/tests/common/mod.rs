//! What the wide-forms diagnosis tests share: a world simulated and diagnosed, with its ranking
//! printed so that a failing assertion shows why.

use forcemap_eval::diagnose_eval::world::{
    SensorDynamics, Term, World, WorldEffect, WorldKind, WorldRun, simulate,
};
use forcemap_math::diagnose::{DiagnoseOptions, Diagnosis, Effect, RankedEffect, diagnose};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::recipe::Setup;
use forcemap_math::sim::rig::PAPER_RIG_MASS_KG;

/// The world of `effects` (none: the paper's rig alone) over the paper's rig run at `snr_db`
/// from `seed`, diagnosed against the world's baseline; prints the headline, every ranked
/// candidate and the best pair under `label`.
#[allow(
    clippy::unwrap_used,
    reason = "a test helper: a panic is how it reports failure"
)]
pub fn diagnose_world(
    label: &str,
    effects: &[WorldEffect],
    snr_db: f64,
    seed: u64,
) -> (Diagnosis, WorldRun) {
    let world = World::of(effects);
    let run = simulate(&world, snr_db, seed).unwrap();
    let baseline = Model::by_name(world.baseline, &ModelOptions::default()).unwrap();
    let setup = Setup::BaseExcited {
        mass_kg: PAPER_RIG_MASS_KG,
    };
    let d = diagnose(
        &setup,
        &baseline,
        &run.records,
        &[],
        &DiagnoseOptions::default(),
    )
    .unwrap()
    .diagnosis;
    println!(
        "{label}: {} (truth {:.2} %)",
        d.findings.headline(),
        run.truth_nmse_percent
    );
    for r in &d.ranked_effects {
        println!(
            "  {:<20} {:8.3} % score {:8.3} {:?} {:?}",
            r.effect.name(),
            r.gap_after_percent,
            r.score_percent,
            r.member,
            r.added_parameters
        );
    }
    if let Some(p) = &d.best_pair {
        println!(
            "  pair {} + {}: {:.3} % score {:.3}",
            p.effects[0].name(),
            p.effects[1].name(),
            p.gap_after_percent,
            p.score_percent
        );
    }
    (d, run)
}

/// A hardening spring of `cubic_n_per_m3` x^3 + `quintic_n_per_m5` x^5, planted as
/// cubic_stiffness (the candidate is x^3 alone).
#[allow(dead_code, reason = "not every test file plants a spring")]
pub fn hardening_spring(cubic_n_per_m3: f64, quintic_n_per_m5: f64) -> WorldEffect {
    let odd = |coef, exponent| Term::OddPower {
        coef,
        exponent,
        on_velocity: false,
    };
    WorldEffect::of_terms(
        "cubic_stiffness",
        WorldKind::Library,
        [
            Some(odd(cubic_n_per_m3, 3.0)),
            Some(odd(quintic_n_per_m5, 5.0)),
        ],
    )
}

/// A free play with contact at `gap_pos_m` and -`gap_neg_m` and a stop of `stiffness_n_per_m`,
/// planted as free_play (the wide forms' form: unequal gaps, its own stiffness).
#[allow(dead_code, reason = "not every test file plants a free play")]
pub fn free_play_effect(gap_neg_m: f64, gap_pos_m: f64, stiffness_n_per_m: f64) -> WorldEffect {
    WorldEffect::of_terms(
        "free_play",
        WorldKind::Library,
        [
            Some(Term::FreePlay {
                gap_neg_m,
                gap_pos_m,
                stiffness_n_per_m,
            }),
            None,
        ],
    )
}

/// A Stribeck excess of `excess_n` decaying as exp(-|v/velocity_mps|^exponent), planted as
/// stribeck_friction (the wide forms' form: its shape exponent drawn, not only the Gaussian 2).
#[allow(dead_code, reason = "not every test file plants a Stribeck friction")]
pub fn stribeck_effect(excess_n: f64, velocity_mps: f64, exponent: f64) -> WorldEffect {
    WorldEffect::of_terms(
        "stribeck_friction",
        WorldKind::Library,
        [
            Some(Term::Stribeck {
                excess_n,
                velocity_mps,
                exponent,
            }),
            None,
        ],
    )
}

/// The first two effects of the ranking.
#[allow(
    dead_code,
    reason = "not every test file looks at the ranking's top two"
)]
pub fn top_two(d: &Diagnosis) -> Vec<Effect> {
    d.ranked_effects.iter().take(2).map(|r| r.effect).collect()
}

/// Sensor dynamics planted as the sensor_lowpass family (no element term).
#[allow(dead_code, reason = "not every test file plants a sensor filter")]
pub fn sensor_effect(sensor: SensorDynamics) -> WorldEffect {
    WorldEffect {
        sensor: Some(sensor),
        ..WorldEffect::of_terms("sensor_lowpass", WorldKind::Library, [None, None])
    }
}

/// The value of a ranked candidate's added or searched parameter `name`, if it has one.
#[allow(dead_code, reason = "not every test file reads a searched parameter")]
pub fn searched(r: &RankedEffect, name: &str) -> Option<f64> {
    r.added_parameters
        .iter()
        .find(|p| p.name == name)
        .map(|p| p.value)
}

/// The Stribeck shape exponents a verdict's member names: the one found ("exponent 1.0") and,
/// when the held-out records do not tell them apart, those that predict alike ("exponents 0.5,
/// 1.0 and 2.0 predict ...").
#[allow(dead_code, reason = "not every test file reads a Stribeck member")]
pub fn stribeck_exponents_named(member: &str) -> Vec<f64> {
    let number = |s: &str| {
        s.trim_matches(|c: char| !c.is_ascii_digit() && c != '.')
            .parse()
            .ok()
    };
    let mut named: Vec<f64> = member
        .split("exponent ")
        .nth(1)
        .and_then(|s| s.split_whitespace().next())
        .and_then(number)
        .into_iter()
        .collect();
    if let Some(list) = member.split("exponents ").nth(1) {
        let list = list.split(" predict").next().unwrap_or_default();
        named.extend(list.split([',', ' ']).filter_map(number));
    }
    named
}
