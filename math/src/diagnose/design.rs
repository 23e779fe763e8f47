//! A structure's design columns on the step cycles computed once for the fit on every step
//! and its leave-one-step-out cross-validation (the phasor search asks for both of every
//! structure it tries; a hysteresis structure's columns include a Bouc-Wen cycle, and each
//! column is band-limited to the measured harmonics).

use std::sync::Arc;

use super::cycles::StepCycle;
use super::effects::Structure;
use super::fit::{
    Fitted, all_terms, columns, combination, cycle_factor, fit_on_columns, parameter_names,
    residual_sums_of, root_ratio_percent,
};
use crate::basis::Term;
use crate::lstsq::{LstsqError, QrAccumulator};
use crate::model::Model;

/// Baseline + structure on `cycles` with each unstuck cycle's design columns computed once,
/// for the fit on every step ([`super::fit::fit`] with no skip) and its cross-validation
/// ([`super::fit::cross_validated_percent`]), which the search asks for one after the other.
pub struct Design<'a> {
    baseline: &'a Model,
    s: &'a Structure,
    cycles: &'a [StepCycle],
    terms: Vec<Arc<dyn Term>>,
    cols: Vec<Option<Vec<Vec<f64>>>>,
}

impl<'a> Design<'a> {
    pub fn new(baseline: &'a Model, s: &'a Structure, cycles: &'a [StepCycle]) -> Design<'a> {
        let terms = all_terms(baseline, s);
        let cols = cycles
            .iter()
            .map(|c| (!c.stuck).then(|| columns(&terms, s, c)))
            .collect();
        Design {
            baseline,
            s,
            cycles,
            terms,
            cols,
        }
    }

    /// [`super::fit::fit`] on every step.
    pub fn fit(&self) -> Result<Fitted, LstsqError> {
        let (b, s, terms) = (self.baseline, self.s, self.terms.clone());
        fit_on_columns(b, s, terms, self.cycles, &self.cols, None)
    }

    /// [`super::fit::cross_validated_percent`]: each unstuck cycle's weighted rows factored
    /// once, and each leave-one-out fit the merge of the other cycles' factors (to rounding
    /// the fit of their rows; factoring every other cycle's rows again for each left-out one
    /// was most of a cross-validation).
    pub fn cross_validated_percent(&self) -> Option<f64> {
        let cycles = self.cycles;
        if cycles.len() < 3 {
            return None;
        }
        let names = parameter_names(&self.terms, self.s);
        let factors: Vec<Option<QrAccumulator>> = cycles
            .iter()
            .zip(&self.cols)
            .map(|(c, cols)| cols.as_ref().map(|cols| cycle_factor(c, cols)).transpose())
            .collect::<Result<_, _>>()
            .ok()?;
        let (mut num, mut den) = (0.0, 0.0);
        for (k, c) in cycles.iter().enumerate() {
            let mut others = QrAccumulator::new(names.len());
            for (j, f) in factors.iter().enumerate() {
                if let (true, Some(f)) = (j != k, f) {
                    others.merge(f).ok()?;
                }
            }
            let theta = others.solve(&names, 1.0).ok()?.theta;
            // A stuck cycle keeps no point: it adds nothing to either sum.
            let Some(ck) = &self.cols[k] else { continue };
            let (n, d) = residual_sums_of(&combination(ck, &theta), c);
            num += n;
            den += d;
        }
        Some(root_ratio_percent(num, den))
    }
}
