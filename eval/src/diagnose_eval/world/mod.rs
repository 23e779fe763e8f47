//! The world of `diagnose-eval --forms wide`: a simulator of the rig kept apart from the
//! diagnosis's candidates, whose planted effects take forms drawn from families wider than the
//! candidates' ([`draw`]): the element's terms ([`element`]) and the channel effects applied to
//! the simulated records, not to the physics ([`channels`]).
//!
//! The true model of a case is the world itself: its element replayed on the base the rig
//! received (with the noise the measured base got), its mass-acceleration prediction through
//! the world's sensor dynamics; the held-out NMSE it leaves is what no effect causes.

pub mod channels;
pub mod draw;
pub mod element;

use forcemap_math::diagnose::effects::Transform;
use forcemap_math::diagnose::score::predict_record;
use forcemap_math::pipeline::nmse_percent;
use forcemap_math::record::{Channel, Excitation, Record};
use forcemap_math::signal::differentiate::central_difference_at_rate;
use forcemap_math::sim::excitation::derive_seed;
use forcemap_math::sim::noise::add_noise;
use forcemap_math::sim::rig::PAPER_RIG_MASS_KG;
use forcemap_math::sim::{RunSpec, SimError, TruthElement};
use serde::Serialize;

pub use channels::{Exciter, SensorDynamics};
pub use element::{Term, WorldElement};

use super::{RIG_C, RIG_K};

/// What the diagnosis should make of a planted world effect.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum WorldKind {
    /// A library effect in a wider form: the right answer is its library name.
    Library,
    /// A named effect (`series_compliance`, `drift`) that the library may lack.
    NewName,
    /// Out of the library, and staying so: no library name is right.
    OutOfLibrary,
}

/// One planted world effect: its name, its kind, and its drawn form (element terms, sensor
/// dynamics or an exciter).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct WorldEffect {
    pub name: &'static str,
    pub kind: WorldKind,
    pub terms: [Option<Term>; 2],
    pub sensor: Option<SensorDynamics>,
    pub exciter: Option<Exciter>,
}

impl WorldEffect {
    /// An effect made of element terms only.
    pub fn of_terms(name: &'static str, kind: WorldKind, terms: [Option<Term>; 2]) -> Self {
        WorldEffect {
            name,
            kind,
            terms,
            sensor: None,
            exciter: None,
        }
    }
}

/// A case's world: the element, the channel effects and the baseline the diagnosis is given
/// (Coulomb friction is planted on the linear rig against the linear baseline, everything
/// else on the paper's Coulomb rig against the Coulomb baseline, as in the exact forms).
#[derive(Debug, Clone, PartialEq)]
pub struct World {
    pub element: WorldElement,
    pub sensors: Vec<SensorDynamics>,
    pub exciter: Option<Exciter>,
    pub baseline: &'static str,
}

impl World {
    pub fn of(effects: &[WorldEffect]) -> World {
        let coulomb = effects.iter().any(|e| e.name == "coulomb_friction");
        let base = if coulomb {
            TruthElement::linear(RIG_K, RIG_C)
        } else {
            TruthElement::rig_coulomb()
        };
        World {
            element: WorldElement {
                base,
                terms: effects
                    .iter()
                    .flat_map(|e| e.terms.iter().flatten().copied())
                    .collect(),
            },
            sensors: effects.iter().filter_map(|e| e.sensor).collect(),
            exciter: effects.iter().find_map(|e| e.exciter),
            baseline: if coulomb { "linear" } else { "coulomb" },
        }
    }
}

impl World {
    /// The world of `effects` with only `effects[kept]` planted: the same rig and baseline as
    /// [`World::of`] gives the whole set (a member of a pair with Coulomb friction stays on the
    /// linear rig), so what the member causes alone is measured on the pair's own rig.
    pub fn with_only(effects: &[WorldEffect], kept: usize) -> World {
        let all = World::of(effects);
        let member = World::of(&effects[kept..=kept]);
        World {
            element: WorldElement {
                base: all.element.base,
                terms: member.element.terms,
            },
            sensors: member.sensors,
            exciter: member.exciter,
            baseline: all.baseline,
        }
    }
}

/// A simulated world case: the noisy records the diagnosis sees and the true model's held-out
/// NMSE on them.
#[derive(Debug, Clone)]
pub struct WorldRun {
    pub records: Vec<Record>,
    pub truth_nmse_percent: f64,
}

/// Simulates `world` over the paper's rig run (stepped sine and two band-random records) with
/// noise at `snr_db` from `seed`, and scores the true model on the band-random records.
pub fn simulate(world: &World, snr_db: f64, seed: u64) -> Result<WorldRun, SimError> {
    let spec = RunSpec::paper_rig(None, seed).with_element(world.element.base.clone());
    let physical = spec.simulate_with_element(&world.element)?.records;
    let mut clean = physical.clone();
    if let Some(ex) = world.exciter {
        ex.apply(&mut clean, &spec.program());
    }
    for s in &world.sensors {
        s.apply(&mut clean);
    }
    let mut records = clean.clone();
    // The same noise stream a `RunSpec` run uses.
    add_noise(&mut records, Some(snr_db), derive_seed(seed, 1));
    let mut sum = 0.0;
    let mut n = 0usize;
    // The run's integral of the squared relative velocity before each record [m^2/s], and
    // each record's squared relative velocity over time.
    let mut v2_before = Vec::with_capacity(physical.len());
    let mut v2_record: Vec<Vec<f64>> = Vec::with_capacity(physical.len());
    let mut v2_integral = 0.0;
    for p in &physical {
        let fs = p.sample_rate_hz;
        let v2: Vec<f64> = p
            .channel(Channel::RelativeDisplacementM)
            .map(|x| central_difference_at_rate(x, fs))
            .unwrap_or_default()
            .iter()
            .map(|v| v * v / fs)
            .collect();
        v2_before.push(v2_integral);
        v2_integral += v2.iter().sum::<f64>();
        v2_record.push(v2);
    }
    for j in 0..records.len() {
        if !matches!(records[j].excitation, Excitation::Random { .. }) {
            continue;
        }
        let now = [&records[j], &clean[j], &physical[j]];
        let (before, preroll, v2_at_start) = match j.checked_sub(1) {
            Some(i) => {
                let p = PREROLL_SAMPLES.min(records[i].len());
                let skipped = records[i].len() - p;
                let at = v2_before[i] + v2_record[i][..skipped].iter().sum::<f64>();
                (Some([&records[i], &clean[i], &physical[i]]), p, at)
            }
            None => (None, 0, v2_before[j]),
        };
        let at_start = World {
            element: WorldElement {
                base: world.element.base.clone(),
                terms: world
                    .element
                    .terms
                    .iter()
                    .map(|t| t.at_dissipation(v2_at_start))
                    .collect(),
            },
            ..world.clone()
        };
        sum += truth_nmse_percent(&at_start, now, before, preroll)?;
        n += 1;
    }
    Ok(WorldRun {
        records,
        truth_nmse_percent: sum / n.max(1) as f64,
    })
}

/// Samples of the preceding record the true model's replay starts from, so that the world's
/// internal states (hysteresis, series spring, elastomer branches) have settled when the scored
/// record begins (the record's own samples alone would start them from rest).
const PREROLL_SAMPLES: usize = 300;

/// The true model's held-out NMSE on one record (`now`: noisy, clean and physical): the world
/// element replayed on the base the rig received plus the noise of the measured base (the
/// relative displacement, which gives the initial state, likewise), from `preroll` samples
/// before the record (the tail of `before`), the predicted mass acceleration through the
/// world's sensor dynamics on that channel, scored over the record's samples.
fn truth_nmse_percent(
    world: &World,
    now: [&Record; 3],
    before: Option<[&Record; 3]>,
    preroll: usize,
) -> Result<f64, SimError> {
    let missing = |c: Channel| SimError::InvalidSpec(format!("world record lacks {}", c.name()));
    let received = |r: [&Record; 3], c: Channel, from: usize| -> Result<Vec<f64>, SimError> {
        let (Some(n), Some(m), Some(p)) = (r[0].channel(c), r[1].channel(c), r[2].channel(c))
        else {
            return Err(missing(c));
        };
        Ok(n[from..]
            .iter()
            .zip(&m[from..])
            .zip(&p[from..])
            .map(|((n, m), p)| p + (n - m))
            .collect())
    };
    let measured = |r: &Record, from: usize| -> Result<Vec<f64>, SimError> {
        r.channel(Channel::MassAccelerationMps2)
            .map(|a| a[from..].to_vec())
            .ok_or_else(|| missing(Channel::MassAccelerationMps2))
    };
    let mut channels = Vec::new();
    for c in [Channel::BaseDisplacementM, Channel::RelativeDisplacementM] {
        let mut v = match before {
            Some(b) => received(b, c, b[0].len() - preroll)?,
            None => Vec::new(),
        };
        v.extend(received(now, c, 0)?);
        channels.push((c, v));
    }
    let mut acc = match before {
        Some(b) => measured(b[0], b[0].len() - preroll)?,
        None => Vec::new(),
    };
    let scored = measured(now[0], 0)?;
    acc.extend(&scored);
    channels.push((Channel::MassAccelerationMps2, acc));
    let replay = Record {
        channels,
        ..now[0].clone()
    };
    let held = predict_record(
        &world.element,
        PAPER_RIG_MASS_KG,
        &replay,
        &Transform::default(),
    )?;
    let mut predicted = held.predicted_mps2;
    for s in &world.sensors {
        if s.applies_to(Channel::MassAccelerationMps2) {
            predicted = s.filter(&predicted, now[0].sample_rate_hz);
        }
    }
    Ok(nmse_percent(&scored, &predicted[preroll..]))
}
