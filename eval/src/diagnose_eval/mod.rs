//! Checked on withheld effects: seeded cases from the rig simulator, each with an effect
//! planted that the diagnosis is not told, and the scores (top-1 hit rate, false alarms, wrong
//! names on out-of-library cases, predicted against true shrink, confusion matrix).

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicUsize, Ordering};

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

mod summary;
pub mod world;

pub use summary::{
    CONFUSABLE_PAIRS, ConfusablePair, DIVERGED_BASELINE_PERCENT, EvalSummary,
    QUALIFYING_GAP_PERCENT, Rate, summarise,
};

use forcemap_math::diagnose::effects::{Effect, Transform};
use forcemap_math::diagnose::score::predict_record;
use forcemap_math::diagnose::sensor::SensorFilter;
use forcemap_math::diagnose::{DiagnoseError, DiagnoseOptions, Verdict, diagnose};
use forcemap_math::element::{Element, Friction};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::recipe::{Setup, SetupKind};
use forcemap_math::record::{Excitation, Record};
use forcemap_math::sim::rig::PAPER_RIG_MASS_KG;
use forcemap_math::sim::{
    AsymmetricDamping, BoucWen, FreePlay, RigEffects, RunSpec, SimError, TruthElement,
};

/// What is planted in a case.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Planted {
    None,
    /// One library effect at severity 1 (mild) to 3 (strong).
    One {
        effect: Effect,
        severity: u8,
    },
    /// Two library effects at severity 2.
    Two {
        effects: [Effect; 2],
    },
    /// The damper's oil is compressible, so its force lags (a spring `oil_stiffness_n_per_m`
    /// in series with the damper): a frequency-dependent stiffness and damping. Out of the
    /// library until series_compliance joined it; now a series_compliance case (label, group).
    CompressibleOil {
        oil_stiffness_n_per_m: f64,
    },
    /// `--forms wide`: one effect in a form drawn wider than its candidate's (or a new-name or
    /// out-of-library effect), simulated by [`world`].
    Wide {
        effect: world::WorldEffect,
    },
    /// `--forms wide`: two library effects in wide forms.
    WidePair {
        effects: [world::WorldEffect; 2],
    },
}

impl Planted {
    pub fn label(&self) -> String {
        match self {
            Planted::None => "none".into(),
            Planted::One { effect, .. } => effect.name().into(),
            Planted::Two { effects } => format!("{}+{}", effects[0].name(), effects[1].name()),
            Planted::CompressibleOil { .. } => Effect::SeriesCompliance.name().into(),
            Planted::Wide { effect } => match effect.kind {
                world::WorldKind::OutOfLibrary => format!("out_of_library:{}", effect.name),
                _ => effect.name.into(),
            },
            Planted::WidePair { effects } => format!("{}+{}", effects[0].name, effects[1].name),
        }
    }

    /// One effect with a name the diagnosis should give (a library effect, or a new name).
    pub fn is_single(&self) -> bool {
        match self {
            Planted::One { .. } | Planted::CompressibleOil { .. } => true,
            Planted::Wide { effect } => effect.kind != world::WorldKind::OutOfLibrary,
            _ => false,
        }
    }

    /// Out of the library: any library name is wrong.
    pub fn is_out_of_library(&self) -> bool {
        match self {
            Planted::Wide { effect } => effect.kind == world::WorldKind::OutOfLibrary,
            _ => false,
        }
    }

    /// The names of a planted pair.
    pub fn pair_names(&self) -> Option<[&'static str; 2]> {
        match self {
            Planted::Two { effects } => Some(effects.map(Effect::name)),
            Planted::WidePair { effects } => Some(effects.map(|e| e.name)),
            _ => None,
        }
    }

    /// The wide forms' world effects (empty for the exact forms).
    pub fn world_effects(&self) -> Vec<world::WorldEffect> {
        match self {
            Planted::Wide { effect } => vec![*effect],
            Planted::WidePair { effects } => effects.to_vec(),
            _ => Vec::new(),
        }
    }
}

/// One generated case.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CaseSpec {
    pub index: usize,
    pub seed: u64,
    pub planted: Planted,
    pub snr_db: f64,
}

/// The effects the rig evaluation plants, in the order its cases draw them: the library's
/// effects that can show on the base-excited rig (a preload only moves its equilibrium), but
/// not the new names of issue 13 (series compliance, drift), which only the wide forms' world
/// plants: the exact forms' draws stay those of the published figures.
fn planted_effects() -> Vec<Effect> {
    Effect::ALL
        .into_iter()
        .filter(|e| e.applies_to(SetupKind::BaseExcited) && !NOT_PLANTED.contains(e))
        .collect()
}

/// The library effects the exact forms do not plant (see [`planted_effects`]).
const NOT_PLANTED: [Effect; 2] = [Effect::SeriesCompliance, Effect::Drift];

/// The paper's rig values: k [N/m] and c [N s/m] (the Coulomb level is that of `TruthElement::rig_coulomb`).
const RIG_K: f64 = 6380.0;
const RIG_C: f64 = 184.0;

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

fn truth_element(t: &Truth) -> Box<dyn Element> {
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

/// What one case gave.
#[derive(Debug, Clone, Serialize)]
pub struct CaseResult {
    pub case: CaseSpec,
    pub label: String,
    pub verdict: Verdict,
    /// The named effect, or "adequate"/"unexplained".
    pub named: String,
    pub gap_before_percent: f64,
    pub gap_after_percent: f64,
    /// Held-out NMSE of the true model (the truth simulated on the measured base) [%].
    pub truth_nmse_percent: f64,
    /// The held-out NMSE the planted effect causes alone: `gap_before - truth_nmse` [%].
    pub effect_gap_percent: f64,
    pub noise_floor_percent: f64,
    /// Cross-validated force error of the baseline on the sine steps [%].
    pub baseline_cv_percent: Option<f64>,
    /// The runner-up effect.
    pub second: Option<String>,
    /// The second effect when the verdict names two fitted together (`named` is the first).
    pub second_named: Option<String>,
    /// Every candidate, best first: (effect, held-out NMSE with it [%], penalised score [%],
    /// cross-validated force error on the sine steps [%]).
    pub ranked: Vec<(String, f64, f64, Option<f64>)>,
    /// The best pair fitted together (the top candidate and the second effect searched on what
    /// it leaves): (first, second, held-out NMSE [%], penalised score [%]).
    pub best_pair: Option<(String, String, f64, f64)>,
}

/// Runs the diagnosis on one case.
pub fn run_case(case: &CaseSpec) -> Result<CaseResult, DiagnoseError> {
    let sim_error = |source| DiagnoseError::Simulation { step: 0, source };
    let effects = case.planted.world_effects();
    if !effects.is_empty() {
        let w = world::World::of(&effects);
        let run = world::simulate(&w, case.snr_db, case.seed).map_err(sim_error)?;
        return diagnose_case(case, &run.records, w.baseline, run.truth_nmse_percent);
    }
    let (truth, records) = simulate_case(case).map_err(sim_error)?;
    let element = truth_element(&truth);
    let transform = Transform {
        delay_s: truth.effects.exciter_delay_s,
        sensor: truth
            .effects
            .sensor_lowpass_hz
            .map(SensorFilter::first_order_on_all),
        mass_factor: truth.effects.mass_factor,
    };
    let mut truth_nmse = 0.0;
    let random: Vec<&Record> = records
        .iter()
        .filter(|r| matches!(r.excitation, Excitation::Random { .. }))
        .collect();
    for r in &random {
        truth_nmse += predict_record(element.as_ref(), PAPER_RIG_MASS_KG, r, &transform)
            .map_err(|source| DiagnoseError::Simulation {
                step: r.step,
                source,
            })?
            .nmse_percent;
    }
    truth_nmse /= random.len().max(1) as f64;
    diagnose_case(case, &records, truth.baseline, truth_nmse)
}

/// The diagnosis of a case's records against `baseline`, with the true model's held-out NMSE.
fn diagnose_case(
    case: &CaseSpec,
    records: &[Record],
    baseline: &str,
    truth_nmse: f64,
) -> Result<CaseResult, DiagnoseError> {
    let baseline = Model::by_name(baseline, &ModelOptions::default())
        .expect("eval baselines are known models");
    let setup = Setup::BaseExcited {
        mass_kg: PAPER_RIG_MASS_KG,
    };
    // Pairs fitted together, as `forcemap diagnose` does: a pair can be the verdict.
    let options = DiagnoseOptions::default();
    let d = diagnose(&setup, &baseline, records, &[], &options)?.diagnosis;
    let f = &d.findings;
    let named = match (f.verdict, f.top_effect) {
        (Verdict::Explained, Some(e)) => e.name().to_string(),
        (v, _) => v.name().to_string(),
    };
    Ok(CaseResult {
        case: *case,
        label: case.planted.label(),
        verdict: f.verdict,
        named,
        gap_before_percent: f.gap_before_percent,
        gap_after_percent: f.gap_after_percent,
        truth_nmse_percent: truth_nmse,
        effect_gap_percent: f.gap_before_percent - truth_nmse,
        noise_floor_percent: f.floor_percent,
        baseline_cv_percent: d.baseline_phasor_cv_percent,
        second: d.ranked_effects.get(1).map(|r| r.effect.name().to_string()),
        second_named: f.second_effect.map(|e| e.name().to_string()),
        ranked: d
            .ranked_effects
            .iter()
            .map(|r| {
                (
                    r.effect.name().to_string(),
                    r.gap_after_percent,
                    r.score_percent,
                    r.phasor_cv_percent,
                )
            })
            .collect(),
        best_pair: d.best_pair.as_ref().map(|p| {
            (
                p.effects[0].name().to_string(),
                p.effects[1].name().to_string(),
                p.gap_after_percent,
                p.score_percent,
            )
        }),
    })
}

/// Seeded cases: 15 % without an effect, 60 % with one (effect and severity drawn), 10 % with
/// two, 15 % out of the library; half at `snr_db`, half 10 dB cleaner.
pub fn generate_cases(n: usize, seed: u64, snr_db: f64) -> Vec<CaseSpec> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let planted_effects = planted_effects();
    (0..n)
        .map(|index| {
            let u: f64 = rng.random();
            let planted = if u < 0.15 {
                Planted::None
            } else if u < 0.75 {
                let e = planted_effects[rng.random_range(0..planted_effects.len())];
                Planted::One {
                    effect: e,
                    severity: rng.random_range(1..=3u8),
                }
            } else if u < 0.85 {
                let a = rng.random_range(0..planted_effects.len());
                let mut b = rng.random_range(0..planted_effects.len() - 1);
                if b >= a {
                    b += 1;
                }
                Planted::Two {
                    effects: [planted_effects[a], planted_effects[b]],
                }
            } else {
                Planted::CompressibleOil {
                    oil_stiffness_n_per_m: [3000.0, 6000.0, 12000.0][rng.random_range(0..3usize)],
                }
            };
            CaseSpec {
                index,
                seed: rng.random(),
                planted,
                snr_db: if rng.random::<bool>() {
                    snr_db
                } else {
                    snr_db + 10.0
                },
            }
        })
        .collect()
}

/// The SNRs [dB] of the wide forms' single effects (every other group is at the middle one).
pub const WIDE_SNRS_DB: [f64; 3] = [20.0, 30.0, 40.0];

/// Seeded cases of the wide forms: 10 % without an effect, 50 % one library effect in a wide
/// form (family uniform, SNR uniform over [`WIDE_SNRS_DB`]), 12 % two library effects,
/// 14 % out of the library, 14 % the new names; all but the single effects at 30 dB.
pub fn generate_wide_cases(n: usize, seed: u64) -> Vec<CaseSpec> {
    use world::draw::{LIBRARY_FAMILIES, NEW_NAMES, OUT_OF_LIBRARY, draw};
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|index| {
            let u: f64 = rng.random();
            let mut snr_db = WIDE_SNRS_DB[1];
            fn pick(names: &[&str], rng: &mut ChaCha8Rng) -> world::WorldEffect {
                let name = names[rng.random_range(0..names.len())];
                draw(name, rng).expect("the draw knows its own names")
            }
            let planted = if u < 0.10 {
                Planted::None
            } else if u < 0.60 {
                snr_db = WIDE_SNRS_DB[rng.random_range(0..WIDE_SNRS_DB.len())];
                Planted::Wide {
                    effect: pick(&LIBRARY_FAMILIES, &mut rng),
                }
            } else if u < 0.72 {
                let a = rng.random_range(0..LIBRARY_FAMILIES.len());
                let mut b = rng.random_range(0..LIBRARY_FAMILIES.len() - 1);
                if b >= a {
                    b += 1;
                }
                Planted::WidePair {
                    effects: [
                        pick(&LIBRARY_FAMILIES[a..=a], &mut rng),
                        pick(&LIBRARY_FAMILIES[b..=b], &mut rng),
                    ],
                }
            } else if u < 0.86 {
                Planted::Wide {
                    effect: pick(&OUT_OF_LIBRARY, &mut rng),
                }
            } else {
                Planted::Wide {
                    effect: pick(&NEW_NAMES, &mut rng),
                }
            };
            CaseSpec {
                index,
                seed: rng.random(),
                planted,
                snr_db,
            }
        })
        .collect()
}

/// The group a wide-forms case is reported in: "single effects at 30 dB", "pairs", "out of
/// library", "new names", "no effect".
pub fn wide_group(case: &CaseSpec) -> String {
    match &case.planted {
        Planted::None => "no effect".into(),
        Planted::Two { .. } | Planted::WidePair { .. } => "pairs".into(),
        p if p.is_out_of_library() => "out of library".into(),
        Planted::Wide { effect } if effect.kind == world::WorldKind::NewName => "new names".into(),
        _ => format!("single effects at {} dB", case.snr_db),
    }
}

/// Runs `cases` on `threads` threads; `progress` is called after each case (from any thread).
pub fn run_cases(
    cases: &[CaseSpec],
    threads: usize,
    progress: &(dyn Fn(&CaseResult) + Sync),
) -> Vec<Result<CaseResult, String>> {
    let next = AtomicUsize::new(0);
    let mut out: Vec<Option<Result<CaseResult, String>>> = vec![None; cases.len()];
    let slots: Vec<std::sync::Mutex<Option<Result<CaseResult, String>>>> = (0..cases.len())
        .map(|_| std::sync::Mutex::new(None))
        .collect();
    std::thread::scope(|s| {
        for _ in 0..threads.max(1) {
            s.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if i >= cases.len() {
                        break;
                    }
                    let r = run_case(&cases[i]).map_err(|e| format!("case {i}: {e}"));
                    if let Ok(ok) = &r {
                        progress(ok);
                    }
                    *slots[i].lock().expect("no panics while holding the lock") = Some(r);
                }
            });
        }
    });
    for (o, s) in out.iter_mut().zip(slots) {
        *o = s.into_inner().expect("no panics while holding the lock");
    }
    out.into_iter()
        .map(|o| o.expect("every case ran"))
        .collect()
}

#[cfg(test)]
mod planted_tests {
    use super::*;

    /// The cases a seed draws stay those of the published figures: the planted list is the
    /// library's eleven rig effects in their order (a new effect that cannot show on the rig
    /// does not shift the draws).
    #[test]
    fn the_planted_effects_are_the_rig_effects_in_order() {
        assert_eq!(
            planted_effects(),
            [
                Effect::CoulombFriction,
                Effect::StribeckFriction,
                Effect::QuadraticDamping,
                Effect::CubicStiffness,
                Effect::QuadraticStiffness,
                Effect::AsymmetricDamping,
                Effect::FreePlay,
                Effect::Hysteresis,
                Effect::ExciterDelay,
                Effect::SensorLowpass,
                Effect::MassError,
            ]
        );
    }
}
