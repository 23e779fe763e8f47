//! The time-domain path of the gap diagnosis, for data that are not stepped sines: a
//! force-driven axis (the EMPS benchmark, `tau = M q'' + Fv q' + ... + offset`), fitted by least
//! squares on one record and scored on another by the relative force error, after the
//! published procedure (position low-passed without phase shift, derivatives by central
//! differences, every column and the force low-passed again and decimated).
//!
//! Candidates here are the element-force effects: coulomb_friction, stribeck_friction,
//! quadratic_damping, asymmetric_damping (Fv+ != Fv-), cubic_stiffness and quadratic_stiffness
//! (in the position about its mean) and hysteresis (Bouc-Wen over the measured motion). The
//! rig-channel effects (exciter_delay, sensor_lowpass) and mass_error (M is fitted) do not
//! apply to a force-driven axis, and free_play has no centre on a travelling axis.

use serde::Serialize;

use super::effects::Effect;
use super::score::penalised;
use super::{ParameterValue, Verdict, parameter_values, verdict};
use crate::lstsq::{self, LstsqError};
use crate::sim::rig::zero_phase_lowpass;

/// A record of a force-driven axis.
#[derive(Debug, Clone)]
pub struct AxisRecord {
    pub sample_rate_hz: f64,
    pub position_m: Vec<f64>,
    pub force_n: Vec<f64>,
}

/// Preparation of the regressors.
#[derive(Debug, Clone, Copy)]
pub struct TimeDomainOptions {
    /// Zero-phase low-pass of the position before differentiation [Hz].
    pub position_cutoff_hz: f64,
    /// Keep one sample in this many after the anti-alias low-pass.
    pub decimation: usize,
}

impl Default for TimeDomainOptions {
    fn default() -> Self {
        TimeDomainOptions {
            position_cutoff_hz: 40.0,
            decimation: 10,
        }
    }
}

/// The baselines of the time-domain path.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum AxisBaseline {
    /// M q'' + Fv q' + offset.
    EmpsViscous,
    /// M q'' + Fv q' + Fc sgn(q') + offset (the published model).
    EmpsCoulomb,
}

impl AxisBaseline {
    pub fn from_name(name: &str) -> Option<AxisBaseline> {
        match name {
            "emps-viscous" => Some(AxisBaseline::EmpsViscous),
            "emps-coulomb" => Some(AxisBaseline::EmpsCoulomb),
            _ => None,
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            AxisBaseline::EmpsViscous => "emps-viscous",
            AxisBaseline::EmpsCoulomb => "emps-coulomb",
        }
    }
}

/// Full-rate motion after the position low-pass.
struct Motion {
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
    fs: f64,
    q_mean: f64,
}

fn motion(r: &AxisRecord, o: &TimeDomainOptions) -> Motion {
    let fs = r.sample_rate_hz;
    let dt = 1.0 / fs;
    // Two passes of the 2nd-order zero-phase filter: 8th-order magnitude roll-off.
    let q = zero_phase_lowpass(
        &zero_phase_lowpass(&r.position_m, fs, o.position_cutoff_hz),
        fs,
        o.position_cutoff_hz,
    );
    let n = q.len();
    let mut qd = vec![0.0; n];
    let mut qdd = vec![0.0; n];
    for i in 1..n.saturating_sub(1) {
        qd[i] = (q[i + 1] - q[i - 1]) / (2.0 * dt);
        qdd[i] = (q[i + 1] - 2.0 * q[i] + q[i - 1]) / (dt * dt);
    }
    let q_mean = q.iter().sum::<f64>() / n.max(1) as f64;
    Motion {
        q,
        qd,
        qdd,
        fs,
        q_mean,
    }
}

/// A regressor column at full rate, anti-alias filtered and decimated (edges of a quarter
/// second left out).
fn decimate(m: &Motion, full: &[f64], o: &TimeDomainOptions) -> Vec<f64> {
    let cut = 0.8 * m.fs / 2.0 / o.decimation as f64;
    let f = zero_phase_lowpass(&zero_phase_lowpass(full, m.fs, cut), m.fs, cut);
    let edge = (0.25 * m.fs).round() as usize;
    let mut out = Vec::new();
    let mut i = edge;
    while i + edge < f.len() {
        out.push(f[i]);
        i += o.decimation;
    }
    out
}

/// A named regressor evaluated on the motion.
#[derive(Debug, Clone)]
enum Column {
    Acceleration,
    Velocity,
    Offset,
    Sign,
    Stribeck(f64),
    SignedSquareVelocity,
    AbsVelocity,
    Cubic,
    SignedSquarePosition,
    SquarePosition,
    BoucWen(f64),
}

impl Column {
    fn symbol(&self) -> String {
        match self {
            Column::Acceleration => "m".into(),
            Column::Velocity => "fv".into(),
            Column::Offset => "offset".into(),
            Column::Sign => "fc".into(),
            Column::Stribeck(_) => "fs".into(),
            Column::SignedSquareVelocity => "c2".into(),
            Column::AbsVelocity => "ca".into(),
            Column::Cubic => "s".into(),
            Column::SignedSquarePosition => "k2".into(),
            Column::SquarePosition => "k2a".into(),
            Column::BoucWen(_) => "alpha".into(),
        }
    }

    fn full(&self, m: &Motion) -> Vec<f64> {
        let sgn = |v: f64| if v == 0.0 { 0.0 } else { v.signum() };
        let dq = |q: f64| q - m.q_mean;
        match self {
            Column::Acceleration => m.qdd.clone(),
            Column::Velocity => m.qd.clone(),
            Column::Offset => vec![1.0; m.q.len()],
            Column::Sign => m.qd.iter().map(|v| sgn(*v)).collect(),
            Column::Stribeck(vs) => {
                m.qd.iter()
                    .map(|v| sgn(*v) * (-(v / vs).powi(2)).exp())
                    .collect()
            }
            Column::SignedSquareVelocity => m.qd.iter().map(|v| v * v.abs()).collect(),
            Column::AbsVelocity => m.qd.iter().map(|v| v.abs()).collect(),
            Column::Cubic => m.q.iter().map(|q| dq(*q).powi(3)).collect(),
            Column::SignedSquarePosition => m.q.iter().map(|q| dq(*q) * dq(*q).abs()).collect(),
            Column::SquarePosition => m.q.iter().map(|q| dq(*q).powi(2)).collect(),
            Column::BoucWen(zy) => {
                let dt = 1.0 / m.fs;
                let mut z = 0.0;
                m.qd.iter()
                    .map(|v| {
                        z += dt * (v - (v.abs() * z + v * z.abs()) / (2.0 * zy));
                        z
                    })
                    .collect()
            }
        }
    }
}

struct Prepared {
    motion: Motion,
    force: Vec<f64>,
}

fn prepare(r: &AxisRecord, o: &TimeDomainOptions) -> Prepared {
    let m = motion(r, o);
    let force = decimate(&m, &r.force_n, o);
    Prepared { motion: m, force }
}

fn design(p: &Prepared, cols: &[Column], o: &TimeDomainOptions) -> Vec<Vec<f64>> {
    cols.iter()
        .map(|c| decimate(&p.motion, &c.full(&p.motion), o))
        .collect()
}

fn relative_error(cols: &[Vec<f64>], y: &[f64], theta: &[f64]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (i, t) in y.iter().enumerate() {
        let pred: f64 = cols.iter().zip(theta).map(|(c, th)| c[i] * th).sum();
        num += (t - pred).powi(2);
        den += t * t;
    }
    100.0 * (num / den.max(f64::MIN_POSITIVE)).sqrt()
}

struct TdFit {
    names: Vec<String>,
    theta: Vec<f64>,
    std: Vec<f64>,
    fit_percent: f64,
    validation_percent: f64,
}

fn fit_and_score(
    fit: &Prepared,
    val: &Prepared,
    cols: &[Column],
    o: &TimeDomainOptions,
) -> Result<TdFit, LstsqError> {
    let a_cols = design(fit, cols, o);
    let names: Vec<String> = cols.iter().map(|c| c.symbol()).collect();
    let n = fit.force.len();
    let a = nalgebra::DMatrix::from_fn(n, cols.len(), |r, c| a_cols[c][r]);
    let b = nalgebra::DVector::from_column_slice(&fit.force);
    let sol = lstsq::solve(&a, &b, &names, 1.0)?;
    let v_cols = design(val, cols, o);
    Ok(TdFit {
        fit_percent: relative_error(&a_cols, &fit.force, &sol.theta),
        validation_percent: relative_error(&v_cols, &val.force, &sol.theta),
        std: sol.std(),
        theta: sol.theta,
        names,
    })
}

/// One candidate of the time-domain path.
#[derive(Debug, Clone, Serialize)]
pub struct AxisRankedEffect {
    pub effect: Effect,
    /// Relative force error on the validation record with the effect [%].
    pub gap_after_percent: f64,
    /// The same on the fitting record [%].
    pub fit_percent: f64,
    pub score_percent: f64,
    pub extra_parameters: usize,
    pub added_parameters: Vec<ParameterValue>,
    pub significant: bool,
    pub signature: String,
}

/// Where the baseline's residual lies, by velocity.
#[derive(Debug, Clone, Serialize)]
pub struct AxisLocated {
    /// Mean residual force for q' > 0 and q' < 0 [N] (asymmetry).
    pub mean_residual_positive_velocity_n: f64,
    pub mean_residual_negative_velocity_n: f64,
    /// RMS residual near zero velocity (|q'| < 10 % of the peak) and elsewhere [N].
    pub rms_residual_near_zero_velocity_n: f64,
    pub rms_residual_elsewhere_n: f64,
    pub summary: Vec<String>,
}

/// The time-domain diagnosis.
#[derive(Debug, Clone, Serialize)]
pub struct AxisDiagnosis {
    pub verdict: Verdict,
    pub top_effect: Option<Effect>,
    /// Relative force error of the baseline on the validation record [%].
    pub gap_before_percent: f64,
    pub gap_after_percent: f64,
    pub fit_before_percent: f64,
    pub baseline_model: String,
    pub baseline_parameters: Vec<ParameterValue>,
    pub ranked_effects: Vec<AxisRankedEffect>,
    pub located: AxisLocated,
    pub equations: usize,
    pub rule: String,
}

/// Searched grids, relative to the peak speed and the position range.
const STRIBECK_FRACTIONS: [f64; 5] = [0.01, 0.02, 0.05, 0.1, 0.2];
const YIELD_FRACTIONS: [f64; 5] = [0.001, 0.003, 0.01, 0.03, 0.1];

/// Diagnoses the baseline on an axis: fit on `fit`, score on `validation`. The floor of the
/// verdict rule is zero here (no repeated periods to estimate the noise from).
pub fn diagnose_axis(
    baseline: AxisBaseline,
    fit: &AxisRecord,
    validation: &AxisRecord,
    options: &TimeDomainOptions,
) -> Result<AxisDiagnosis, LstsqError> {
    let pf = prepare(fit, options);
    let pv = prepare(validation, options);
    let mut base = vec![Column::Acceleration, Column::Velocity, Column::Offset];
    if baseline == AxisBaseline::EmpsCoulomb {
        base.insert(2, Column::Sign);
    }
    let b = fit_and_score(&pf, &pv, &base, options)?;
    let vmax = pf
        .motion
        .qd
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()))
        .max(1e-12);
    let (qlo, qhi) = pf
        .motion
        .q
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), q| {
            (l.min(*q), h.max(*q))
        });
    let range = (qhi - qlo).max(1e-12);
    let n_eff = pv.force.len() as f64;
    let pen = |e: f64, p: usize| penalised(e * e, p, n_eff).sqrt();
    let base_score = pen(b.validation_percent, 0);
    let mut candidates: Vec<(Effect, Vec<Vec<Column>>)> = vec![
        (
            Effect::StribeckFriction,
            STRIBECK_FRACTIONS
                .iter()
                .map(|f| {
                    let mut c = vec![Column::Stribeck(f * vmax)];
                    if baseline == AxisBaseline::EmpsViscous {
                        c.insert(0, Column::Sign);
                    }
                    c
                })
                .collect(),
        ),
        (
            Effect::QuadraticDamping,
            vec![vec![Column::SignedSquareVelocity]],
        ),
        (Effect::AsymmetricDamping, vec![vec![Column::AbsVelocity]]),
        (Effect::CubicStiffness, vec![vec![Column::Cubic]]),
        (
            Effect::QuadraticStiffness,
            vec![vec![Column::SignedSquarePosition, Column::SquarePosition]],
        ),
        (
            Effect::Hysteresis,
            YIELD_FRACTIONS
                .iter()
                .map(|f| vec![Column::BoucWen(f * range)])
                .collect(),
        ),
    ];
    if baseline == AxisBaseline::EmpsViscous {
        candidates.insert(0, (Effect::CoulombFriction, vec![vec![Column::Sign]]));
    }
    let mut ranked = Vec::new();
    for (effect, options_list) in candidates {
        let mut best: Option<(TdFit, Vec<Column>)> = None;
        for extra in options_list {
            let mut cols = base.clone();
            cols.extend(extra.iter().cloned());
            let Ok(f) = fit_and_score(&pf, &pv, &cols, options) else {
                continue;
            };
            let wrong_sign =
                f.names.iter().zip(&f.theta).skip(base.len()).any(|(n, v)| {
                    super::search::POSITIVE_SYMBOLS.contains(&n.as_str()) && *v <= 0.0
                });
            if wrong_sign {
                continue;
            }
            // The searched parameter is chosen on the fitting record only.
            if best
                .as_ref()
                .is_none_or(|(bf, _)| f.fit_percent < bf.fit_percent)
            {
                best = Some((f, extra));
            }
        }
        let Some((f, extra)) = best else { continue };
        let searched = match extra.last() {
            Some(Column::Stribeck(vs)) => Some(("stribeck_velocity_mps", *vs)),
            Some(Column::BoucWen(zy)) => Some(("yield_m", *zy)),
            _ => None,
        };
        let extra_parameters = extra.len() + usize::from(searched.is_some());
        let mut added: Vec<(String, f64, f64)> = f
            .names
            .iter()
            .zip(&f.theta)
            .zip(&f.std)
            .skip(base.len())
            .map(|((n, v), s)| (n.clone(), *v, *s))
            .collect();
        if let Some((n, v)) = searched {
            added.push((n.into(), v, f64::NAN));
        }
        let score = pen(f.validation_percent, extra_parameters);
        ranked.push(AxisRankedEffect {
            effect,
            gap_after_percent: f.validation_percent,
            fit_percent: f.fit_percent,
            score_percent: score,
            extra_parameters,
            added_parameters: parameter_values(added),
            significant: super::significant(
                b.validation_percent,
                0.0,
                f.validation_percent,
                score,
                base_score,
            ),
            signature: effect.signature().into(),
        });
    }
    ranked.sort_by(|a, b| a.score_percent.total_cmp(&b.score_percent));
    let v = verdict(
        b.validation_percent,
        0.0,
        ranked.first().map(|r| (r.gap_after_percent, r.significant)),
    );
    // Where: the baseline's residual on the validation record by velocity.
    let cols = design(&pv, &base, options);
    let qd = decimate(&pv.motion, &pv.motion.qd, options);
    let vpk = qd.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-12);
    let (mut sp, mut np, mut sn, mut nn, mut s0, mut n0, mut s1, mut n1) =
        (0.0, 0usize, 0.0, 0usize, 0.0, 0usize, 0.0, 0usize);
    for (i, t) in pv.force.iter().enumerate() {
        let pred: f64 = cols.iter().zip(&b.theta).map(|(c, th)| c[i] * th).sum();
        let r = t - pred;
        if qd[i] > 0.0 {
            sp += r;
            np += 1;
        } else if qd[i] < 0.0 {
            sn += r;
            nn += 1;
        }
        if qd[i].abs() < 0.1 * vpk {
            s0 += r * r;
            n0 += 1;
        } else {
            s1 += r * r;
            n1 += 1;
        }
    }
    let mp = sp / np.max(1) as f64;
    let mn = sn / nn.max(1) as f64;
    let r0 = (s0 / n0.max(1) as f64).sqrt();
    let r1 = (s1 / n1.max(1) as f64).sqrt();
    let mut summary = vec![format!(
        "residual RMS near zero velocity {r0:.2} N, elsewhere {r1:.2} N"
    )];
    summary.push(format!(
        "mean residual {mp:+.2} N moving forward, {mn:+.2} N moving back"
    ));
    Ok(AxisDiagnosis {
        verdict: v,
        top_effect: (v == Verdict::Explained).then(|| ranked[0].effect),
        gap_before_percent: b.validation_percent,
        gap_after_percent: ranked
            .first()
            .map_or(b.validation_percent, |r| r.gap_after_percent),
        fit_before_percent: b.fit_percent,
        baseline_model: baseline.name().into(),
        baseline_parameters: parameter_values(
            b.names
                .iter()
                .zip(&b.theta)
                .zip(&b.std)
                .map(|((n, v), s)| (n.clone(), *v, *s))
                .collect(),
        ),
        ranked_effects: ranked,
        located: AxisLocated {
            mean_residual_positive_velocity_n: mp,
            mean_residual_negative_velocity_n: mn,
            rms_residual_near_zero_velocity_n: r0,
            rms_residual_elsewhere_n: r1,
            summary,
        },
        equations: pf.force.len(),
        rule: format!(
            "{} (floor 0: the time-domain path has no repeated periods to estimate the noise from)",
            super::RULE
        ),
    })
}
