//! Pairs with a sensor filter in them: a filter on one channel distorts what the element laws
//! are fitted on, so the second planted effect fitted alone may come out unphysical or
//! unstable (quadratic damping with a negative coefficient, whose replay diverges) and was
//! never tried beside the filter. The pair search now tries such partners jointly with the top
//! candidate ([`forcemap_math::diagnose::pair_partners`]); the planted pair ranks first and
//! second, the partner with the pair's figures (`fitted_with`).

use forcemap_math::diagnose::sensor::{SensorFilter, apply_samples};
use forcemap_math::diagnose::{DiagnoseOptions, Diagnosis, Effect, diagnose};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::recipe::Setup;
use forcemap_math::record::{Channel, Record};
use forcemap_math::sim::rig::PAPER_RIG_MASS_KG;
use forcemap_math::sim::{RunSpec, TruthElement};

/// The paper's Coulomb rig with quadratic damping `c2 v|v|` added, 30 dB, its relative
/// displacement seen through `filter` (applied to the noisy samples, as a sensor's
/// conditioning would), diagnosed against the Coulomb baseline.
fn diagnosed(c2_n_s2_per_m2: f64, filter: &SensorFilter, seed: u64) -> Diagnosis {
    let element = TruthElement {
        quadratic_damping_n_s2_per_m2: c2_n_s2_per_m2,
        ..TruthElement::rig_coulomb()
    };
    let mut records: Vec<Record> = RunSpec::paper_rig(Some(30.0), seed)
        .with_element(element)
        .simulate()
        .expect("the rig run");
    for r in &mut records {
        let fs = r.sample_rate_hz;
        for (c, v) in &mut r.channels {
            if filter.applies_to(*c) {
                *v = apply_samples(v, fs, filter);
            }
        }
    }
    let baseline = Model::by_name("coulomb", &ModelOptions::default()).expect("a known model");
    let setup = Setup::BaseExcited {
        mass_kg: PAPER_RIG_MASS_KG,
    };
    diagnose(
        &setup,
        &baseline,
        &records,
        &[],
        &DiagnoseOptions::default(),
    )
    .expect("the diagnosis")
    .diagnosis
}

fn ranked_text(d: &Diagnosis) -> String {
    d.ranked_effects
        .iter()
        .map(|r| {
            format!(
                "{} {:.3} % (score {:.3}, CV {:?}, with {:?})",
                r.effect.name(),
                r.gap_after_percent,
                r.score_percent,
                r.phasor_cv_percent,
                r.fitted_with.map(Effect::name)
            )
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// A second-order filter on the relative displacement (wide seed 1 case 192's form: 4.6 Hz,
/// damping ratio 0.62) and quadratic damping of 800 N s^2/m^2: alone, quadratic damping is
/// fitted with a negative coefficient and cannot be simulated, so it had no ranked entry and
/// the pair search never tried it (before: the second place went to asymmetric damping).
#[test]
fn quadratic_damping_behind_a_relative_displacement_filter_ranks_second() {
    let c2_n_s2_per_m2 = 800.0;
    let filter = SensorFilter::on(Channel::RelativeDisplacementM, 2, 4.6, 0.62);
    let d = diagnosed(c2_n_s2_per_m2, &filter, 1);
    let text = ranked_text(&d);
    println!("{}\n{text}\npair {:?}", d.findings.headline(), d.best_pair);
    let top: Vec<Effect> = d.ranked_effects.iter().take(2).map(|r| r.effect).collect();
    assert_eq!(
        top,
        [Effect::SensorLowpass, Effect::QuadraticDamping],
        "{text}"
    );
    // Alone it has no held-out figures: it ranks with the pair's, fitted with the filter.
    assert_eq!(
        d.ranked_effects[1].fitted_with,
        Some(Effect::SensorLowpass),
        "{text}"
    );
    let pair = d.best_pair.as_ref().expect("a best pair");
    assert_eq!(
        pair.effects,
        [Effect::SensorLowpass, Effect::QuadraticDamping]
    );
    let c2 = pair
        .added_parameters
        .iter()
        .find(|p| p.name == "c2")
        .expect("c2 in the pair")
        .value;
    assert!((c2 / c2_n_s2_per_m2 - 1.0).abs() < 0.25, "c2 {c2}");
    // The pair leaves a fraction of what the filter alone leaves.
    assert!(
        pair.gap_after_percent < 0.8 * d.ranked_effects[0].gap_after_percent,
        "{text}"
    );
}
