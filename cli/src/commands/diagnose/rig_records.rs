//! A rig's records with no sine steps: diagnosed as the element between base and mass (the force
//! that holds the mass along the measured relative motion, `phasor_only`), then the baseline and
//! the named effect refitted by output error on the rig itself, the mass simulated under each
//! record's measured base displacement (the fit `identify` runs on such records), and the
//! held-out records predicted by simulation (eq. 27).
//!
//! Why both: the fit along the measured motion is quick and ranks every candidate, but its
//! velocity is the differentiated noisy displacement, which biases a friction level low (errors
//! in the variables); the simulation takes the motion from the model and has no such bias, at
//! a few seconds per model.

use forcemap_math::diagnose::PhasorFindings;
use forcemap_math::identify::Method;
use forcemap_math::model::{IdentifiedModel, Model};
use forcemap_math::pipeline::{identify_random_records, validate_rig_on_random_records};
use forcemap_math::recipe::Setup;
use forcemap_math::record::Record;

use anyhow::Context as _;

/// The rig's own records, kept beside their element view.
pub(super) struct RigRecords {
    pub records: Vec<Record>,
    pub validation: Vec<Record>,
    pub mass_kg: f64,
}

/// One model refitted by output error on the rig's records.
#[derive(Debug, Clone, serde::Serialize)]
pub(super) struct Refit {
    pub model: String,
    /// (name, value, std).
    pub parameters: Vec<(String, f64, f64)>,
    /// Held-out NMSE of the mass acceleration per validation record [%] (eq. 27).
    pub heldout_nmse_percent: Vec<f64>,
}

/// The baseline and, when the diagnosis names an effect made of extra element terms, the
/// baseline with them, each refitted by output error on `rig`'s records and simulated on its
/// held-out records. An effect with an internal state or a channel transformation (hysteresis,
/// a lag) is not a model `identify` fits: only the baseline is refitted then.
pub(super) fn refit(
    rig: &RigRecords,
    baseline: &Model,
    f: &PhasorFindings,
) -> anyhow::Result<Vec<Refit>> {
    let named = f
        .findings
        .top_effect
        .and_then(|e| f.ranked_effects.iter().find(|r| r.effect == e))
        .and_then(|r| {
            let fit = r.fit.as_ref()?;
            let extra = fit.terms.len() > baseline.terms.len() && fit.hysteresis.is_none();
            extra.then(|| {
                Model::new(
                    format!("{} + {}", baseline.name, r.effect.name()),
                    fit.terms.clone(),
                )
            })
        });
    std::iter::once(baseline.clone())
        .chain(named)
        .map(|model| {
            let pb = super::super::progress_spinner();
            pb.set_message(format!(
                "refitting {} by output error on the rig's records",
                model.name
            ));
            let setup = Setup::BaseExcited {
                mass_kg: rig.mass_kg,
            };
            let id = identify_random_records(&model, &setup, Method::OutputError, &rig.records)
                .with_context(|| format!("refitting {} by output error", model.name))?;
            let fitted = IdentifiedModel::new(model.clone(), id.theta());
            let held = validate_rig_on_random_records(&fitted, rig.mass_kg, &rig.validation)
                .with_context(|| format!("simulating {} on the held-out records", model.name))?;
            pb.finish_and_clear();
            Ok(Refit {
                model: model.name.clone(),
                parameters: id
                    .parameters
                    .iter()
                    .map(|p| (p.name.clone(), p.value, p.std))
                    .collect(),
                heldout_nmse_percent: held.iter().map(|v| v.nmse_percent).collect(),
            })
        })
        .collect()
}

pub(super) fn print(refits: &[Refit]) {
    if refits.is_empty() {
        return;
    }
    println!(
        "refitted by output error on the rig's records (the mass simulated under each record's measured base displacement):"
    );
    for r in refits {
        let params: Vec<String> = r
            .parameters
            .iter()
            .map(|(n, v, s)| format!("{n} {v:.5e} +/- {s:.1e}"))
            .collect();
        let held: Vec<String> = r
            .heldout_nmse_percent
            .iter()
            .map(|v| format!("{v:.2} %"))
            .collect();
        println!(
            "  {}: {}; held-out mass-acceleration NMSE {}",
            r.model,
            params.join(", "),
            if held.is_empty() {
                "- (no held-out records)".to_string()
            } else {
                held.join(", ")
            }
        );
    }
}
