//! Fitting a baseline plus a candidate structure to the step cycles (weighted least squares on
//! the rebuilt periods), leave-one-step-out cross-validation, and the fitted element that the
//! rig simulator can run.

use std::sync::Arc;

use nalgebra::{DMatrix, DVector};

use num_complex::Complex64;

use super::cycles::{StepCycle, harmonics_of, synthesize};
use super::effects::{Structure, Transform};
pub use super::fitted_element::FittedElement;
use super::{drift, series};
use crate::basis::Term;
use crate::lstsq::{self, LstsqError};
use crate::model::Model;

/// Grid points with |x'| below this fraction of the step's peak |x'| are left out of fits and
/// scores, for every model alike: near a reversal a friction force is set-valued (stick) and
/// the rebuilt waveforms ring (a jump rebuilt from ~15 harmonics), so no model can be judged
/// there. The displacement extremes lose at most 0.5 % of the amplitude.
pub const REVERSAL_BAND: f64 = 0.1;

/// A fitted baseline + structure.
#[derive(Debug, Clone)]
pub struct Fitted {
    pub structure: Structure,
    pub terms: Vec<Arc<dyn Term>>,
    /// Symbols of the coefficients: the terms', then "alpha" for hysteresis.
    pub names: Vec<String>,
    pub theta: Vec<f64>,
    pub std: Vec<f64>,
    /// Number of baseline coefficients (the first ones).
    pub baseline_parameters: usize,
    /// 100 * weighted RMS residual / weighted RMS force over the fitted points [%].
    pub residual_percent: f64,
}

pub(super) fn columns(terms: &[Arc<dyn Term>], s: &Structure, c: &StepCycle) -> Vec<Vec<f64>> {
    let mut cols: Vec<Vec<f64>> = terms
        .iter()
        .map(|t| {
            c.displacement_m
                .iter()
                .zip(&c.velocity_mps)
                .map(|(x, v)| t.eval(*x, *v))
                .collect()
        })
        .collect();
    // Series compliance replaces the damper's column by the velocity through the spring's
    // low-pass (linear in c for a given relaxation time); drift adds t times that column.
    let damper = damper_index(terms);
    if let (Some(tau), Some(i)) = (s.series_relaxation_s, damper) {
        cols[i] = series::damper_column(&c.velocity_mps, c.frequency_hz, tau);
    }
    let drift_col = match (s.drift, damper) {
        (true, Some(i)) => Some(cols[i].iter().map(|v| v * c.time_s).collect()),
        _ => None,
    };
    if let Some(law) = &s.hysteresis {
        cols.push(
            c.hysteresis_states
                .steady_cycle(&c.velocity_mps, 1.0 / c.frequency_hz, law)
                .to_vec(),
        );
    }
    cols.extend(drift_col);
    // The measured force is rebuilt from harmonics 0..=N only; a model force is compared in
    // the same band (a jump rebuilt from N harmonics rings, and so must the prediction), and
    // through the same sensor low-pass, if the cycle's state had one undone.
    cols.iter()
        .map(|col| as_measured(col, c.harmonics, c.force_response.as_deref()))
        .collect()
}

/// Index of the baseline's viscous damper term among `terms`.
fn damper_index(terms: &[Arc<dyn Term>]) -> Option<usize> {
    terms
        .iter()
        .position(|t| t.symbol() == series::DAMPER_SYMBOL)
}

/// `h` (one period on a uniform grid) keeping only harmonics 0..=n, each multiplied by its
/// factor of `response` if given (what the measured force went through).
fn as_measured(h: &[f64], n: usize, response: Option<&[Complex64]>) -> Vec<f64> {
    match response {
        None if n + 1 >= h.len() / 2 => h.to_vec(),
        None => synthesize(&harmonics_of(h, n), h.len(), |_| Complex64::new(1.0, 0.0)),
        Some(r) => synthesize(&harmonics_of(h, n), h.len(), |k| {
            r.get(k).copied().unwrap_or(Complex64::new(0.0, 0.0))
        }),
    }
}

fn kept(c: &StepCycle) -> Vec<bool> {
    if c.stuck {
        return vec![false; c.velocity_mps.len()];
    }
    let vmax = c.velocity_mps.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    c.velocity_mps
        .iter()
        .map(|v| v.abs() >= REVERSAL_BAND * vmax)
        .collect()
}

/// The element terms of baseline + structure.
pub fn all_terms(baseline: &Model, s: &Structure) -> Vec<Arc<dyn Term>> {
    let mut t = baseline.terms.clone();
    t.extend(s.terms.iter().cloned());
    t
}

/// Fits baseline + structure on `cycles` (skipping the step at index `skip`).
pub fn fit(
    baseline: &Model,
    s: &Structure,
    cycles: &[StepCycle],
    skip: Option<usize>,
) -> Result<Fitted, LstsqError> {
    let terms = all_terms(baseline, s);
    let cols: Vec<Option<Vec<Vec<f64>>>> = cycles
        .iter()
        .enumerate()
        .map(|(k, c)| (Some(k) != skip && !c.stuck).then(|| columns(&terms, s, c)))
        .collect();
    fit_on_columns(baseline, s, terms, cycles, &cols, skip)
}

/// [`fit`] with each cycle's design columns given (`None` for a stuck cycle): the
/// cross-validation's fits share them (computing them, a Bouc-Wen cycle among them, was most of
/// the phasor search before).
pub(super) fn fit_on_columns(
    baseline: &Model,
    s: &Structure,
    terms: Vec<Arc<dyn Term>>,
    cycles: &[StepCycle],
    columns_of: &[Option<Vec<Vec<f64>>>],
    skip: Option<usize>,
) -> Result<Fitted, LstsqError> {
    let names = parameter_names(&terms, s);
    let p = names.len();
    // The kept points of each fitted cycle, then the weighted rows straight into A and b.
    let fitted: Vec<_> = cycles
        .iter()
        .zip(columns_of)
        .enumerate()
        .filter(|(k, (c, _))| Some(*k) != skip && !c.stuck)
        .map(|(_, (c, cols))| {
            (
                c,
                cols.as_ref().expect("columns of every fitted cycle"),
                kept(c),
            )
        })
        .collect();
    let n_rows = fitted
        .iter()
        .map(|(_, _, keep)| keep.iter().filter(|k| **k).count())
        .sum();
    let mut a = DMatrix::zeros(n_rows, p);
    let mut b = DVector::zeros(n_rows);
    let mut independent = 0.0;
    let mut r = 0;
    for (c, cols, keep) in &fitted {
        r = write_weighted_rows(c, cols, keep, &mut a, &mut b, r);
        independent += (2 * c.harmonics + 1) as f64;
    }
    // Grid points are not independent equations: 2N+1 harmonics made each period.
    let scale = if independent > p as f64 {
        ((n_rows as f64 - p as f64) / (independent - p as f64)).max(1.0)
    } else {
        1.0
    };
    let sol = lstsq::solve(&a, &b, &names, scale)?;
    let res = &a * DVector::from_vec(sol.theta.clone()) - &b;
    let residual_percent =
        100.0 * (res.norm_squared() / b.norm_squared().max(f64::MIN_POSITIVE)).sqrt();
    Ok(Fitted {
        structure: s.clone(),
        std: sol.std(),
        theta: sol.theta,
        names,
        terms,
        baseline_parameters: baseline.terms.len(),
        residual_percent,
    })
}

/// Symbols of the coefficients of baseline + structure: the terms', then "alpha" for
/// hysteresis, then the drift rate.
pub(super) fn parameter_names(terms: &[Arc<dyn Term>], s: &Structure) -> Vec<String> {
    let mut names: Vec<String> = terms.iter().map(|t| t.symbol()).collect();
    if s.hysteresis.is_some() {
        names.push("alpha".into());
    }
    if s.drift && damper_index(terms).is_some() {
        names.push(drift::RATE_SYMBOL.into());
    }
    names
}

/// Writes cycle `c`'s rows at its kept points (`keep`), weighted by its force noise, into `a`
/// and `b` from row `r`; returns the row after them.
fn write_weighted_rows(
    c: &StepCycle,
    cols: &[Vec<f64>],
    keep: &[bool],
    a: &mut DMatrix<f64>,
    b: &mut DVector<f64>,
    mut r: usize,
) -> usize {
    let wt = 1.0 / c.force_noise_n;
    for (i, _) in keep.iter().enumerate().filter(|(_, k)| **k) {
        for (j, col) in cols.iter().enumerate() {
            a[(r, j)] = col[i] * wt;
        }
        b[r] = c.force_n[i] * wt;
        r += 1;
    }
    r
}

/// Cycle `c`'s weighted rows (as [`fit_on_columns`] writes them) as their QR factor, for fits
/// that leave cycles out ([`super::design::Design::cross_validated_percent`]).
pub(super) fn cycle_factor(
    c: &StepCycle,
    cols: &[Vec<f64>],
) -> Result<lstsq::QrAccumulator, LstsqError> {
    let keep = kept(c);
    let n = keep.iter().filter(|k| **k).count();
    let mut a = DMatrix::zeros(n, cols.len());
    let mut b = DVector::zeros(n);
    write_weighted_rows(c, cols, &keep, &mut a, &mut b, 0);
    let mut acc = lstsq::QrAccumulator::new(cols.len());
    acc.add_rows(&a, &b)?;
    Ok(acc)
}

/// The force of coefficients `theta` on design columns `cols`.
pub(super) fn combination(cols: &[Vec<f64>], theta: &[f64]) -> Vec<f64> {
    let n = cols.first().map_or(0, Vec::len);
    (0..n)
        .map(|i| cols.iter().zip(theta).map(|(col, th)| col[i] * th).sum())
        .collect()
}

impl Fitted {
    /// The model's element force over the cycle.
    pub fn predict(&self, c: &StepCycle) -> Vec<f64> {
        self.predict_on_columns(c, &columns(&self.terms, &self.structure, c))
    }

    /// [`Fitted::predict`] with the cycle's design columns given.
    pub(super) fn predict_on_columns(&self, c: &StepCycle, cols: &[Vec<f64>]) -> Vec<f64> {
        debug_assert!(cols.iter().all(|col| col.len() == c.force_n.len()));
        combination(cols, &self.theta)
    }

    /// The force the structure adds (everything but the baseline terms) over the cycle.
    pub fn added_force(&self, c: &StepCycle) -> Vec<f64> {
        let cols = columns(&self.terms, &self.structure, c);
        (0..c.force_n.len())
            .map(|i| {
                cols.iter()
                    .zip(&self.theta)
                    .skip(self.baseline_parameters)
                    .map(|(col, th)| col[i] * th)
                    .sum()
            })
            .collect()
    }

    /// The element the simulators can run, for a record that starts at the start of the run.
    pub fn element(&self) -> FittedElement {
        self.element_at(0.0)
    }

    /// The element the simulators can run, for a record that starts `start_time_s` after the
    /// start of the run (a drifting damper has the damping of its time).
    pub fn element_at(&self, start_time_s: f64) -> FittedElement {
        let n = self.terms.len();
        let damper = damper_index(&self.terms);
        let series = self
            .structure
            .series_relaxation_s
            .and_then(|tau| damper.map(|i| (i, tau)));
        FittedElement::new(
            self.terms.clone(),
            self.theta[..n].to_vec(),
            self.structure.hysteresis.map(|law| (self.theta[n], law)),
            series,
            match (self.structure.drift, damper) {
                (true, Some(i)) => self.theta.last().map(|rate| (i, *rate, start_time_s)),
                _ => None,
            },
        )
    }

    pub fn transform(&self) -> Transform {
        self.structure.transform
    }

    /// The fitted coefficient of the term or parameter named `symbol` (None when the fit has
    /// none).
    pub fn coefficient(&self, symbol: &str) -> Option<f64> {
        self.names
            .iter()
            .position(|n| n == symbol)
            .map(|i| self.theta[i])
    }

    /// (name, value, std) of the baseline's coefficients refitted beside the structure: with the
    /// added parameters, the whole model with the effect.
    pub fn refitted_baseline(&self) -> Vec<(String, f64, f64)> {
        self.names
            .iter()
            .zip(&self.theta)
            .zip(&self.std)
            .take(self.baseline_parameters)
            .map(|((n, v), s)| (n.clone(), *v, *s))
            .collect()
    }

    /// (name, value, std) of the parameters the structure added.
    pub fn added_parameters(&self) -> Vec<(String, f64, f64)> {
        let mut out: Vec<(String, f64, f64)> = self
            .names
            .iter()
            .zip(&self.theta)
            .zip(&self.std)
            .skip(self.baseline_parameters)
            .map(|((n, v), s)| (n.clone(), *v, *s))
            .collect();
        // Searched values have no least-squares std; the search grid sets their resolution.
        out.extend(
            self.structure
                .searched
                .iter()
                .map(|(n, v)| (n.clone(), *v, f64::NAN)),
        );
        // The shapes of the damper effects in the units they are reported in.
        if let Some(ks) = series::stiffness_n_per_m(self) {
            out.push(("series_stiffness_n_per_m".into(), ks, f64::NAN));
        }
        if let Some((_, r)) = drift::rate(self) {
            out.push(("drift_per_s".into(), r, f64::NAN));
        }
        if self.structure.transform.delay_s != 0.0 {
            out.push(("delay_s".into(), self.structure.transform.delay_s, f64::NAN));
        }
        out
    }
}

/// Weighted residual of `fitted` on one cycle over the kept points: (sum w^2 r^2, sum w^2 g^2).
pub fn residual_sums(fitted: &Fitted, c: &StepCycle) -> (f64, f64) {
    residual_sums_of(&fitted.predict(c), c)
}

/// [`residual_sums`] of the prediction `pred` of cycle `c`.
pub(super) fn residual_sums_of(pred: &[f64], c: &StepCycle) -> (f64, f64) {
    let wt2 = c.force_noise_n.powi(-2);
    let mut num = 0.0;
    let mut den = 0.0;
    for ((p, g), k) in pred.iter().zip(&c.force_n).zip(kept(c)) {
        if k {
            num += wt2 * (g - p).powi(2);
            den += wt2 * g * g;
        }
    }
    (num, den)
}

/// Leave-one-step-out cross-validation: each step predicted by a fit to the others;
/// 100 * sqrt(sum of weighted squared residuals / sum of weighted squared forces) [%].
pub fn cross_validated_percent(
    baseline: &Model,
    s: &Structure,
    cycles: &[StepCycle],
) -> Option<f64> {
    // Each cycle's columns once: every fit but one uses them, and the left-out one predicts
    // its cycle with them.
    super::design::Design::new(baseline, s, cycles).cross_validated_percent()
}

/// 100 sqrt(num / den) [%]: a residual's size relative to the data's, from their sums of
/// squares (a zero denominator taken as the smallest positive number).
pub(crate) fn root_ratio_percent(num: f64, den: f64) -> f64 {
    100.0 * (num / den.max(f64::MIN_POSITIVE)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::element::Element;
    use crate::signal::bouc_wen::{self, HysteresisLaw};

    #[test]
    fn as_measured_applies_the_response_per_harmonic() {
        // cos(3 w t) through 1 / (1 + j 3 f / fc): gain 1 / sqrt(1 + (3 f / fc)^2), phase
        // -atan(3 f / fc); harmonics above n are dropped.
        let l = 256;
        let (f, fc) = (2.0, 5.0);
        let t = |i: usize| std::f64::consts::TAU * i as f64 / l as f64;
        let h: Vec<f64> = (0..l)
            .map(|i| (3.0 * t(i)).cos() + 0.5 * (9.0 * t(i)).cos())
            .collect();
        let response: Vec<Complex64> = (0..=5)
            .map(|k| Complex64::new(1.0, k as f64 * f / fc).inv())
            .collect();
        let y = as_measured(&h, 5, Some(&response));
        let r = 3.0 * f / fc;
        let (gain, phase) = (1.0 / (1.0 + r * r).sqrt(), -r.atan());
        for (i, yi) in y.iter().enumerate() {
            let want = gain * (3.0 * t(i) + phase).cos();
            assert!((yi - want).abs() < 1e-12, "{i}: {yi} vs {want}");
        }
        // Without a low-pass only the band limit acts.
        let y = as_measured(&h, 5, None);
        for (i, yi) in y.iter().enumerate() {
            assert!((yi - (3.0 * t(i)).cos()).abs() < 1e-12);
        }
    }

    /// Sine cycles of a coulomb element with Bouc-Wen hysteresis (yield 2 mm) and a
    /// deterministic misfit; the third cycle stuck.
    fn hysteretic_cycles() -> Vec<StepCycle> {
        let l = 128;
        (0..5)
            .map(|k| {
                let f_hz = 1.5 + 0.5 * k as f64;
                let amp = 0.006 / (1.0 + 0.3 * k as f64);
                let w = std::f64::consts::TAU * f_hz;
                let ph = |i: usize| std::f64::consts::TAU * i as f64 / l as f64;
                let x: Vec<f64> = (0..l).map(|i| amp * ph(i).cos()).collect();
                let v: Vec<f64> = (0..l).map(|i| -amp * w * ph(i).sin()).collect();
                let z = bouc_wen::steady_cycle(&v, 1.0 / f_hz, &HysteresisLaw::yield_law(0.002));
                let force: Vec<f64> = (0..l)
                    .map(|i| {
                        6000.0 * x[i]
                            + 180.0 * v[i]
                            + 12.0 * v[i].signum()
                            + 900.0 * z[i]
                            + 0.3 * (3.0 * ph(i) + k as f64).sin()
                    })
                    .collect();
                StepCycle {
                    step: k,
                    frequency_hz: f_hz,
                    time_s: 10.0 * k as f64,
                    amplitude_m: amp,
                    displacement_m: x,
                    velocity_mps: v,
                    force_n: force,
                    force_noise_n: 0.1,
                    harmonics: l / 2,
                    force_response: None,
                    force_harmonic_noise_n: vec![0.1; l / 2 + 1],
                    stuck: k == 2,
                    hysteresis_states: Default::default(),
                }
            })
            .collect()
    }

    #[test]
    fn cross_validation_with_shared_columns_is_the_leave_one_out_of_fit() {
        let baseline = Model::by_name("coulomb", &Default::default()).unwrap();
        let s = Structure {
            hysteresis: Some(HysteresisLaw::yield_law(0.002)),
            ..Structure::default()
        };
        let cycles = hysteretic_cycles();
        let (mut num, mut den) = (0.0, 0.0);
        for k in 0..cycles.len() {
            let f = fit(&baseline, &s, &cycles, Some(k)).unwrap();
            let (n, d) = residual_sums(&f, &cycles[k]);
            num += n;
            den += d;
        }
        let by_fit = 100.0 * (num / den).sqrt();
        // The cross-validation merges each cycle's factored rows instead of refitting the
        // others' rows: the same figure to rounding.
        let cv = cross_validated_percent(&baseline, &s, &cycles).unwrap();
        assert!((cv / by_fit - 1.0).abs() < 1e-12, "{cv} vs {by_fit}");
        assert!(cv > 0.0 && cv < 5.0, "{cv}");
        // The search's fit on every step from the same shared columns is `fit`'s, to the bit.
        let design = super::super::design::Design::new(&baseline, &s, &cycles);
        let (shared, own) = (
            design.fit().unwrap(),
            fit(&baseline, &s, &cycles, None).unwrap(),
        );
        let bits = |f: &Fitted| {
            let mut b: Vec<u64> = f.theta.iter().chain(&f.std).map(|v| v.to_bits()).collect();
            b.push(f.residual_percent.to_bits());
            b
        };
        assert_eq!(bits(&shared), bits(&own));
        assert_eq!(
            design.cross_validated_percent().map(f64::to_bits),
            Some(cv.to_bits())
        );
    }

    #[test]
    fn the_fitted_element_force_leaves_out_the_friction_term() {
        let baseline = Model::by_name("coulomb", &Default::default()).unwrap();
        let s = Structure {
            hysteresis: Some(HysteresisLaw::yield_law(0.002)),
            ..Structure::default()
        };
        let f = fit(&baseline, &s, &hysteretic_cycles(), None).unwrap();
        let e = f.element();
        let (x, v, z) = (0.003, -0.05, 0.0012);
        let want = f.theta[0] * x + f.theta[1] * v + f.theta[3] * z;
        let got = e.smooth_force(x, v, &[z]);
        assert!((got - want).abs() <= 1e-12 * want.abs(), "{got} vs {want}");
        assert!((e.friction().unwrap().kinetic_n - f.theta[2]).abs() < 1e-12);
    }
}
