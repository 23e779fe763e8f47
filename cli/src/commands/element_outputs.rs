//! What `forcemap identify` adds for an element test (a damper dyno, a mount or bushing
//! tester): the dynamic stiffness table K*(f, A) with loss angle, dissipated energy and the
//! peak force at peak velocity, in the summary, in `--json` and as plots in `--plot DIR`.

use std::path::Path;

use forcemap_io::atomic::write_atomically;
use forcemap_math::dynamic_stiffness::{
    PeakVelocityState, StiffnessPoint, peak_velocity_states, stiffness_point,
};
use forcemap_math::model::Model;
use forcemap_math::phasor::HarmonicAnalysis;
use forcemap_math::recipe::Setup;
use forcemap_math::record::{Excitation, Record};

use crate::plot::{Series, SeriesPanel, series_color, series_panels_svg};

/// One step's point with its amplitude as its record gives it (commanded, or measured on an
/// export without the program), in the driven channel's unit.
pub struct ElementStep {
    pub step_amplitude: f64,
    pub point: StiffnessPoint,
    /// The identified model's force at the same peak velocities (rebound, compression) [N].
    pub model_force_at_peak_velocity_n: (f64, f64),
}

/// The element-test figures of every sine step. `setup` has its identified extra parameters
/// set ([`Setup::with_extra_values`]).
pub fn element_steps(
    setup: &Setup,
    model: &Model,
    theta: &[f64],
    analyses: &[HarmonicAnalysis],
    records: &[Record],
) -> anyhow::Result<Vec<ElementStep>> {
    let mut out = Vec::new();
    for an in analyses {
        let Some(Excitation::Sine { amplitude, .. }) = records
            .iter()
            .find(|r| r.step == an.step)
            .map(|r| &r.excitation)
        else {
            continue;
        };
        let point = stiffness_point(setup, an)?;
        // The model at the measured states of the two velocity peaks.
        let peaks = peak_velocity_states(setup, an)?;
        let model_at = |p: &PeakVelocityState| model.force(theta, p.displacement_m, p.velocity_mps);
        out.push(ElementStep {
            step_amplitude: *amplitude,
            point,
            model_force_at_peak_velocity_n: (model_at(&peaks[0]), model_at(&peaks[1])),
        });
    }
    Ok(out)
}

/// The table as the summary prints it.
pub fn print_table(steps: &[ElementStep]) {
    println!(
        "dynamic stiffness K* = G_1 / X_1 (element force over displacement, fundamental) and loops:"
    );
    println!(
        "{:>5} {:>8} {:>10} {:>12} {:>12} {:>9} {:>10} {:>9} {:>10} {:>10}",
        "step",
        "f [Hz]",
        "X [m]",
        "K' [N/m]",
        "K'' [N/m]",
        "angle [°]",
        "W [J]",
        "v_pk[m/s]",
        "F_reb [N]",
        "F_comp [N]"
    );
    for s in steps {
        let p = &s.point;
        println!(
            "{:>5} {:>8.3} {:>10.3e} {:>12.5e} {:>12.5e} {:>9.3} {:>10.4e} {:>9.4} {:>10.3} {:>10.3}",
            p.step,
            p.frequency_hz,
            p.displacement_amplitude_m,
            p.storage_stiffness_n_per_m,
            p.loss_stiffness_n_per_m,
            p.loss_angle_deg,
            p.dissipated_energy_j,
            p.peak_velocity_mps,
            p.rebound_force_at_peak_velocity_n,
            p.compression_force_at_peak_velocity_n
        );
    }
}

/// Amplitudes within this relative distance are one level of the program (a CSV's steps carry
/// the amplitude measured on each step, which scatters with the noise and the control).
const SAME_LEVEL: f64 = 0.03;

/// The program's amplitude levels, in order: each step's amplitude joins the first level
/// within [`SAME_LEVEL`] of it.
fn amplitude_levels(steps: &[ElementStep]) -> Vec<f64> {
    let mut amplitudes: Vec<f64> = steps.iter().map(|s| s.step_amplitude).collect();
    amplitudes.sort_by(f64::total_cmp);
    let mut levels: Vec<f64> = Vec::new();
    for a in amplitudes {
        if levels.last().is_none_or(|l| !same_level(*l, a)) {
            levels.push(a);
        }
    }
    levels
}

fn same_level(level: f64, a: f64) -> bool {
    (a - level).abs() <= SAME_LEVEL * level.abs()
}

/// The level an amplitude joined: the last one not above it.
fn level_of(levels: &[f64], a: f64) -> Option<f64> {
    levels.iter().rev().find(|l| **l <= a).copied()
}

/// K*(f, A) (storage, loss, loss angle against frequency, one line per amplitude) and the
/// peak force against peak velocity, measured and by the identified model.
pub fn write_plots(dir: &Path, steps: &[ElementStep], model_name: &str) -> anyhow::Result<()> {
    let levels = amplitude_levels(steps);
    let by_level = |value: fn(&StiffnessPoint) -> f64| -> Vec<Series> {
        levels
            .iter()
            .enumerate()
            .map(|(i, a)| {
                let mut points: Vec<(f64, f64)> = steps
                    .iter()
                    .filter(|s| level_of(&levels, s.step_amplitude) == Some(*a))
                    .map(|s| (s.point.frequency_hz, value(&s.point)))
                    .collect();
                points.sort_by(|p, q| p.0.total_cmp(&q.0));
                Series {
                    label: format!("amplitude {a:.3e}"),
                    points,
                    color: series_color(i),
                    line: true,
                }
            })
            .collect()
    };
    let panel = |caption: &str, y_desc: &str, value: fn(&StiffnessPoint) -> f64| SeriesPanel {
        caption: caption.into(),
        x_desc: "frequency [Hz]".into(),
        y_desc: y_desc.into(),
        series: by_level(value),
    };
    let svg = series_panels_svg(
        "dynamic stiffness K*(f, A) of the element (fundamental), one line per amplitude level",
        &[
            panel("storage stiffness K'", "K' [N/m]", |p| {
                p.storage_stiffness_n_per_m
            }),
            panel("loss stiffness K''", "K'' [N/m]", |p| {
                p.loss_stiffness_n_per_m
            }),
            panel("loss angle", "atan(K''/K') [deg]", |p| p.loss_angle_deg),
        ],
    )?;
    let path = dir.join("dynamic_stiffness.svg");
    write_atomically(&path, &svg)?;
    eprintln!("wrote {}", path.display());

    let mut order: Vec<&ElementStep> = steps.iter().collect();
    order.sort_by(|a, b| {
        a.point
            .peak_velocity_mps
            .total_cmp(&b.point.peak_velocity_mps)
    });
    // Measured as marks, the model as lines through its values at the same states.
    let curve = |label: &str, i: usize, line: bool, f: &dyn Fn(&ElementStep) -> f64| Series {
        label: label.into(),
        points: order
            .iter()
            .map(|s| (s.point.peak_velocity_mps, f(s)))
            .collect(),
        color: series_color(i),
        line,
    };
    let svg = series_panels_svg(
        "force at peak velocity against peak velocity (every sine step; rebound > 0, compression < 0)",
        &[SeriesPanel {
            caption: format!("measured and model {model_name}"),
            x_desc: "peak velocity [m/s]".into(),
            y_desc: "element force [N]".into(),
            series: vec![
                curve("rebound, measured", 0, false, &|s| {
                    s.point.rebound_force_at_peak_velocity_n
                }),
                curve("compression, measured", 1, false, &|s| {
                    s.point.compression_force_at_peak_velocity_n
                }),
                curve("rebound, model", 2, true, &|s| {
                    s.model_force_at_peak_velocity_n.0
                }),
                curve("compression, model", 3, true, &|s| {
                    s.model_force_at_peak_velocity_n.1
                }),
            ],
        }],
    )?;
    let path = dir.join("peak_force_velocity.svg");
    write_atomically(&path, &svg)?;
    eprintln!("wrote {}", path.display());
    Ok(())
}
