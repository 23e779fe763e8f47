//! Records with no sine steps whose motion the model can simulate: a base-excited rig's (the
//! mass under each record's measured base displacement) and a force-driven element test's (the
//! mass under each record's measured force, where the user names the force as the drive). They
//! are diagnosed along the measured motion (`phasor_only`: the rig as the element between base
//! and mass), then the baseline and the named effect are refitted by output error, the fit
//! `identify` runs on such records, and the held-out records predicted by simulation. The
//! rig's channel effects (a sensor low-pass, an exciter delay), which the fit along the
//! measured motion cannot see, are candidates only here.
//!
//! Why both: the fit along the measured motion is quick and ranks every candidate, but its
//! velocity and acceleration are differentiated from the noisy, sampled displacement, which
//! biases a friction level low (errors in the variables) or a stiffness term where the
//! resonance has few samples per period; the simulation takes the motion from the model and
//! has no such bias, at seconds per model.

use forcemap_math::diagnose::effects::{Effect, Transform};
use forcemap_math::diagnose::element_heldout::TermFit;
use forcemap_math::diagnose::fitted_element::FittedElement;
use forcemap_math::diagnose::score::predict_record;
use forcemap_math::diagnose::sensor::{ALL_CHANNELS, SensorFilter};
use forcemap_math::diagnose::simulated_gap::{SimulatedGap, SimulatedModel};
use forcemap_math::diagnose::{PhasorFindings, Verdict};
use forcemap_math::identify::{
    FORM_MISFIT_VARIANCE, Identification, Method, RecordsOutputError, RigChannelEffect,
};
use forcemap_math::model::{IdentifiedModel, Model};
use forcemap_math::pipeline::{
    identify_element_sample_records, identify_random_records, refine_hysteresis_on_records,
    validate_forced_element, validate_forced_hysteresis, validate_rig_on_random_records,
};
use forcemap_math::recipe::Setup;
use forcemap_math::record::Record;
use forcemap_math::sim::ElementDrive;

use anyhow::Context as _;

/// The note of a candidate refitted because the baseline's simulation misses the records
/// beyond their noise though no effect was named along the measured motion.
const BEST_RANKED_NOTE: &str = "no effect was named along the measured motion, but the baseline's simulation misses the records beyond their noise: the best-ranked candidate, refitted";

/// What the records' simulation drives.
pub(super) enum Simulation {
    /// A base-excited rig of this mass, under the measured base displacement.
    Rig { mass_kg: f64 },
    /// A force-driven element test, under the measured force (the moving mass known, or None:
    /// fitted).
    Forced { moving_mass_kg: Option<f64> },
}

/// The records the refits simulate, kept beside what the diagnosis fits along the motion.
pub(super) struct SimulatedRecords {
    pub records: Vec<Record>,
    pub validation: Vec<Record>,
    pub simulation: Simulation,
}

impl SimulatedRecords {
    /// What is simulated and compared, for the printed line.
    fn what(&self) -> (&'static str, &'static str, &'static str) {
        match self.simulation {
            Simulation::Rig { .. } => (
                "the mass simulated under each record's measured base displacement",
                "mass-acceleration",
                "m/s^2",
            ),
            Simulation::Forced { .. } => (
                "the mass simulated under each record's measured force",
                "displacement",
                "m",
            ),
        }
    }

    /// The verdict from the refits' simulations of the held-out records (None without held-out
    /// records): the baseline's held-out NMSE the gap, the refitted candidate's what it leaves.
    pub fn verdict(&self, refits: &[Refit]) -> Option<SimulatedGap> {
        let base = refits.first()?;
        if self.validation.is_empty() {
            return None;
        }
        Some(SimulatedGap::judge(
            base.simulated(),
            closest_candidate(&refits[1..]).map(Refit::simulated),
            closest_of(refits.iter().filter(|r| r.second_effect.is_some())).map(Refit::simulated),
        ))
    }
}

/// Of the refitted candidates, the one whose simulation misses the fitted records least (in
/// noise std; the first where a misfit could not be compared with noise): chosen on the
/// fitted records, so that the held-out records judge it without having chosen it.
fn closest_candidate(candidates: &[Refit]) -> Option<&Refit> {
    closest_of(
        candidates
            .iter()
            .filter(|r| r.effect.is_some() && r.second_effect.is_none()),
    )
}

/// Of `refits`, the one whose simulation misses the fitted records least (the first where a
/// misfit could not be compared with noise).
fn closest_of<'a>(refits: impl Iterator<Item = &'a Refit> + Clone) -> Option<&'a Refit> {
    if refits.clone().any(|r| r.misfit_noise_std.is_none()) {
        return refits.clone().next();
    }
    refits.min_by(|a, b| {
        a.misfit_noise_std
            .partial_cmp(&b.misfit_noise_std)
            .unwrap_or(std::cmp::Ordering::Equal)
    })
}

/// One model refitted by output error on the records.
#[derive(Debug, Clone, serde::Serialize)]
pub(super) struct Refit {
    pub model: String,
    /// The effect added to the baseline (None: the baseline itself).
    pub effect: Option<Effect>,
    /// A second effect added together with `effect` (a pair).
    pub second_effect: Option<Effect>,
    /// (name, value, std).
    pub parameters: Vec<(String, f64, f64)>,
    /// Held-out NMSE of the simulated channel (the rig's mass acceleration, eq. 27; a
    /// force-driven element's displacement) per validation record [%].
    pub heldout_nmse_percent: Vec<f64>,
    /// Held-out RMS error of that channel in its own unit (m/s^2; m).
    pub heldout_rms_error: Vec<f64>,
    /// The fit's misfit in noise std (None: the noise could not be measured).
    pub misfit_noise_std: Option<f64>,
    /// The fit's own lines: its misfit against the noise, and whether the form may be wrong.
    pub notes: Vec<String>,
}

impl Refit {
    /// `model` refitted as `id`, with each held-out record's (NMSE [%], RMS error); the effect
    /// it adds is the caller's to set.
    fn new(model: String, id: &Identification, held: &[(f64, f64)]) -> Refit {
        Refit {
            model,
            effect: None,
            second_effect: None,
            parameters: id
                .parameters
                .iter()
                .map(|p| (p.name.clone(), p.value, p.std))
                .collect(),
            heldout_nmse_percent: held.iter().map(|h| h.0).collect(),
            heldout_rms_error: held.iter().map(|h| h.1).collect(),
            misfit_noise_std: id.misfit_noise_std,
            notes: id.warnings.clone(),
        }
    }

    fn simulated(&self) -> SimulatedModel<'_> {
        SimulatedModel {
            effect: self.effect,
            second_effect: self.second_effect,
            heldout_nmse_percent: &self.heldout_nmse_percent,
            misfit_noise_std: self.misfit_noise_std,
        }
    }
}

/// The baseline and, when the diagnosis names an effect made of extra element terms or a
/// hysteresis state, the baseline with it, each refitted by output error on `sim`'s records
/// and simulated on its held-out records (a hysteresis from the fit along the motion, its
/// exponent held: `identify --model NAME+hysteresis`'s refinement). An effect with another
/// internal state (a series spring, a drift) is not refitted. On the rig, where the baseline's
/// simulation misses the records beyond their noise and no element candidate's fits them
/// within it, the channel effects ([`CHANNEL_EFFECTS`]) are refitted too, one parameter beside
/// the baseline's element.
pub(super) fn refit(
    sim: &SimulatedRecords,
    baseline: &Model,
    f: &PhasorFindings,
) -> anyhow::Result<Vec<Refit>> {
    let (base, base_id) = refitting_with_spinner(&baseline.name, || refit_one(sim, baseline))?;
    // Along the measured motion the differentiated noise can hide what the simulation shows:
    // where the baseline's simulation misses the records beyond their noise and no effect was
    // named, the best-ranked candidate is refitted too.
    let form_wrong = base
        .misfit_noise_std
        .is_some_and(|m| m * m > FORM_MISFIT_VARIANCE);
    let candidate = match f.findings.top_effect {
        Some(e) => f.ranked_effects.iter().find(|r| r.effect == e),
        None if form_wrong => f.ranked_effects.first(),
        None => None,
    };
    let named_fit = candidate.and_then(|r| Some((r.effect, r.fit.as_ref()?)));
    let named = named_fit.and_then(|(effect, fit)| {
        let extra = fit.terms.len() > baseline.terms.len() && fit.hysteresis.is_none();
        extra.then(|| {
            let name = format!("{} + {}", baseline.name, effect.name());
            (effect, Model::new(name, fit.terms.clone()))
        })
    });
    let hysteresis = named_fit
        .filter(|(_, fit)| fit.hysteresis.is_some() && fit.terms.len() == baseline.terms.len());
    // A candidate whose refit or held-out simulation fails (a trial model that diverges) is
    // left out with a warning; the baseline's failure ends the diagnosis.
    let mut out = vec![base];
    let best_ranked = f.findings.top_effect.is_none();
    let add =
        |out: &mut Vec<Refit>,
         effect: Effect,
         name: &str,
         run: &dyn Fn() -> anyhow::Result<Refit>| match refitting_with_spinner(name, run) {
            Ok(mut r) => {
                r.effect = Some(effect);
                if best_ranked && !is_channel_effect(effect) {
                    r.notes.insert(0, BEST_RANKED_NOTE.into());
                }
                out.push(r);
            }
            Err(e) => eprintln!("warning: {name} not refitted by output error: {e:#}"),
        };
    // The element candidate's own fit, the start of a pair with a channel effect.
    let element_fit = std::cell::RefCell::new(None);
    if let Some((effect, model)) = &named {
        add(&mut out, *effect, &model.name, &|| {
            let (r, id) = refit_one(sim, model)?;
            *element_fit.borrow_mut() = Some(id);
            Ok(r)
        });
    }
    if let Some((effect, fit)) = hysteresis {
        let name = format!("{} + {}", baseline.name, effect.name());
        add(&mut out, effect, &name, &|| {
            refit_hysteresis(sim, baseline, fit, &name)
        });
    }
    // The rig's channel effects have no candidate along the measured motion (its channels are
    // taken as they are there): where the baseline's simulation misses the records beyond
    // their noise and no element candidate fits them within it (one that does leaves nothing
    // for another effect to remove), each is refitted by simulation.
    let element_within_noise = out[1..].iter().any(|r| {
        r.misfit_noise_std
            .is_some_and(|m| m * m <= FORM_MISFIT_VARIANCE)
    });
    if let Simulation::Rig { mass_kg } = sim.simulation
        && form_wrong
        && !element_within_noise
    {
        for (effect, channel) in CHANNEL_EFFECTS {
            let name = format!("{} + {}", baseline.name, effect.name());
            add(&mut out, effect, &name, &|| {
                refit_channel_effect(sim, mass_kg, baseline, &base_id, channel, &name)
            });
        }
        // Where the closest single candidate still misses the records beyond their noise and it
        // is the element candidate or a channel effect, the element candidate is refitted
        // together with each channel effect (the closer single of each pair named first).
        let element_fit = element_fit.into_inner();
        let first = pair_first(&out[1..]);
        if let (Some((element, model)), Some(element_id), Some(first)) =
            (&named, &element_fit, first)
            && (first == *element || is_channel_effect(first))
        {
            for (effect, channel) in CHANNEL_EFFECTS {
                let name = format!("{} + {}", model.name, effect.name());
                let run = || refit_channel_effect(sim, mass_kg, model, element_id, channel, &name);
                match refitting_with_spinner(&name, run) {
                    Ok(mut r) => {
                        let pair = if first == effect {
                            [effect, *element]
                        } else {
                            [*element, effect]
                        };
                        r.effect = Some(pair[0]);
                        r.second_effect = Some(pair[1]);
                        out.push(r);
                    }
                    Err(e) => eprintln!("warning: {name} not refitted by output error: {e:#}"),
                }
            }
        }
    }
    Ok(out)
}

/// `run` (the refit of `name`) under a spinner that says so.
fn refitting_with_spinner<T>(name: &str, run: impl FnOnce() -> T) -> T {
    let pb = super::super::progress_spinner();
    pb.set_message(format!("refitting {name} by output error"));
    let out = run();
    pb.finish_and_clear();
    out
}

/// The closest single candidate ([`closest_candidate`]) where its simulation still misses the
/// fitted records beyond their noise: the first of the pairs to refit.
fn pair_first(candidates: &[Refit]) -> Option<Effect> {
    let closest = closest_candidate(candidates)?;
    let beyond_noise = closest
        .misfit_noise_std
        .is_some_and(|m| m * m > FORM_MISFIT_VARIANCE);
    beyond_noise.then_some(closest.effect).flatten()
}

fn is_channel_effect(effect: Effect) -> bool {
    CHANNEL_EFFECTS.iter().any(|(e, _)| *e == effect)
}

/// The rig's channel effects refitted by simulation on records with no steps.
const CHANNEL_EFFECTS: [(Effect, RigChannelEffect); 2] = [
    (Effect::SensorLowpass, RigChannelEffect::LowpassEveryChannel),
    (Effect::ExciterDelay, RigChannelEffect::ExciterDelay),
];

/// `baseline` with `channel` between the rig and its channels refitted by output error on the
/// rig's records from `baseline_id` (its own refit), the held-out records predicted through
/// the fitted transformation.
fn refit_channel_effect(
    sim: &SimulatedRecords,
    mass_kg: f64,
    baseline: &Model,
    baseline_id: &Identification,
    channel: RigChannelEffect,
    name: &str,
) -> anyhow::Result<Refit> {
    let refitting = || format!("refitting {name} by output error");
    let refs: Vec<&Record> = sim.records.iter().collect();
    let id = RecordsOutputError::rig(baseline, mass_kg, &refs)
        .and_then(|p| p.with_channel_effect(channel))
        .and_then(|p| p.fit_channel_effect(baseline_id))
        .with_context(refitting)?;
    let mut theta = id.theta();
    let value = theta.pop().context("the refit has no channel parameter")?;
    let (transform, note) = match channel {
        RigChannelEffect::LowpassEveryChannel => {
            let cutoff_hz = 1.0 / (std::f64::consts::TAU * value);
            (
                Transform {
                    sensor: (value > 0.0).then_some(SensorFilter {
                        mask: ALL_CHANNELS,
                        order: 1,
                        cutoff_hz,
                        damping_ratio: 1.0,
                        delay_s: 0.0,
                    }),
                    ..Transform::default()
                },
                format!(
                    "a first-order low-pass on every measured channel, cutoff {cutoff_hz:.3} Hz"
                ),
            )
        }
        RigChannelEffect::ExciterDelay => (
            Transform {
                delay_s: value,
                ..Transform::default()
            },
            format!(
                "the element sees the measured base motion {:.2} ms later",
                value * 1e3
            ),
        ),
    };
    let fitted = IdentifiedModel::new(baseline.clone(), theta);
    let held = sim
        .validation
        .iter()
        .map(|record| {
            predict_record(&fitted, mass_kg, record, &transform)
                .map(|h| (h.nmse_percent, h.rms_error_mps2()))
        })
        .collect::<Result<Vec<_>, _>>()
        .with_context(|| format!("simulating {name} on the held-out records"))?;
    let mut r = Refit::new(name.to_string(), &id, &held);
    r.notes.insert(0, note);
    Ok(r)
}

/// `baseline` with the hysteresis of `start` (the fit along the measured motion) refitted by
/// output error on `sim`'s records, the held-out records simulated with it (a rig's from rest).
fn refit_hysteresis(
    sim: &SimulatedRecords,
    baseline: &Model,
    start: &TermFit,
    name: &str,
) -> anyhow::Result<Refit> {
    let refitting = || format!("refitting {name} by output error");
    let simulating = || format!("simulating {name} on the held-out records");
    let setup = match sim.simulation {
        Simulation::Rig { mass_kg } => Setup::BaseExcited { mass_kg },
        Simulation::Forced { moving_mass_kg } => Setup::Element {
            moving_mass_kg,
            drive: Some(ElementDrive::Force),
        },
    };
    let refs: Vec<&Record> = sim.records.iter().collect();
    let r = refine_hysteresis_on_records(baseline, &setup, &refs, start).with_context(refitting)?;
    let (law, _) = r
        .fit
        .hysteresis
        .context("the refit has no hysteresis state")?;
    let held = sim
        .validation
        .iter()
        .map(|record| -> anyhow::Result<(f64, f64)> {
            match sim.simulation {
                Simulation::Rig { mass_kg } => {
                    let element = FittedElement::of_term_fit(&r.fit);
                    let h = predict_record(&element, mass_kg, record, &Transform::default())?;
                    Ok((h.nmse_percent, h.rms_error_mps2()))
                }
                Simulation::Forced { .. } => {
                    let v = validate_forced_hysteresis(baseline, &r.fit, record)?;
                    Ok((v.nmse_percent, v.rms_error_m))
                }
            }
        })
        .collect::<anyhow::Result<Vec<_>>>()
        .with_context(simulating)?;
    Ok(Refit::new(
        format!("{name} (loop exponent n {} held)", law.n),
        &r.identification,
        &held,
    ))
}

/// `model` refitted by output error on `sim`'s records and simulated on its held-out ones;
/// with its identification.
fn refit_one(sim: &SimulatedRecords, model: &Model) -> anyhow::Result<(Refit, Identification)> {
    let refitting = || format!("refitting {} by output error", model.name);
    let simulating = || format!("simulating {} on the held-out records", model.name);
    let (id, held) = match sim.simulation {
        Simulation::Rig { mass_kg } => {
            let setup = Setup::BaseExcited { mass_kg };
            let id = identify_random_records(model, &setup, Method::OutputError, &sim.records)
                .with_context(refitting)?;
            let fitted = IdentifiedModel::new(model.clone(), id.theta());
            let held = validate_rig_on_random_records(&fitted, mass_kg, &sim.validation)
                .with_context(simulating)?
                .iter()
                .map(|v| (v.nmse_percent, v.rms_error_mps2))
                .collect::<Vec<_>>();
            (id, held)
        }
        Simulation::Forced { moving_mass_kg } => {
            let refs: Vec<&Record> = sim.records.iter().collect();
            let id = identify_element_sample_records(
                model,
                moving_mass_kg,
                Some(ElementDrive::Force),
                Method::OutputError,
                &refs,
            )
            .with_context(refitting)?;
            let theta = id.theta();
            let held = sim
                .validation
                .iter()
                .map(|r| {
                    validate_forced_element(model, moving_mass_kg, None, &theta, r)
                        .map(|v| (v.nmse_percent, v.rms_error_m))
                })
                .collect::<Result<Vec<_>, _>>()
                .with_context(simulating)?;
            (id, held)
        }
    };
    Ok((Refit::new(model.name.clone(), &id, &held), id))
}

pub(super) fn print(sim: &SimulatedRecords, refits: &[Refit]) {
    if refits.is_empty() {
        return;
    }
    let (how, ..) = sim.what();
    println!("refitted by output error on the records ({how}):");
    for r in refits {
        println!("  {}", refit_line(sim, r));
        for n in &r.notes {
            println!("    {n}");
        }
    }
}

/// The report's lines: each refit, then the verdict by simulation.
pub(super) fn report_lines(
    sim: &SimulatedRecords,
    refits: &[Refit],
    by_simulation: Option<&SimulatedGap>,
) -> Vec<String> {
    let mut lines: Vec<String> = refits.iter().map(|r| refit_line(sim, r)).collect();
    lines.push(match by_simulation {
        Some(g) => format!("verdict by simulation: {}", g.headline()),
        None => "verdict by simulation: none: no held-out records".into(),
    });
    lines
}

/// One refit: its parameters and its held-out records' NMSE and RMS error.
fn refit_line(sim: &SimulatedRecords, r: &Refit) -> String {
    let (_, channel, unit) = sim.what();
    let params: Vec<String> = r
        .parameters
        .iter()
        .map(|(n, v, s)| format!("{n} {v:.5e} +/- {s:.1e}"))
        .collect();
    let held: Vec<String> = r
        .heldout_nmse_percent
        .iter()
        .zip(&r.heldout_rms_error)
        .map(|(nmse, rms)| format!("{nmse:.2} % (RMS {rms:.3e} {unit})"))
        .collect();
    format!(
        "{}: {}; held-out {channel} NMSE {}",
        r.model,
        params.join(", "),
        if held.is_empty() {
            "- (no held-out records)".to_string()
        } else {
            held.join(", ")
        }
    )
}

/// The verdict by simulation, and where it differs from the one along the measured motion,
/// what each weighs.
pub(super) fn print_verdict(
    sim: &SimulatedRecords,
    by_simulation: Option<&SimulatedGap>,
    along_motion: &PhasorFindings,
) {
    let (_, channel, _) = sim.what();
    let Some(g) = by_simulation else {
        println!("verdict by simulation: none: no held-out records to simulate (--validate FILE)");
        return;
    };
    println!(
        "verdict by simulation (held-out {channel} NMSE, the models refitted by output error): {}",
        g.headline()
    );
    let along = &along_motion.findings;
    let names = |v: Verdict, e: Option<Effect>| {
        matches!(v, Verdict::Explained | Verdict::ExplainedInPart).then_some(e)
    };
    if (g.verdict, names(g.verdict, g.effect))
        != (along.verdict, names(along.verdict, along.top_effect))
    {
        println!(
            "  the two verdicts differ: the simulation's weighs what the refitted models predict on the held-out records, its motion the model's own (no noise differentiated into it); the one along the motion weighs the element force sample by sample along the measured, differentiated motion"
        );
    }
}
