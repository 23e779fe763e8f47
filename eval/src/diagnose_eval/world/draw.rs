//! Seeded draws of world effects: each family's form drawn from variants wider than the
//! candidate's form, the magnitude log-uniform over a range that spans from effects hidden
//! under the noise to strong ones (about 1-30 % caused held-out NMSE).

use rand::{Rng, RngExt};

use super::channels::{Exciter, SensorDynamics};
use super::element::Term;
use super::{WorldEffect, WorldKind};

/// The library families the wide forms plant (the rig's effects but the mass error, whose
/// form has nothing to widen and which causes no gap on the rig).
pub const LIBRARY_FAMILIES: [&str; 10] = [
    "coulomb_friction",
    "stribeck_friction",
    "quadratic_damping",
    "cubic_stiffness",
    "quadratic_stiffness",
    "asymmetric_damping",
    "free_play",
    "hysteresis",
    "exciter_delay",
    "sensor_lowpass",
];

/// The effects the wide forms add to the library by name.
pub const NEW_NAMES: [&str; 2] = ["series_compliance", "drift"];

/// The out-of-library effects.
pub const OUT_OF_LIBRARY: [&str; 3] = ["cogging", "elastomer", "exciter_resonance"];

/// Reference displacement [m] and velocity [m/s] at which a power law's force is drawn: the
/// sine steps' 6 mm amplitude and about their peak relative speed.
const X_REF_M: f64 = 0.006;
const V_REF_MPS: f64 = 0.1;

/// Dissipated energy of the paper's run in the base damper, about [J]: scales the drift's fade.
pub const RUN_DISSIPATION_J: f64 = 150.0;

fn log_uniform<R: Rng>(rng: &mut R, lo: f64, hi: f64) -> f64 {
    lo * (hi / lo).powf(rng.random::<f64>())
}

fn uniform<R: Rng>(rng: &mut R, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.random::<f64>()
}

/// A form of the named family (a name of [`LIBRARY_FAMILIES`], [`NEW_NAMES`] or
/// [`OUT_OF_LIBRARY`]); None for an unknown name.
pub fn draw<R: Rng>(name: &str, rng: &mut R) -> Option<WorldEffect> {
    use WorldKind::{Library, NewName, OutOfLibrary};
    let one =
        |name: &'static str, kind, t: Term| WorldEffect::of_terms(name, kind, [Some(t), None]);
    let odd = |coef, exponent, on_velocity| Term::OddPower {
        coef,
        exponent,
        on_velocity,
    };
    Some(match name {
        "coulomb_friction" => one(
            "coulomb_friction",
            Library,
            Term::Coulomb {
                level_n: log_uniform(rng, 2.0, 15.0),
                asymmetry: uniform(rng, -0.3, 0.3),
            },
        ),
        "stribeck_friction" => one(
            "stribeck_friction",
            Library,
            Term::Stribeck {
                excess_n: log_uniform(rng, 3.0, 18.0),
                velocity_mps: log_uniform(rng, 0.005, 0.04),
                exponent: uniform(rng, 0.5, 2.5),
            },
        ),
        "quadratic_damping" => {
            let p = uniform(rng, 1.7, 2.3);
            let f = log_uniform(rng, 5.0, 40.0);
            one(
                "quadratic_damping",
                Library,
                odd(f / V_REF_MPS.powf(p), p, true),
            )
        }
        "cubic_stiffness" => {
            // x^3 with a smaller x^5 share (0-30 % of the force at 6 mm).
            let f = log_uniform(rng, 5.0, 35.0);
            let share = uniform(rng, 0.0, 0.3);
            WorldEffect::of_terms(
                "cubic_stiffness",
                Library,
                [
                    Some(odd((1.0 - share) * f / X_REF_M.powi(3), 3.0, false)),
                    Some(odd(share * f / X_REF_M.powi(5), 5.0, false)),
                ],
            )
        }
        "quadratic_stiffness" => {
            let p = uniform(rng, 1.7, 2.3);
            let f = log_uniform(rng, 5.0, 45.0);
            one(
                "quadratic_stiffness",
                Library,
                odd(f / X_REF_M.powf(p), p, false),
            )
        }
        "asymmetric_damping" => {
            let rebound = log_uniform(rng, 25.0, 180.0);
            one(
                "asymmetric_damping",
                Library,
                Term::AsymmetricDamping {
                    rebound_n_s_per_m: rebound,
                    compression_n_s_per_m: -rebound * uniform(rng, 0.5, 1.5),
                },
            )
        }
        "free_play" => {
            let gap = uniform(rng, 0.002, 0.006);
            let pos = uniform(rng, 0.2, 0.8);
            one(
                "free_play",
                Library,
                Term::FreePlay {
                    gap_neg_m: gap * (1.0 - pos),
                    gap_pos_m: gap * pos,
                    stiffness_n_per_m: log_uniform(rng, 1500.0, 10000.0),
                },
            )
        }
        "hysteresis" => {
            // z saturates at zy = (1 / (beta + gamma))^(1/n); beta : gamma = r : 1 - r
            // (the candidate's form: n = 1, r = 0.5).
            let zy = log_uniform(rng, 0.0005, 0.002);
            let n = uniform(rng, 0.7, 2.5);
            let r = uniform(rng, 0.5, 0.9);
            let scale = zy.powf(n);
            one(
                "hysteresis",
                Library,
                Term::BoucWen {
                    alpha_n_per_m: log_uniform(rng, 4.0, 30.0) / zy,
                    beta: r / scale,
                    gamma: (1.0 - r) / scale,
                    n,
                },
            )
        }
        "exciter_delay" => {
            // A pure delay, a first-order lag, or both.
            let which = rng.random_range(0..3u8);
            WorldEffect {
                exciter: Some(Exciter {
                    delay_s: if which != 1 {
                        uniform(rng, 0.005, 0.03)
                    } else {
                        0.0
                    },
                    lag_s: if which != 0 {
                        uniform(rng, 0.003, 0.025)
                    } else {
                        0.0
                    },
                    resonance_hz: None,
                    resonance_damping: 0.0,
                }),
                ..WorldEffect::of_terms("exciter_delay", Library, [None, None])
            }
        }
        "sensor_lowpass" => {
            // One channel (40 %), the two accelerometers (30 %) or all five (30 %).
            let u: f64 = rng.random();
            let mask = if u < 0.4 {
                1u8 << rng.random_range(0..5u8)
            } else if u < 0.7 {
                0b10100
            } else {
                0b11111
            };
            let order = rng.random_range(1..=2u8);
            let cutoff_hz = log_uniform(rng, 3.0, 15.0);
            let damping_ratio = uniform(rng, 0.5, 1.0);
            let delay_s = if rng.random::<bool>() {
                uniform(rng, 0.0, 0.005)
            } else {
                0.0
            };
            WorldEffect {
                sensor: Some(SensorDynamics {
                    mask,
                    order,
                    cutoff_hz,
                    damping_ratio,
                    delay_s,
                }),
                ..WorldEffect::of_terms("sensor_lowpass", Library, [None, None])
            }
        }
        "series_compliance" => one(
            "series_compliance",
            NewName,
            Term::SeriesCompliance {
                damping_n_s_per_m: super::RIG_C,
                stiffness_n_per_m: log_uniform(rng, 1000.0, 12000.0),
            },
        ),
        "drift" => one(
            "drift",
            NewName,
            Term::Drift {
                damping_n_s_per_m: super::RIG_C,
                fade_per_j: uniform(rng, 0.05, 0.4) / RUN_DISSIPATION_J,
                energy_at_start_j: 0.0,
            },
        ),
        "cogging" => one(
            "cogging",
            OutOfLibrary,
            Term::Cogging {
                amplitude_n: log_uniform(rng, 2.0, 15.0),
                pitch_m: uniform(rng, 0.002, 0.008),
                phase_rad: uniform(rng, 0.0, std::f64::consts::TAU),
            },
        ),
        "elastomer" => one(
            "elastomer",
            OutOfLibrary,
            Term::Elastomer {
                stiffness_n_per_m: log_uniform(rng, 500.0, 4000.0),
                order: uniform(rng, 0.2, 0.6),
            },
        ),
        "exciter_resonance" => WorldEffect {
            exciter: Some(Exciter {
                delay_s: 0.0,
                lag_s: 0.0,
                resonance_hz: Some(log_uniform(rng, 6.0, 20.0)),
                resonance_damping: uniform(rng, 0.05, 0.3),
            }),
            ..WorldEffect::of_terms("exciter_resonance", OutOfLibrary, [None, None])
        },
        _ => return None,
    })
}
