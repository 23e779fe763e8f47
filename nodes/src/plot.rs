//! SVG plots of what a person would rather look at than read: force-state maps of the fit and
//! time traces of the validation. Each file is rendered in memory and written atomically.

use std::path::Path;

use anyhow::Context;
use plotters::prelude::*;

/// One step of a force-state map: measured element force and the model's, over one period.
pub struct ForceStateStep {
    pub label: String,
    pub displacement_m: Vec<f64>,
    pub velocity_mps: Vec<f64>,
    pub measured_force_n: Vec<f64>,
    pub model_force_n: Vec<f64>,
}

/// One colour per step of the paper's 10-frequency run (the "tab10" palette).
const COLORS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

fn range(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
        (l.min(v), h.max(v))
    });
    if !lo.is_finite() || !hi.is_finite() {
        return -1.0..1.0;
    }
    let pad = 0.05 * (hi - lo).max(1e-12);
    (lo - pad)..(hi + pad)
}

/// Writes `text` to `path` through a temporary file in the same directory.
pub fn write_atomically(path: &Path, text: &str) -> anyhow::Result<()> {
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let tmp = dir.join(format!(
        ".{}.tmp",
        path.file_name().and_then(|n| n.to_str()).unwrap_or("plot")
    ));
    std::fs::write(&tmp, text).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| {
        let _ = std::fs::remove_file(&tmp);
        format!("renaming {} to {}", tmp.display(), path.display())
    })
}

fn draw_err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow::anyhow!("drawing the plot: {e:?}")
}

/// Element force against velocity (left) and against displacement (right): measured points
/// and the identified model's curve, one colour per step.
pub fn force_state_map(path: &Path, title: &str, steps: &[ForceStateStep]) -> anyhow::Result<()> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1200, 520)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        let root = root.titled(title, ("sans-serif", 18)).map_err(draw_err)?;
        let panels = root.split_evenly((1, 2));
        let f_range = range(
            steps
                .iter()
                .flat_map(|s| s.measured_force_n.iter().chain(&s.model_force_n).copied()),
        );
        for (panel, (xlabel, pick)) in panels.iter().zip([
            (
                "relative velocity x' [m/s]",
                (|s: &ForceStateStep| &s.velocity_mps) as fn(&ForceStateStep) -> &Vec<f64>,
            ),
            ("relative displacement x [m]", |s: &ForceStateStep| {
                &s.displacement_m
            }),
        ]) {
            let x_range = range(steps.iter().flat_map(|s| pick(s).iter().copied()));
            let mut chart = ChartBuilder::on(panel)
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d(x_range, f_range.clone())
                .map_err(draw_err)?;
            chart
                .configure_mesh()
                .x_desc(xlabel)
                .y_desc("element force g [N]")
                .draw()
                .map_err(draw_err)?;
            for (i, s) in steps.iter().enumerate() {
                let color = COLORS[i % COLORS.len()];
                let xs = pick(s);
                chart
                    .draw_series(
                        xs.iter()
                            .zip(&s.measured_force_n)
                            .map(|(x, g)| Circle::new((*x, *g), 2, color.filled())),
                    )
                    .map_err(draw_err)?
                    .label(format!("{} measured", s.label))
                    .legend(move |(x, y)| Circle::new((x, y), 3, color.filled()));
                let mut line: Vec<(f64, f64)> = xs
                    .iter()
                    .copied()
                    .zip(s.model_force_n.iter().copied())
                    .collect();
                line.push(line[0]);
                chart
                    .draw_series(LineSeries::new(line, color.stroke_width(1)))
                    .map_err(draw_err)?;
            }
            if steps.len() <= COLORS.len() {
                chart
                    .configure_series_labels()
                    .background_style(WHITE.mix(0.8))
                    .border_style(BLACK)
                    .draw()
                    .map_err(draw_err)?;
            }
        }
        root.present().map_err(draw_err)?;
    }
    write_atomically(path, &svg)
}

/// Measured against predicted time trace.
pub fn time_trace(
    path: &Path,
    title: &str,
    time_s: &[f64],
    measured: &[f64],
    predicted: &[f64],
    unit: &str,
) -> anyhow::Result<()> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1200, 420)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        let t_range = range(time_s.iter().copied());
        let y_range = range(measured.iter().chain(predicted).copied());
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(t_range, y_range)
            .map_err(draw_err)?;
        chart
            .configure_mesh()
            .x_desc("time [s]")
            .y_desc(unit)
            .draw()
            .map_err(draw_err)?;
        chart
            .draw_series(LineSeries::new(
                time_s.iter().copied().zip(measured.iter().copied()),
                BLACK.stroke_width(1),
            ))
            .map_err(draw_err)?
            .label("measured")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
        chart
            .draw_series(LineSeries::new(
                time_s.iter().copied().zip(predicted.iter().copied()),
                COLORS[3].stroke_width(1),
            ))
            .map_err(draw_err)?
            .label("predicted")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], COLORS[3]));
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(draw_err)?;
        root.present().map_err(draw_err)?;
    }
    write_atomically(path, &svg)
}
