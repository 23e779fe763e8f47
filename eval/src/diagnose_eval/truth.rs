//! The exact forms' truth: each planted effect in exactly the form its candidate assumes, as
//! the rig simulator's element and effects, and the simulation of a case from it.

use super::{CaseSpec, Planted};
use forcemap_math::diagnose::effects::Effect;
use forcemap_math::element::{Element, Friction};
use forcemap_math::recipe::SetupKind;
use forcemap_math::record::Record;
use forcemap_math::sim::{
    AsymmetricDamping, BoucWen, FreePlay, RigEffects, RunSpec, SimError, TruthElement,
};

/// The effects the rig evaluation plants, in the order its cases draw them: the library's
/// effects that can show on the base-excited rig (a preload only moves its equilibrium), but
/// not the names series compliance and drift, which only the wide forms' world
/// plants: the exact forms' draws stay those of the published figures.
pub(super) fn planted_effects() -> Vec<Effect> {
    Effect::ALL
        .into_iter()
        .filter(|e| e.applies_to(SetupKind::BaseExcited) && !NOT_PLANTED.contains(e))
        .collect()
}

/// The library effects the exact forms do not plant (see [`planted_effects`]).
const NOT_PLANTED: [Effect; 2] = [Effect::SeriesCompliance, Effect::Drift];

/// The paper's rig values: k [N/m] and c [N s/m] (the Coulomb level is that of `TruthElement::rig_coulomb`).
pub(super) const RIG_K: f64 = 6380.0;
pub(super) const RIG_C: f64 = 184.0;

/// Severity-scaled magnitude of an effect.
fn magnitude(effect: Effect, severity: u8) -> f64 {
    let i = (severity.clamp(1, 3) - 1) as usize;
    let table: [f64; 3] = match effect {
        Effect::CoulombFriction => [4.0, 8.0, 12.3],
        Effect::StribeckFriction => [4.0, 8.0, 14.0],
        Effect::QuadraticDamping => [800.0, 1600.0, 3200.0],
        Effect::CubicStiffness => [3e7, 6e7, 1.2e8],
        Effect::QuadraticStiffness => [2.5e5, 5e5, 1e6],
        Effect::AsymmetricDamping => [40.0, 80.0, 140.0],
        Effect::FreePlay => [2000.0, 4000.0, 8000.0],
        Effect::Hysteresis => [6000.0, 12000.0, 24000.0],
        Effect::ExciterDelay => [0.006, 0.012, 0.024],
        Effect::SensorLowpass => [12.0, 7.0, 4.0],
        Effect::MassError => [1.05, 1.1, 1.2],
        Effect::Preload => [20.0, 50.0, 100.0],
        // Not planted here (`NOT_PLANTED`).
        Effect::SeriesCompliance | Effect::Drift => [0.0; 3],
    };
    table[i]
}

/// Free-play gap [m], hysteresis yield [m] and Stribeck velocity [m/s] of the planted effects.
const FREE_PLAY_GAP_M: f64 = 0.004;
const HYSTERESIS_YIELD_M: f64 = 0.001;
const STRIBECK_VELOCITY_MPS: f64 = 0.015;

/// The truth: element, rig-level effects and the baseline model the diagnosis is given.
#[derive(Debug, Clone)]
pub struct Truth {
    pub element: TruthElement,
    pub effects: RigEffects,
    /// Series oil stiffness of the out-of-library case.
    pub oil_stiffness_n_per_m: Option<f64>,
    pub baseline: &'static str,
}

fn plant(truth: &mut Truth, effect: Effect, m: f64) {
    let e = &mut truth.element;
    match effect {
        Effect::CoulombFriction => e.friction = Some(Friction::coulomb(m)),
        Effect::StribeckFriction => {
            if let Some(f) = e.friction.as_mut() {
                f.breakaway_n = f.kinetic_n + m;
                f.stribeck_velocity_mps = STRIBECK_VELOCITY_MPS;
            }
        }
        Effect::QuadraticDamping => e.quadratic_damping_n_s2_per_m2 = m,
        Effect::CubicStiffness => e.cubic_stiffness_n_per_m3 = m,
        Effect::QuadraticStiffness => e.quadratic_stiffness_n_per_m2 = m,
        Effect::AsymmetricDamping => {
            e.asymmetric_damping = Some(AsymmetricDamping {
                rebound_n_s_per_m: m,
                compression_n_s_per_m: -m,
            });
        }
        Effect::FreePlay => {
            e.free_play = Some(FreePlay {
                gap_m: FREE_PLAY_GAP_M,
                stiffness_n_per_m: m,
            });
        }
        Effect::Hysteresis => {
            e.bouc_wen = Some(BoucWen {
                alpha_n_per_m: m,
                a: 1.0,
                beta: 0.5 / HYSTERESIS_YIELD_M,
                gamma: 0.5 / HYSTERESIS_YIELD_M,
                n: 1.0,
            });
        }
        Effect::ExciterDelay => truth.effects.exciter_delay_s = m,
        Effect::SensorLowpass => truth.effects.sensor_lowpass_hz = Some(m),
        Effect::MassError => truth.effects.mass_factor = m,
        Effect::Preload => e.preload_n = m,
        // Not planted here (`NOT_PLANTED`): the wide forms' world has them.
        Effect::SeriesCompliance | Effect::Drift => {}
    }
}

/// The truth of a case. Coulomb friction is planted on the linear rig against the linear
/// baseline (the paper's story); every other effect on the paper's Coulomb rig against the
/// Coulomb baseline (the "sim" already has the friction).
pub fn truth_of(planted: &Planted) -> Truth {
    let involves_coulomb = match planted {
        Planted::One { effect, .. } => *effect == Effect::CoulombFriction,
        Planted::Two { effects } => effects.contains(&Effect::CoulombFriction),
        _ => false,
    };
    let mut t = Truth {
        element: if involves_coulomb {
            TruthElement::linear(RIG_K, RIG_C)
        } else {
            TruthElement::rig_coulomb()
        },
        effects: RigEffects::default(),
        oil_stiffness_n_per_m: None,
        baseline: if involves_coulomb {
            "linear"
        } else {
            "coulomb"
        },
    };
    match planted {
        Planted::None => {}
        Planted::One { effect, severity } => plant(&mut t, *effect, magnitude(*effect, *severity)),
        Planted::Two { effects } => {
            for e in effects {
                plant(&mut t, *e, magnitude(*e, 2));
            }
        }
        Planted::CompressibleOil {
            oil_stiffness_n_per_m,
        } => t.oil_stiffness_n_per_m = Some(*oil_stiffness_n_per_m),
        // The wide forms' truth is their world (`world::World::of`), not a `TruthElement`.
        Planted::Wide { .. } | Planted::WidePair { .. } => {}
    }
    t
}

/// A damper whose oil is compressible: the viscous force f obeys f' = k_oil (x' - f / c)
/// (internal state f), plus the rest of a truth element without its own viscous term.
#[derive(Debug, Clone)]
pub struct CompressibleOilDamper {
    pub rest: TruthElement,
    pub damping_n_s_per_m: f64,
    pub oil_stiffness_n_per_m: f64,
}

impl Element for CompressibleOilDamper {
    fn smooth_force(&self, x: f64, v: f64, z: &[f64]) -> f64 {
        self.rest.smooth_force(x, v, &z[1..]) + z[0]
    }
    fn friction(&self) -> Option<Friction> {
        self.rest.friction()
    }
    fn internal_states(&self) -> usize {
        1 + self.rest.internal_states()
    }
    fn internal_rates(&self, x: f64, v: f64, z: &[f64], dz: &mut [f64]) {
        dz[0] = self.oil_stiffness_n_per_m * (v - z[0] / self.damping_n_s_per_m);
        self.rest.internal_rates(x, v, &z[1..], &mut dz[1..]);
    }
}

pub(super) fn truth_element(t: &Truth) -> Box<dyn Element> {
    match t.oil_stiffness_n_per_m {
        Some(k) => Box::new(CompressibleOilDamper {
            rest: TruthElement {
                damping_n_s_per_m: 0.0,
                ..t.element.clone()
            },
            damping_n_s_per_m: t.element.damping_n_s_per_m,
            oil_stiffness_n_per_m: k,
        }),
        None => Box::new(t.element.clone()),
    }
}

/// Simulates a case: the paper's stepped sine and its two band-random records, with noise.
pub fn simulate_case(case: &CaseSpec) -> Result<(Truth, Vec<Record>), SimError> {
    if !case.planted.world_effects().is_empty() {
        return Err(SimError::InvalidSpec(
            "the wide forms are simulated by their world (world::simulate)".into(),
        ));
    }
    let truth = truth_of(&case.planted);
    let run = RunSpec::paper_rig(Some(case.snr_db), case.seed)
        .with_element(truth.element.clone())
        .with_effects(truth.effects);
    let out = run.simulate_with_element(truth_element(&truth).as_ref())?;
    Ok((truth, out.records))
}
