//! A second-order sensor filter on every channel near the top excitation frequency (wide seed 2
//! case 47, seed 3 case 159): undone on the held-out records by central differences it would
//! lose to the baseline there (two central differences fall 8 % short at 8 Hz, where x'' /
//! wc^2 dominates the undo), and its grid member (3.4 Hz, damping 0.7) leaves a lag. Undone by
//! sixth-order stencils and refined on the sine steps (`sensor::refine_on_every_channel`), the
//! member is named, its cutoff near the planted one.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how they report failure"
)]

mod common;

use common::{searched, sensor_effect};
use forcemap_eval::diagnose_eval::world::SensorDynamics;
use forcemap_math::diagnose::sensor::ALL_CHANNELS;
use forcemap_math::diagnose::{Diagnosis, Effect, Verdict};

/// The diagnosis of the world with `sensor` on every channel at 30 dB from `seed`.
fn diagnosed(label: &str, sensor: SensorDynamics, seed: u64) -> (Diagnosis, f64) {
    let (d, run) = common::diagnose_world(label, &[sensor_effect(sensor)], 30.0, seed);
    (d, run.truth_nmse_percent)
}

#[test]
fn a_second_order_filter_on_every_channel_near_the_top_frequency_is_named_with_its_cutoff() {
    // (label, cutoff, damping, delay, seed): the cases' planted filters and world seeds.
    let cases = [
        (
            "seed 2 case 47",
            3.056_354_996_565_709_3,
            0.561_198_599_028_768_1,
            0.000_693_604_443_519_467_7,
            17_216_009_713_837_823_111,
        ),
        (
            "seed 3 case 159",
            3.440_197_086_946_206_6,
            0.645_489_692_334_008_8,
            0.003_971_858_107_145_601,
            10_360_437_349_429_903_023,
        ),
    ];
    for (label, cutoff_hz, damping_ratio, delay_s, seed) in cases {
        let (d, truth) = diagnosed(
            label,
            SensorDynamics {
                mask: ALL_CHANNELS,
                order: 2,
                cutoff_hz,
                damping_ratio,
                delay_s,
            },
            seed,
        );
        assert_eq!(d.findings.verdict, Verdict::Explained, "{label}");
        assert_eq!(
            d.findings.top_effect,
            Some(Effect::SensorLowpass),
            "{label}"
        );
        let member = d.findings.top_member.clone().unwrap();
        assert!(member.starts_with("all channels, 2nd order"), "{member}");
        // The grid's second-order cutoffs are multiples of the top step frequency, 3.4 Hz, 11 %
        // above case 47's: refined, within 5 % of it. The steps pin the filter down loosely
        // (on a linear element a filter on every channel cancels; only the friction's
        // harmonics see it): case 159's is refined to 3.21 Hz, damping 0.77, against 3.44 Hz,
        // 0.65, so only its naming is asserted.
        if label == "seed 2 case 47" {
            let fc = searched(&d.ranked_effects[0], "cutoff_hz").unwrap_or(0.0);
            assert!((fc / cutoff_hz - 1.0).abs() < 0.05, "{label}: cutoff {fc}");
        }
        // The held-out error left within 1 % of the world's own (0.25 and 0.15 %).
        let left = d.ranked_effects[0].gap_after_percent;
        assert!(left < truth + 1.0, "{label}: {left} % against {truth} %");
    }
}
