//! The sensor-dynamics family of the gap diagnosis on the wide forms' world: sensor dynamics on
//! one channel are named sensor_lowpass with the channel, the order and the delay found; a
//! filter on a channel the diagnosis does not read, or no filter, is given none.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how they report failure"
)]

mod common;

use common::{searched, sensor_effect};
use forcemap_eval::diagnose_eval::world::{SensorDynamics, WorldEffect};
use forcemap_math::diagnose::{Diagnosis, Effect, Verdict};
use forcemap_math::sim::rig::RIG_CHANNELS;

/// RIG_CHANNELS bit of the channel named `name` (its `short_name`).
fn mask(name: &str) -> u8 {
    let i = RIG_CHANNELS
        .iter()
        .position(|c| forcemap_math::diagnose::sensor::short_name(*c) == name)
        .unwrap();
    1 << i
}

/// The diagnosis of the world with `sensor` (none: the paper's rig alone) at `snr_db`, against
/// the Coulomb baseline.
fn diagnosed(sensor: Option<SensorDynamics>, snr_db: f64, seed: u64) -> Diagnosis {
    let effects: Vec<WorldEffect> = sensor.map(sensor_effect).into_iter().collect();
    common::diagnose_world(&format!("{sensor:?}"), &effects, snr_db, seed).0
}

#[test]
fn a_second_order_lowpass_on_the_mass_accelerometer_is_named_with_its_channel_and_order() {
    let d = diagnosed(
        Some(SensorDynamics {
            mask: mask("mass_acceleration"),
            order: 2,
            cutoff_hz: 6.0,
            damping_ratio: 0.7,
            delay_s: 0.0,
        }),
        30.0,
        41,
    );
    assert_eq!(d.findings.verdict, Verdict::Explained, "{d:#?}");
    assert_eq!(d.findings.top_effect, Some(Effect::SensorLowpass));
    let member = d.findings.top_member.clone().unwrap();
    assert!(
        member.starts_with("channel mass_acceleration, 2nd order"),
        "{member}"
    );
    assert!(d.findings.headline().ends_with(&format!("({member})")));
    // Cutoff and damping within 10 % and 0.1 of the truth.
    let fc = searched(&d.ranked_effects[0], "cutoff_hz").unwrap_or(0.0);
    assert!((fc / 6.0 - 1.0).abs() < 0.1, "cutoff {fc}");
    let zeta = searched(&d.ranked_effects[0], "damping_ratio").unwrap_or(0.0);
    assert!((zeta - 0.7).abs() < 0.1, "damping {zeta}");
}

#[test]
fn a_first_order_lowpass_with_a_delay_on_the_force_channel_is_named_with_its_delay() {
    // The rig's force is read from the mass accelerometer (and the mass displacement): 8 Hz
    // first order and 3 ms on the accelerometer.
    let d = diagnosed(
        Some(SensorDynamics {
            mask: mask("mass_acceleration"),
            order: 1,
            cutoff_hz: 8.0,
            damping_ratio: 1.0,
            delay_s: 0.003,
        }),
        30.0,
        42,
    );
    assert_eq!(d.findings.top_effect, Some(Effect::SensorLowpass), "{d:#?}");
    let member = d.findings.top_member.clone().unwrap();
    assert!(
        member.starts_with("channel mass_acceleration, 1st order"),
        "{member}"
    );
    let delay = searched(&d.ranked_effects[0], "sensor_delay_s").unwrap_or(0.0);
    assert!((delay - 0.003).abs() < 0.001, "delay {delay} s");
}

#[test]
fn a_lowpass_on_the_base_displacement_is_named_with_its_channel() {
    let d = diagnosed(
        Some(SensorDynamics {
            mask: mask("base_displacement"),
            order: 1,
            cutoff_hz: 10.0,
            damping_ratio: 1.0,
            delay_s: 0.0,
        }),
        30.0,
        43,
    );
    assert_eq!(d.findings.top_effect, Some(Effect::SensorLowpass), "{d:#?}");
    let member = d.findings.top_member.clone().unwrap();
    assert!(member.starts_with("channel base_displacement"), "{member}");
}

#[test]
fn no_sensor_effect_is_given_none() {
    // The paper's rig with nothing planted, and a filter on the base accelerometer, which the
    // diagnosis does not read: adequate, and no single-channel member is offered.
    for sensor in [
        None,
        Some(SensorDynamics {
            mask: mask("base_acceleration"),
            order: 2,
            cutoff_hz: 4.0,
            damping_ratio: 0.5,
            delay_s: 0.004,
        }),
    ] {
        let d = diagnosed(sensor, 30.0, 44);
        assert_eq!(d.findings.verdict, Verdict::Adequate, "{d:#?}");
        assert!(
            d.ranked_effects
                .iter()
                .filter(|r| r.effect == Effect::SensorLowpass)
                .filter_map(|r| r.member.as_deref())
                .all(|m| m.starts_with("all channels")),
            "{d:#?}"
        );
    }
}
