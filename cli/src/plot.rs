//! SVG plots of what a person would rather look at than read: force-state maps of the fit and
//! time traces of the validation. Each file is rendered in memory and written atomically.

use std::path::Path;

use forcemap_io::atomic::write_atomically;
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

/// A plotters error as an anyhow error.
pub fn draw_err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
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

/// Colours of the baseline model and of the model with the top effect in the diagnosis plots.
pub const BASELINE_COLOR: RGBColor = RGBColor(214, 39, 40);
pub const AFTER_COLOR: RGBColor = RGBColor(31, 119, 180);

/// Axis range of the finite values, padded by 5 % ([-1, 1] when there are none).
pub fn span(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    range(values.filter(|v| v.is_finite()))
}

/// One line of [`lines_svg`].
pub struct Line<'a> {
    pub label: &'a str,
    pub values: &'a [f64],
    pub color: RGBColor,
}

/// Lines over a common abscissa (e.g. measured and predicted time traces), as SVG text.
pub fn lines_svg(
    title: &str,
    x: &[f64],
    x_desc: &str,
    y_desc: &str,
    lines: &[Line],
) -> anyhow::Result<String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1200, 420)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(
                span(x.iter().copied()),
                span(lines.iter().flat_map(|l| l.values.iter().copied())),
            )
            .map_err(draw_err)?;
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc(y_desc)
            .draw()
            .map_err(draw_err)?;
        for l in lines {
            let color = l.color;
            chart
                .draw_series(LineSeries::new(
                    x.iter().copied().zip(l.values.iter().copied()),
                    color.stroke_width(1),
                ))
                .map_err(draw_err)?
                .label(l.label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(draw_err)?;
        root.present().map_err(draw_err)?;
    }
    Ok(svg)
}

/// One panel of [`scatter_panels_svg`].
pub struct ScatterPanel<'a> {
    pub caption: String,
    pub x: &'a [f64],
    pub y: &'a [f64],
    pub color: RGBColor,
}

/// Side-by-side scatter plots with common axes (e.g. a residual against velocity before and
/// after), as SVG text.
pub fn scatter_panels_svg(
    title: &str,
    x_desc: &str,
    y_desc: &str,
    panels: &[ScatterPanel],
) -> anyhow::Result<String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1200, 480)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        let root = root.titled(title, ("sans-serif", 18)).map_err(draw_err)?;
        let x_range = span(panels.iter().flat_map(|p| p.x.iter().copied()));
        let y_range = span(panels.iter().flat_map(|p| p.y.iter().copied()));
        for (area, p) in root
            .split_evenly((1, panels.len().max(1)))
            .iter()
            .zip(panels)
        {
            let mut chart = ChartBuilder::on(area)
                .caption(&p.caption, ("sans-serif", 15))
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d(x_range.clone(), y_range.clone())
                .map_err(draw_err)?;
            chart
                .configure_mesh()
                .x_desc(x_desc)
                .y_desc(y_desc)
                .draw()
                .map_err(draw_err)?;
            chart
                .draw_series(
                    p.x.iter()
                        .zip(p.y)
                        .filter(|(x, y)| x.is_finite() && y.is_finite())
                        .map(|(x, y)| Circle::new((*x, *y), 1, p.color.filled())),
                )
                .map_err(draw_err)?;
        }
        root.present().map_err(draw_err)?;
    }
    Ok(svg)
}

/// Mean of `value` in the bins of an `nx` x `ny` grid over the ranges of `x` and `y`.
#[derive(Debug, Clone)]
pub struct BinnedMean {
    pub x_range: std::ops::Range<f64>,
    pub y_range: std::ops::Range<f64>,
    /// `means[i][j]`: bin i of x, bin j of y; None where no sample fell.
    pub means: Vec<Vec<Option<f64>>>,
}

impl BinnedMean {
    pub fn new(x: &[f64], y: &[f64], value: &[f64], nx: usize, ny: usize) -> BinnedMean {
        let (nx, ny) = (nx.max(1), ny.max(1));
        let x_range = span(x.iter().copied());
        let y_range = span(y.iter().copied());
        let mut sum = vec![vec![(0.0, 0usize); ny]; nx];
        let bin = |v: f64, r: &std::ops::Range<f64>, n: usize| {
            (((v - r.start) / (r.end - r.start) * n as f64) as usize).min(n - 1)
        };
        for ((x, y), v) in x.iter().zip(y).zip(value) {
            if x.is_finite() && y.is_finite() && v.is_finite() {
                let cell = &mut sum[bin(*x, &x_range, nx)][bin(*y, &y_range, ny)];
                cell.0 += v;
                cell.1 += 1;
            }
        }
        let means = sum
            .into_iter()
            .map(|col| {
                col.into_iter()
                    .map(|(s, n)| (n > 0).then(|| s / n as f64))
                    .collect()
            })
            .collect();
        BinnedMean {
            x_range,
            y_range,
            means,
        }
    }

    fn max_abs(&self) -> f64 {
        self.means
            .iter()
            .flatten()
            .flatten()
            .fold(0.0f64, |m, v| m.max(v.abs()))
    }
}

/// Blue (negative) through white to red (positive), saturated at +-`scale`.
fn diverging(v: f64, scale: f64) -> RGBColor {
    let t = (v / scale.max(f64::MIN_POSITIVE)).clamp(-1.0, 1.0);
    let fade = |c: u8, t: f64| (255.0 + (c as f64 - 255.0) * t.abs()).round() as u8;
    let c = if t >= 0.0 {
        BASELINE_COLOR
    } else {
        AFTER_COLOR
    };
    RGBColor(fade(c.0, t), fade(c.1, t), fade(c.2, t))
}

/// Side-by-side maps of binned means over a plane (e.g. the residual over the state plane
/// before and after), one diverging colour scale for all panels (its range in the title).
pub fn heatmap_panels_svg(
    title: &str,
    x_desc: &str,
    y_desc: &str,
    unit: &str,
    panels: &[(String, BinnedMean)],
) -> anyhow::Result<String> {
    let scale = panels.iter().fold(0.0f64, |m, (_, b)| m.max(b.max_abs()));
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1200, 520)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        let root = root
            .titled(
                &format!("{title} (colour: red +{scale:.2} {unit}, white 0, blue -{scale:.2} {unit}; grey: no samples)"),
                ("sans-serif", 16),
            )
            .map_err(draw_err)?;
        for (area, (caption, b)) in root
            .split_evenly((1, panels.len().max(1)))
            .iter()
            .zip(panels)
        {
            let mut chart = ChartBuilder::on(area)
                .caption(caption, ("sans-serif", 15))
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d(b.x_range.clone(), b.y_range.clone())
                .map_err(draw_err)?;
            chart
                .configure_mesh()
                .disable_mesh()
                .x_desc(x_desc)
                .y_desc(y_desc)
                .draw()
                .map_err(draw_err)?;
            let nx = b.means.len();
            let ny = b.means.first().map_or(1, Vec::len);
            let dx = (b.x_range.end - b.x_range.start) / nx as f64;
            let dy = (b.y_range.end - b.y_range.start) / ny as f64;
            chart
                .draw_series(b.means.iter().enumerate().flat_map(|(i, col)| {
                    col.iter().enumerate().map(move |(j, v)| {
                        let x0 = b.x_range.start + i as f64 * dx;
                        let y0 = b.y_range.start + j as f64 * dy;
                        let color = v.map_or(RGBColor(235, 235, 235), |v| diverging(v, scale));
                        Rectangle::new([(x0, y0), (x0 + dx, y0 + dy)], color.filled())
                    })
                }))
                .map_err(draw_err)?;
        }
        root.present().map_err(draw_err)?;
    }
    Ok(svg)
}

/// One series of a [`SeriesPanel`]: points, marked, and joined in order when `line`.
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    pub color: RGBColor,
    pub line: bool,
}

/// One panel of [`series_panels_svg`].
pub struct SeriesPanel {
    pub caption: String,
    pub x_desc: String,
    pub y_desc: String,
    pub series: Vec<Series>,
}

/// Side-by-side panels of marked lines, each with its own axes and legend (e.g. storage and
/// loss stiffness against frequency, one line per amplitude), as SVG text.
pub fn series_panels_svg(title: &str, panels: &[SeriesPanel]) -> anyhow::Result<String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1200, 480)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        let root = root.titled(title, ("sans-serif", 18)).map_err(draw_err)?;
        for (area, p) in root
            .split_evenly((1, panels.len().max(1)))
            .iter()
            .zip(panels)
        {
            let points = || p.series.iter().flat_map(|s| s.points.iter());
            let mut chart = ChartBuilder::on(area)
                .caption(&p.caption, ("sans-serif", 15))
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(70)
                .build_cartesian_2d(span(points().map(|q| q.0)), span(points().map(|q| q.1)))
                .map_err(draw_err)?;
            chart
                .configure_mesh()
                .x_desc(&p.x_desc)
                .y_desc(&p.y_desc)
                .draw()
                .map_err(draw_err)?;
            for s in &p.series {
                let color = s.color;
                let finite: Vec<(f64, f64)> = s
                    .points
                    .iter()
                    .copied()
                    .filter(|(x, y)| x.is_finite() && y.is_finite())
                    .collect();
                let marks = chart
                    .draw_series(finite.iter().map(|q| Circle::new(*q, 3, color.filled())))
                    .map_err(draw_err)?;
                if s.line {
                    chart
                        .draw_series(LineSeries::new(finite, color.stroke_width(2)))
                        .map_err(draw_err)?
                        .label(s.label.clone())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
                } else {
                    marks
                        .label(s.label.clone())
                        .legend(move |(x, y)| Circle::new((x + 10, y), 4, color.filled()));
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

/// The driven channel of records over time, each record in its own colour with its step and
/// kind written above it, so a reader sees how the data were cut; as SVG text.
pub fn records_svg(
    title: &str,
    records: &[forcemap_math::record::Record],
    driven: forcemap_math::record::Channel,
) -> anyhow::Result<String> {
    let traces: Vec<(Vec<f64>, &[f64])> = records
        .iter()
        .filter_map(|r| {
            let v = r.channel(driven)?;
            let t = (0..v.len())
                .map(|k| r.start_time_s + k as f64 / r.sample_rate_hz)
                .collect();
            Some((t, v))
        })
        .collect();
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1400, 460)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        let y_range = span(traces.iter().flat_map(|(_, v)| v.iter().copied()));
        let top = y_range.end;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(
                span(traces.iter().flat_map(|(t, _)| t.iter().copied())),
                y_range,
            )
            .map_err(draw_err)?;
        chart
            .configure_mesh()
            .x_desc("time [s]")
            .y_desc(driven.name())
            .draw()
            .map_err(draw_err)?;
        for (i, ((t, v), r)) in traces.iter().zip(records).enumerate() {
            let color = series_color(i);
            chart
                .draw_series(LineSeries::new(
                    t.iter().copied().zip(v.iter().copied()),
                    color.stroke_width(1),
                ))
                .map_err(draw_err)?;
            use forcemap_math::record::Excitation as E;
            let kind = match &r.excitation {
                E::Sine { frequency_hz, .. } => format!("{} sine {frequency_hz:.4} Hz", r.step),
                E::Random { .. } => format!("{} random", r.step),
                E::Multisine { .. } => format!("{} multisine", r.step),
                E::Sweep { .. } => format!("{} sweep", r.step),
            };
            if let Some(&t0) = t.first() {
                chart
                    .draw_series(std::iter::once(Text::new(
                        kind,
                        (t0, top),
                        ("sans-serif", 12).into_font().color(&color),
                    )))
                    .map_err(draw_err)?;
            }
        }
        root.present().map_err(draw_err)?;
    }
    Ok(svg)
}

/// The colour of series `i` (the "tab10" palette, repeating).
pub fn series_color(i: usize) -> RGBColor {
    COLORS[i % COLORS.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn binned_means_land_in_their_cells() {
        let b = BinnedMean::new(&[0.0, 0.0, 1.0], &[0.0, 0.0, 1.0], &[1.0, 3.0, -5.0], 2, 2);
        assert_eq!(b.means[0][0], Some(2.0));
        assert_eq!(b.means[1][1], Some(-5.0));
        assert_eq!(b.means[0][1], None);
        assert_eq!(b.max_abs(), 5.0);
    }
}
