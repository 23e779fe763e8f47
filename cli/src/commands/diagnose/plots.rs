//! The SVG plots of the diagnosis report: held-out records before and after, the state plane
//! and the harmonics of the residual.

use forcemap_math::diagnose::{self, DiagnosisDetail, Located};
use plotters::prelude::*;

use crate::plot::{AFTER_COLOR, BASELINE_COLOR, Line, draw_err, lines_svg, span};

/// Measured against predicted mass acceleration of one held-out record, before and after.
pub(super) fn svg_heldout(
    h_before: &diagnose::score::HeldOut,
    h_after: Option<&diagnose::score::HeldOut>,
    fs: f64,
    title: &str,
) -> anyhow::Result<String> {
    let t: Vec<f64> = (0..h_before.measured_mps2.len())
        .map(|i| i as f64 / fs)
        .collect();
    let mut lines = vec![
        Line {
            label: "measured",
            values: &h_before.measured_mps2,
            color: BLACK,
        },
        Line {
            label: "baseline",
            values: &h_before.predicted_mps2,
            color: BASELINE_COLOR,
        },
    ];
    if let Some(h) = h_after {
        lines.push(Line {
            label: "with the top effect",
            values: &h.predicted_mps2,
            color: AFTER_COLOR,
        });
    }
    lines_svg(title, &t, "time [s]", "mass acceleration [m/s^2]", &lines)
}

/// Residual element force over the state plane (against velocity and against displacement),
/// before and after, from the step cycles.
pub(super) fn svg_state_plane(detail: &DiagnosisDetail) -> anyhow::Result<String> {
    let cycles = &detail.search.cycles;
    let before: Vec<Vec<f64>> = cycles
        .iter()
        .map(|c| {
            let p = detail.search.baseline.predict(c);
            c.force_n.iter().zip(&p).map(|(g, p)| g - p).collect()
        })
        .collect();
    let after: Option<Vec<Vec<f64>>> = detail
        .after_fit
        .as_ref()
        .filter(|f| f.transform().sensor.is_none() && f.transform().mass_factor == 1.0)
        .map(|f| {
            cycles
                .iter()
                .map(|c| {
                    let p = f.predict(c);
                    c.force_n.iter().zip(&p).map(|(g, p)| g - p).collect()
                })
                .collect()
        });
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1200, 520)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        let root = root
            .titled("residual element force over the state plane (sine steps): baseline (red), with the top effect (blue)", ("sans-serif", 18))
            .map_err(draw_err)?;
        let panels = root.split_evenly((1, 2));
        let r_range = span(
            before
                .iter()
                .flatten()
                .chain(after.iter().flatten().flatten())
                .copied(),
        );
        for (k, panel) in panels.iter().enumerate() {
            let pick = |c: &diagnose::cycles::StepCycle| {
                if k == 0 {
                    c.velocity_mps.clone()
                } else {
                    c.displacement_m.clone()
                }
            };
            let x_range = span(cycles.iter().flat_map(&pick));
            let mut chart = ChartBuilder::on(panel)
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d(x_range, r_range.clone())
                .map_err(draw_err)?;
            chart
                .configure_mesh()
                .x_desc(if k == 0 {
                    "relative velocity x' [m/s]"
                } else {
                    "relative displacement x [m]"
                })
                .y_desc("residual force [N]")
                .draw()
                .map_err(draw_err)?;
            for (set, color) in [
                (Some(&before), BASELINE_COLOR),
                (after.as_ref(), AFTER_COLOR),
            ] {
                let Some(set) = set else { continue };
                for (c, r) in cycles.iter().zip(set) {
                    let xs = pick(c);
                    chart
                        .draw_series(
                            xs.iter()
                                .zip(r)
                                .step_by(2)
                                .map(|(x, y)| Circle::new((*x, *y), 1, color.filled())),
                        )
                        .map_err(draw_err)?;
                }
            }
        }
        root.present().map_err(draw_err)?;
    }
    Ok(svg)
}

/// Per-harmonic residual (DC to 5th) against frequency and against amplitude, before (solid)
/// and after (dashed markers).
pub(super) fn svg_harmonics(before: &Located, after: Option<&Located>) -> anyhow::Result<String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1200, 520)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        let root = root
            .titled("residual force harmonics per step: baseline (lines), with the top effect (crosses)", ("sans-serif", 18))
            .map_err(draw_err)?;
        let panels = root.split_evenly((1, 2));
        let palette = [
            RGBColor(127, 127, 127),
            RGBColor(31, 119, 180),
            RGBColor(255, 127, 14),
            RGBColor(44, 160, 44),
            RGBColor(214, 39, 40),
            RGBColor(148, 103, 189),
        ];
        let all = before
            .by_step
            .iter()
            .chain(after.iter().flat_map(|a| a.by_step.iter()));
        let ymax = all
            .flat_map(|s| s.harmonic_residual_n.iter().copied())
            .fold(0.0f64, f64::max)
            .max(1e-9);
        for (k, panel) in panels.iter().enumerate() {
            let key = |s: &diagnose::locate::StepGap| {
                if k == 0 {
                    s.frequency_hz
                } else {
                    1e3 * s.amplitude_m
                }
            };
            let x_range = span(before.by_step.iter().map(key));
            let mut chart = ChartBuilder::on(panel)
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d(x_range, 0.0..ymax * 1.05)
                .map_err(draw_err)?;
            chart
                .configure_mesh()
                .x_desc(if k == 0 {
                    "excitation frequency [Hz]"
                } else {
                    "relative displacement amplitude [mm]"
                })
                .y_desc("|residual harmonic| [N]")
                .draw()
                .map_err(draw_err)?;
            for n in 0..diagnose::locate::ORDERS {
                let color = palette[n % palette.len()];
                let mut pts: Vec<(f64, f64)> = before
                    .by_step
                    .iter()
                    .map(|s| (key(s), s.harmonic_residual_n[n]))
                    .collect();
                pts.sort_by(|a, b| a.0.total_cmp(&b.0));
                let label = match n {
                    0 => "DC".to_string(),
                    1 => "1st".into(),
                    2 => "2nd".into(),
                    3 => "3rd".into(),
                    _ => format!("{n}th"),
                };
                chart
                    .draw_series(LineSeries::new(pts, color.stroke_width(2)))
                    .map_err(draw_err)?
                    .label(label)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
                if let Some(a) = after {
                    chart
                        .draw_series(a.by_step.iter().map(|s| {
                            Cross::new((key(s), s.harmonic_residual_n[n]), 4, color.stroke_width(1))
                        }))
                        .map_err(draw_err)?;
                }
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()
                .map_err(draw_err)?;
        }
        root.present().map_err(draw_err)?;
    }
    Ok(svg)
}
