//! The baselines and the candidates' regressors evaluated on a prepared record, and their
//! least-squares fits on the decimated equations.

use std::sync::Arc;

use serde::Serialize;

use super::AxisError;
use super::preprocess::{AxisRecord, Motion, Prepared, TimeDomainOptions, check_equations};
use crate::basis::{Constant, SignVelocity, Term, Velocity};
use crate::lstsq;
use crate::model::Model;
use crate::signal::bouc_wen;

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
    /// The baseline's force law as a model of the effect library (its inertia column M q''
    /// aside), for what the candidates ask of it (`effects::baseline_has`).
    pub(super) fn model(self) -> Model {
        let terms: Vec<Arc<dyn Term>> = match self {
            AxisBaseline::EmpsViscous => vec![Arc::new(Velocity), Arc::new(Constant)],
            AxisBaseline::EmpsCoulomb => vec![
                Arc::new(Velocity),
                Arc::new(SignVelocity),
                Arc::new(Constant),
            ],
        };
        Model::new(self.name(), terms)
    }

    /// The baseline's columns: the inertia, then its force law's terms.
    pub(super) fn columns(self) -> Vec<Column> {
        let mut cols = vec![Column::Acceleration];
        cols.extend(self.model().terms.into_iter().map(Column::Term));
        cols
    }
}

/// A named regressor evaluated on the motion: the inertia, a term of the effect library
/// (`basis`, evaluated at q - mean(q) and q'), or the Bouc-Wen state of a yield displacement.
#[derive(Debug, Clone)]
pub(super) enum Column {
    Acceleration,
    Term(Arc<dyn Term>),
    BoucWen(f64),
}

impl Column {
    /// The symbol in EMPS's published names where the axis has one (M, Fv, Fc), else the
    /// library's.
    pub(super) fn symbol(&self) -> String {
        match self {
            Column::Acceleration => "m".into(),
            Column::Term(t) => match t.symbol().as_str() {
                "c" => "fv".into(),
                "fd" => "fc".into(),
                other => other.into(),
            },
            Column::BoucWen(_) => "alpha".into(),
        }
    }

    pub(super) fn full(&self, m: &Motion) -> Vec<f64> {
        match self {
            Column::Acceleration => m.qdd.clone(),
            Column::Term(t) => {
                m.q.iter()
                    .zip(&m.qd)
                    .map(|(q, v)| t.eval(q - m.q_mean, *v))
                    .collect()
            }
            Column::BoucWen(zy) => bouc_wen::integrate_record(&m.qd, 1.0 / m.fs, *zy),
        }
    }
}

/// The decimated columns of `cols` on a record.
fn design(m: &Motion, cols: &[Column]) -> Vec<Vec<f64>> {
    cols.iter().map(|c| m.decimate(&c.full(m))).collect()
}

fn predict(cols: &[Vec<f64>], theta: &[f64], rows: usize) -> Vec<f64> {
    (0..rows)
        .map(|i| cols.iter().zip(theta).map(|(c, th)| c[i] * th).sum())
        .collect()
}

/// 100 |y - prediction| / |y| [%].
pub(super) fn relative_error(y: &[f64], prediction: &[f64]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (t, p) in y.iter().zip(prediction) {
        num += (t - p).powi(2);
        den += t * t;
    }
    crate::diagnose::fit::root_ratio_percent(num, den)
}

/// Least squares of the decimated force on decimated columns.
fn solve(
    model: &str,
    cols: &[Vec<f64>],
    y: &[f64],
    names: &[String],
) -> Result<lstsq::Solution, AxisError> {
    let a = nalgebra::DMatrix::from_fn(y.len(), cols.len(), |r, c| cols[c][r]);
    let b = nalgebra::DVector::from_column_slice(y);
    lstsq::solve(&a, &b, names, 1.0).map_err(|source| AxisError::Lstsq {
        model: model.into(),
        source,
    })
}

/// A baseline fitted on one record (the EMPS reference fit is the `EmpsCoulomb` one).
#[derive(Debug, Clone, Serialize)]
pub struct AxisModelFit {
    pub baseline: AxisBaseline,
    /// m [kg], fv [N s/m], fc [N] (emps-coulomb only), offset [N].
    pub names: Vec<String>,
    pub theta: Vec<f64>,
    /// Least-squares standard deviations (white residual assumed), same order.
    pub std: Vec<f64>,
    /// Relative force error on the fitting record [%].
    pub relative_error_percent: f64,
    /// Decimated equations.
    pub equations: usize,
    #[serde(skip)]
    options: TimeDomainOptions,
}

impl AxisModelFit {
    /// Given parameters of a baseline (in the order of [`AxisModelFit::names`]), for scoring
    /// them on a record; the fit statistics are NaN.
    pub fn new(
        baseline: AxisBaseline,
        theta: Vec<f64>,
        options: &TimeDomainOptions,
    ) -> AxisModelFit {
        let names: Vec<String> = baseline.columns().iter().map(Column::symbol).collect();
        AxisModelFit {
            baseline,
            std: vec![f64::NAN; theta.len()],
            theta,
            names,
            relative_error_percent: f64::NAN,
            equations: 0,
            options: *options,
        }
    }

    /// The relative force error [%] of these parameters on another record, prepared the same
    /// way.
    pub fn relative_error_on(&self, record: &AxisRecord) -> Result<f64, AxisError> {
        let m = Motion::new(record, &self.options, "validation")?;
        check_equations(&m, "validation", self.theta.len())?;
        if self.theta.len() != self.names.len() {
            return Err(AxisError::BadOptions(format!(
                "{} parameters for the {} columns of {}",
                self.theta.len(),
                self.names.len(),
                self.baseline.name()
            )));
        }
        let cols = design(&m, &self.baseline.columns());
        let y = m.decimate(&m.force);
        Ok(relative_error(&y, &predict(&cols, &self.theta, y.len())))
    }
}

/// Fits a baseline on a record.
pub fn fit_axis_model(
    baseline: AxisBaseline,
    record: &AxisRecord,
    options: &TimeDomainOptions,
) -> Result<AxisModelFit, AxisError> {
    let m = Motion::new(record, options, "fitting")?;
    let cols = baseline.columns();
    check_equations(&m, "fitting", cols.len())?;
    let names: Vec<String> = cols.iter().map(Column::symbol).collect();
    let a = design(&m, &cols);
    let y = m.decimate(&m.force);
    let sol = solve(baseline.name(), &a, &y, &names)?;
    Ok(AxisModelFit {
        baseline,
        relative_error_percent: relative_error(&y, &predict(&a, &sol.theta, y.len())),
        equations: y.len(),
        std: sol.std(),
        theta: sol.theta,
        names,
        options: *options,
    })
}

pub(super) struct TdFit {
    pub(super) names: Vec<String>,
    pub(super) theta: Vec<f64>,
    pub(super) std: Vec<f64>,
    pub(super) fit_percent: f64,
    pub(super) validation_percent: f64,
    /// The model's force on the validation record (decimated).
    pub(super) validation_prediction: Vec<f64>,
}

pub(super) fn fit_and_score(
    model: &str,
    fit: &Prepared,
    val: &Prepared,
    cols: &[Column],
) -> Result<TdFit, AxisError> {
    let a = design(&fit.motion, cols);
    let names: Vec<String> = cols.iter().map(Column::symbol).collect();
    let sol = solve(model, &a, &fit.force, &names)?;
    let v = design(&val.motion, cols);
    let validation_prediction = predict(&v, &sol.theta, val.force.len());
    Ok(TdFit {
        fit_percent: relative_error(&fit.force, &predict(&a, &sol.theta, fit.force.len())),
        validation_percent: relative_error(&val.force, &validation_prediction),
        validation_prediction,
        std: sol.std(),
        theta: sol.theta,
        names,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_short_record_is_an_error_that_names_it() {
        let r = AxisRecord {
            sample_rate_hz: 1000.0,
            position_m: vec![0.0; 150],
            force_n: vec![0.0; 150],
        };
        let e = fit_axis_model(AxisBaseline::EmpsCoulomb, &r, &TimeDomainOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("fitting record has 150 samples"), "{e}");
    }
}
