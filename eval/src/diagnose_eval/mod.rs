//! Checked on withheld effects: seeded cases from the rig simulator, each with an effect
//! planted that the diagnosis is not told, and the scores (top-1 hit rate, false alarms, wrong
//! names on out-of-library cases, predicted against true shrink, confusion matrix).

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicUsize, Ordering};

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

mod summary;
mod truth;
pub mod world;

pub use summary::{
    CONFUSABLE_PAIRS, ConfusablePair, DIVERGED_BASELINE_PERCENT, EvalSummary,
    QUALIFYING_GAP_PERCENT, Rate, summarise,
};
pub use truth::{CompressibleOilDamper, Truth, simulate_case, truth_of};
use truth::{RIG_C, RIG_K, planted_effects, truth_element};

use forcemap_math::diagnose::effects::{Effect, Transform};
use forcemap_math::diagnose::score::predict_record;
use forcemap_math::diagnose::sensor::SensorFilter;
use forcemap_math::diagnose::{DiagnoseError, DiagnoseOptions, Verdict, diagnose};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::recipe::Setup;
use forcemap_math::record::{Excitation, Record};
use forcemap_math::sim::rig::PAPER_RIG_MASS_KG;

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
    /// The generator's seed (`diagnose-eval --seed`) and the case's place in its sequence.
    pub generator_seed: u64,
    pub index: usize,
    /// The case's own seed (its draws and noise), drawn by the generator.
    pub seed: u64,
    pub planted: Planted,
    pub snr_db: f64,
}

/// What follows the effect's name in [`CaseResult::named`] when the verdict is "explained in
/// part" by it: never a hit, but which name the verdict gave shows in the confusion matrix.
pub const IN_PART: &str = " in part";

/// What one case gave.
#[derive(Debug, Clone, Serialize)]
pub struct CaseResult {
    pub case: CaseSpec,
    pub label: String,
    pub verdict: Verdict,
    /// The named effect, the effect and [`IN_PART`] for "explained in part", or
    /// "adequate"/"unexplained".
    pub named: String,
    pub gap_before_percent: f64,
    pub gap_after_percent: f64,
    /// Held-out NMSE of the true model (the truth simulated on the measured base) [%].
    pub truth_nmse_percent: f64,
    /// The held-out NMSE the planted effect causes alone: `gap_before - truth_nmse` [%].
    pub effect_gap_percent: f64,
    /// A wide pair's members each planted alone on the pair's rig (same seed and SNR): the
    /// held-out NMSE each causes alone, as `effect_gap_percent` [%]. What a pair member too
    /// small to detect alone would be asked for is scored apart ([`summarise`]).
    pub member_gap_percent: Option<[f64; 2]>,
    pub noise_floor_percent: f64,
    /// Cross-validated force error of the baseline on the sine steps [%].
    pub baseline_cv_percent: Option<f64>,
    /// The runner-up effect.
    pub second: Option<String>,
    /// The second effect when the verdict names two fitted together (`named` is the first).
    pub second_named: Option<String>,
    /// Every candidate, best first.
    pub ranked: Vec<RankedCandidate>,
    /// The baseline's output-error misfit on the sine steps [noise std], when friction
    /// candidates were refitted by output error.
    pub baseline_output_error_misfit: Option<f64>,
    /// The diagnosis's notes (an amplified base, a refused member, ...).
    pub notes: Vec<String>,
    /// The best pair fitted together (the top candidate and the second effect searched on what
    /// it leaves): (first, second, held-out NMSE [%], penalised score [%]).
    pub best_pair: Option<(String, String, f64, f64)>,
}

/// One ranked candidate of a case.
#[derive(Debug, Clone, Serialize)]
pub struct RankedCandidate {
    pub effect: String,
    /// Held-out NMSE with it [%].
    pub gap_after_percent: f64,
    /// Held-out NMSE with the BIC penalty [%].
    pub score_percent: f64,
    /// Cross-validated force error on the sine steps [%].
    pub step_cv_percent: Option<f64>,
    /// Output-error misfit of its refit on the sine steps [noise std], when refitted.
    pub output_error_misfit: Option<f64>,
}

/// Runs the diagnosis on one case.
pub fn run_case(case: &CaseSpec) -> Result<CaseResult, DiagnoseError> {
    let sim_error = |source| DiagnoseError::Simulation { step: 0, source };
    let effects = case.planted.world_effects();
    if !effects.is_empty() {
        let w = world::World::of(&effects);
        let run = world::simulate(&w, case.snr_db, case.seed).map_err(sim_error)?;
        let mut result = diagnose_case(case, &run.records, w.baseline, run.truth_nmse_percent)?;
        if let Planted::WidePair { effects } = &case.planted {
            let mut gaps = [0.0; 2];
            for (kept, gap) in gaps.iter_mut().enumerate() {
                let alone = world::World::with_only(effects, kept);
                let run = world::simulate(&alone, case.snr_db, case.seed).map_err(sim_error)?;
                *gap = baseline_gap_percent(&run.records, alone.baseline)? - run.truth_nmse_percent;
            }
            result.member_gap_percent = Some(gaps);
        }
        return Ok(result);
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

/// The baseline's held-out NMSE on `records` [%]: the diagnosis with no candidate to try.
fn baseline_gap_percent(records: &[Record], baseline: &str) -> Result<f64, DiagnoseError> {
    let baseline = Model::by_name(baseline, &ModelOptions::default())
        .expect("eval baselines are known models");
    let setup = Setup::BaseExcited {
        mass_kg: PAPER_RIG_MASS_KG,
    };
    let options = DiagnoseOptions {
        effects: Vec::new(),
        pairs: false,
        ..DiagnoseOptions::default()
    };
    let d = diagnose(&setup, &baseline, records, &[], &options)?.diagnosis;
    Ok(d.findings.gap_before_percent)
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
        (Verdict::ExplainedInPart, Some(e)) => format!("{}{IN_PART}", e.name()),
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
        member_gap_percent: None,
        noise_floor_percent: f.floor_percent,
        baseline_cv_percent: d.baseline_phasor_cv_percent,
        second: d.ranked_effects.get(1).map(|r| r.effect.name().to_string()),
        second_named: f.second_effect.map(|e| e.name().to_string()),
        ranked: d
            .ranked_effects
            .iter()
            .map(|r| RankedCandidate {
                effect: r.effect.name().to_string(),
                gap_after_percent: r.gap_after_percent,
                score_percent: r.score_percent,
                step_cv_percent: r.phasor_cv_percent,
                output_error_misfit: r.output_error_misfit,
            })
            .collect(),
        baseline_output_error_misfit: d.baseline_output_error_misfit,
        notes: d.notes.clone(),
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
                generator_seed: seed,
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
                generator_seed: seed,
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
                    let c = &cases[i];
                    let r = run_case(c)
                        .map_err(|e| format!("case {} of seed {}: {e}", c.index, c.generator_seed));
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
