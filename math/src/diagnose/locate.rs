//! Where the gap lies: per step (frequency and amplitude), per harmonic order, and over the
//! state plane, from the baseline's residual element force on the step cycles.

use serde::Serialize;

use super::cycles::{StepCycle, harmonics_of};
use super::fit::Fitted;

/// Harmonic orders reported (DC, 1st, ... 5th).
pub const ORDERS: usize = 6;

#[derive(Debug, Clone, Serialize)]
pub struct StepGap {
    pub step: usize,
    pub frequency_hz: f64,
    /// First-harmonic amplitude of the relative displacement [m].
    pub amplitude_m: f64,
    /// 100 * RMS residual force / RMS element force over the whole period [%].
    pub mismatch_percent: f64,
    /// |residual harmonic n| [N], n = 0..ORDERS.
    pub harmonic_residual_n: Vec<f64>,
    /// Noise of force harmonic n [N].
    pub harmonic_noise_n: Vec<f64>,
}

#[derive(Debug, Clone, Serialize)]
pub struct HarmonicGap {
    /// 0 = DC, 1 = fundamental, ...
    pub order: usize,
    /// RMS over steps of |residual harmonic n|, relative to the RMS first force harmonic [%].
    pub residual_percent: f64,
    /// The same for the noise [%].
    pub noise_percent: f64,
    /// Residual above 3 noise standard deviations.
    pub significant: bool,
}

#[derive(Debug, Clone, Serialize)]
pub struct Region {
    pub name: String,
    /// RMS residual force in the region [N].
    pub rms_residual_n: f64,
    /// Relative to the RMS residual over all points.
    pub ratio_to_overall: f64,
}

/// Residual force binned over the state plane.
#[derive(Debug, Clone, Serialize)]
pub struct StatePlane {
    pub displacement_edges_m: Vec<f64>,
    pub velocity_edges_mps: Vec<f64>,
    /// [velocity bin][displacement bin] RMS residual [N] (NaN where empty).
    pub rms_residual_n: Vec<Vec<f64>>,
    /// [velocity bin][displacement bin] mean residual [N] (NaN where empty).
    pub mean_residual_n: Vec<Vec<f64>>,
}

#[derive(Debug, Clone, Serialize)]
pub struct Located {
    pub by_step: Vec<StepGap>,
    pub by_harmonic: Vec<HarmonicGap>,
    pub regions: Vec<Region>,
    pub state_plane: StatePlane,
    /// Mean step mismatch of the lower and upper half of the steps by amplitude [%].
    pub low_amplitude_mismatch_percent: f64,
    pub high_amplitude_mismatch_percent: f64,
    /// Mean step mismatch of the lower and upper half of the steps by frequency [%].
    pub low_frequency_mismatch_percent: f64,
    pub high_frequency_mismatch_percent: f64,
    /// Readable findings, strongest first.
    pub summary: Vec<String>,
}

const BINS: usize = 8;

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

fn halves(steps: &[StepGap], key: impl Fn(&StepGap) -> f64) -> (f64, f64) {
    let mut s: Vec<&StepGap> = steps.iter().collect();
    s.sort_by(|a, b| key(a).total_cmp(&key(b)));
    let h = s.len() / 2;
    let mean =
        |v: &[&StepGap]| v.iter().map(|g| g.mismatch_percent).sum::<f64>() / v.len().max(1) as f64;
    if s.len() < 2 {
        let m = mean(&s);
        return (m, m);
    }
    (mean(&s[..h]), mean(&s[s.len() - h..]))
}

/// Locates the residual of `baseline` on `cycles`.
pub fn locate(baseline: &Fitted, cycles: &[StepCycle]) -> Located {
    let mut by_step = Vec::new();
    let mut all_res = Vec::new();
    // region membership per point
    let names = [
        "near zero velocity (velocity reversals)",
        "high velocity",
        "small displacement (around x = 0)",
        "large displacement",
    ];
    let mut region_res: Vec<Vec<f64>> = vec![Vec::new(); names.len()];
    let xmax = cycles
        .iter()
        .flat_map(|c| c.displacement_m.iter())
        .fold(0.0f64, |m, x| m.max(x.abs()))
        .max(f64::MIN_POSITIVE);
    let vmax = cycles
        .iter()
        .flat_map(|c| c.velocity_mps.iter())
        .fold(0.0f64, |m, v| m.max(v.abs()))
        .max(f64::MIN_POSITIVE);
    let mut sum2 = vec![vec![0.0; BINS]; BINS];
    let mut sum1 = vec![vec![0.0; BINS]; BINS];
    let mut count = vec![vec![0usize; BINS]; BINS];
    let bin = |v: f64, max: f64| {
        (((v / max + 1.0) / 2.0 * BINS as f64).floor() as isize).clamp(0, BINS as isize - 1)
            as usize
    };
    let mut g1 = Vec::new();
    for c in cycles {
        let pred = baseline.predict(c);
        let res: Vec<f64> = c.force_n.iter().zip(&pred).map(|(g, p)| g - p).collect();
        let h = harmonics_of(&res, ORDERS - 1);
        let gh = harmonics_of(&c.force_n, 1);
        g1.push(gh[1].norm());
        let cx = c
            .displacement_m
            .iter()
            .fold(0.0f64, |m, x| m.max(x.abs()))
            .max(f64::MIN_POSITIVE);
        let cv = c
            .velocity_mps
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs()))
            .max(f64::MIN_POSITIVE);
        for ((x, v), r) in c.displacement_m.iter().zip(&c.velocity_mps).zip(&res) {
            let (xn, vn) = (x.abs() / cx, v.abs() / cv);
            for (k, inside) in [vn < 0.2, vn > 0.8, xn < 0.2, xn > 0.8].iter().enumerate() {
                if *inside {
                    region_res[k].push(*r);
                }
            }
            let (i, j) = (bin(*v, vmax), bin(*x, xmax));
            sum2[i][j] += r * r;
            sum1[i][j] += r;
            count[i][j] += 1;
        }
        all_res.extend_from_slice(&res);
        by_step.push(StepGap {
            step: c.step,
            frequency_hz: c.frequency_hz,
            amplitude_m: c.amplitude_m,
            mismatch_percent: 100.0 * rms(&res) / rms(&c.force_n).max(f64::MIN_POSITIVE),
            harmonic_residual_n: h.iter().map(|z| z.norm()).collect(),
            harmonic_noise_n: (0..ORDERS)
                .map(|n| c.force_harmonic_noise_n.get(n).copied().unwrap_or(f64::NAN))
                .collect(),
        });
    }
    let overall = rms(&all_res).max(f64::MIN_POSITIVE);
    let regions: Vec<Region> = names
        .iter()
        .zip(&region_res)
        .map(|(n, r)| Region {
            name: n.to_string(),
            rms_residual_n: rms(r),
            ratio_to_overall: rms(r) / overall,
        })
        .collect();
    let g1_rms = rms(&g1).max(f64::MIN_POSITIVE);
    let by_harmonic: Vec<HarmonicGap> = (0..ORDERS)
        .map(|n| {
            let r: Vec<f64> = by_step
                .iter()
                .map(|s| s.harmonic_residual_n.get(n).copied().unwrap_or(0.0))
                .collect();
            let s: Vec<f64> = by_step
                .iter()
                .map(|s| s.harmonic_noise_n[n])
                .filter(|v| v.is_finite())
                .collect();
            let (rr, ss) = (rms(&r), rms(&s));
            HarmonicGap {
                order: n,
                residual_percent: 100.0 * rr / g1_rms,
                noise_percent: 100.0 * ss / g1_rms,
                significant: rr > 3.0 * ss,
            }
        })
        .collect();
    let (low_a, high_a) = halves(&by_step, |s| s.amplitude_m);
    let (low_f, high_f) = halves(&by_step, |s| s.frequency_hz);
    let edges = |max: f64| {
        (0..=BINS)
            .map(|i| -max + 2.0 * max * i as f64 / BINS as f64)
            .collect::<Vec<_>>()
    };
    let state_plane = StatePlane {
        displacement_edges_m: edges(xmax),
        velocity_edges_mps: edges(vmax),
        rms_residual_n: (0..BINS)
            .map(|i| {
                (0..BINS)
                    .map(|j| {
                        if count[i][j] > 0 {
                            (sum2[i][j] / count[i][j] as f64).sqrt()
                        } else {
                            f64::NAN
                        }
                    })
                    .collect()
            })
            .collect(),
        mean_residual_n: (0..BINS)
            .map(|i| {
                (0..BINS)
                    .map(|j| {
                        if count[i][j] > 0 {
                            sum1[i][j] / count[i][j] as f64
                        } else {
                            f64::NAN
                        }
                    })
                    .collect()
            })
            .collect(),
    };
    let mut summary = Vec::new();
    let mut regs: Vec<&Region> = regions
        .iter()
        .filter(|r| r.ratio_to_overall > 1.3)
        .collect();
    regs.sort_by(|a, b| b.ratio_to_overall.total_cmp(&a.ratio_to_overall));
    for r in regs {
        summary.push(format!(
            "state plane: {}: residual RMS {:.2} x the average",
            r.name, r.ratio_to_overall
        ));
    }
    let sig: Vec<String> = by_harmonic
        .iter()
        .filter(|h| h.significant && h.order != 1)
        .map(|h| {
            let name = match h.order {
                0 => "DC".to_string(),
                2 => "2nd".into(),
                3 => "3rd".into(),
                n => format!("{n}th"),
            };
            format!("{name} {:.2} %", h.residual_percent)
        })
        .collect();
    let first = &by_harmonic[1];
    summary.push(format!(
        "harmonics: 1st {:.2} % of the fundamental force{}",
        first.residual_percent,
        if sig.is_empty() {
            "; no other order stands out of the noise".to_string()
        } else {
            format!("; also {}", sig.join(", "))
        }
    ));
    if low_a > 1.3 * high_a {
        summary.push(format!(
            "amplitude: larger at low amplitude ({low_a:.2} % vs {high_a:.2} % mismatch)"
        ));
    } else if high_a > 1.3 * low_a {
        summary.push(format!(
            "amplitude: larger at high amplitude ({high_a:.2} % vs {low_a:.2} % mismatch)"
        ));
    }
    if low_f > 1.3 * high_f {
        summary.push(format!(
            "frequency: larger at low frequency ({low_f:.2} % vs {high_f:.2} % mismatch)"
        ));
    } else if high_f > 1.3 * low_f {
        summary.push(format!(
            "frequency: larger at high frequency ({high_f:.2} % vs {low_f:.2} % mismatch)"
        ));
    }
    Located {
        by_step,
        by_harmonic,
        regions,
        state_plane,
        low_amplitude_mismatch_percent: low_a,
        high_amplitude_mismatch_percent: high_a,
        low_frequency_mismatch_percent: low_f,
        high_frequency_mismatch_percent: high_f,
        summary,
    }
}
