//! The plots of `forcemap identify --plot DIR`: the force-state map of the fit, the rig's
//! validation time traces, each force-driven held-out record's simulated displacement, and for
//! a model with a hysteresis state each record's loop, measured and predicted.

use anyhow::Context as _;
use forcemap_math::identify::{Identification, rebuilt_cycle};
use forcemap_math::model::Model;
use forcemap_math::pipeline::Validation;
use forcemap_math::recipe::Setup;

use super::identify_held_out::HeldOut;
use crate::plot::{self, ForceStateStep};

/// Force-state map of the fit (the element force of `setup`, whose identified extra
/// parameters are set) and, for the rig, the validation time traces.
pub(super) fn write_plots(
    dir: &std::path::Path,
    setup: &Setup,
    model: &Model,
    id: &Identification,
    analyses: &[forcemap_math::phasor::HarmonicAnalysis],
    records: &[forcemap_math::record::Record],
    validations: &[Validation],
) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("creating the plot directory {}", dir.display()))?;
    let theta = id.theta();
    let mut steps = Vec::new();
    for an in analyses {
        let cyc = rebuilt_cycle(setup, an, 256)?;
        let model_force_n = cyc
            .displacement_m
            .iter()
            .zip(&cyc.velocity_mps)
            .map(|(x, v)| model.force(&theta, *x, *v))
            .collect();
        steps.push(ForceStateStep {
            label: format!("step {} ({:.2} Hz)", an.step, an.frequency_hz),
            displacement_m: cyc.displacement_m,
            velocity_mps: cyc.velocity_mps,
            measured_force_n: cyc.force_n,
            model_force_n,
        });
    }
    let path = dir.join("force_state.svg");
    let title = format!(
        "force-state map: measured element force (points) and model {} by {} (lines)",
        id.model, id.method
    );
    plot::force_state_map(&path, &title, &steps)?;
    eprintln!("wrote {}", path.display());
    for v in validations {
        let Some(rec) = records.iter().find(|r| r.step == v.step) else {
            continue;
        };
        let t: Vec<f64> = (0..v.measured_mass_acceleration_mps2.len())
            .map(|i| rec.time_s(i))
            .collect();
        let path = dir.join(format!("validation_step{}.svg", v.step));
        let title = format!(
            "record {}: mass acceleration, measured and predicted by the identified model (NMSE {:.2} %)",
            v.step, v.nmse_percent
        );
        plot::time_trace(
            &path,
            &title,
            &t,
            &v.measured_mass_acceleration_mps2,
            &v.predicted_mass_acceleration_mps2,
            "mass acceleration [m/s^2]",
        )?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

/// Each force-driven held-out record's displacement, measured and simulated under its measured
/// force: `held_out_N.svg` in the order of the held-out lines.
pub(super) fn write_held_out_plots(
    dir: &std::path::Path,
    held_out: &[HeldOut],
) -> anyhow::Result<()> {
    for (i, h) in held_out.iter().enumerate() {
        let Some(s) = &h.simulated else {
            continue;
        };
        let t: Vec<f64> = (0..s.measured_m.len())
            .map(|k| k as f64 / s.sample_rate_hz)
            .collect();
        let path = dir.join(format!("held_out_{i}.svg"));
        let title = format!(
            "{} record {}: displacement, measured and simulated under the measured force (RMS error {:.3e} m, NMSE {:.2} %)",
            h.file, h.step, s.rms_error_m, s.nmse_percent
        );
        plot::time_trace(
            &path,
            &title,
            &t,
            &s.measured_m,
            &s.simulated_m,
            "displacement [m]",
        )?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

/// One record's force-displacement loop for [`write_loop_plots`]: its file name in the plot
/// directory, what the title says of it, and the record.
pub(super) struct LoopRecord<'a> {
    pub file_name: String,
    pub caption: String,
    pub record: &'a forcemap_math::record::Record,
}

/// Each record's element force against its displacement over its scored samples, measured and
/// predicted by `fit` along the measured motion (a hysteresis state integrated from rest), with
/// the NMSE in the title: the loop a damper engineer compares.
pub(super) fn write_loop_plots(
    dir: &std::path::Path,
    model_name: &str,
    fit: &forcemap_math::diagnose::element_heldout::TermFit,
    records: &[LoopRecord],
) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("creating the plot directory {}", dir.display()))?;
    for r in records {
        let state = forcemap_math::measured_state::MeasuredState::of(r.record)
            .with_context(|| format!("{}: the measured state", r.caption))?;
        let scored = state.scored.clone();
        let measured = &state.force_n[scored.clone()];
        let predicted = state.predicted_force(fit);
        let nmse = forcemap_math::pipeline::nmse_percent(measured, &predicted);
        let svg = plot::lines_svg(
            &format!(
                "{}: force against displacement, measured and predicted by {model_name} (NMSE {nmse:.2} %)",
                r.caption
            ),
            &state.displacement_m[scored],
            "displacement [m]",
            "force [N]",
            &[
                plot::Line {
                    label: "measured",
                    values: measured,
                    color: plotters::style::BLACK,
                },
                plot::Line {
                    label: "predicted",
                    values: &predicted,
                    color: plot::AFTER_COLOR,
                },
            ],
        )?;
        let path = dir.join(&r.file_name);
        forcemap_io::atomic::write_atomically(&path, &svg)?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}
