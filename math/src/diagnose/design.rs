//! A structure's design columns on the step cycles computed once for the fit on every step
//! and its leave-one-step-out cross-validation (the phasor search asks for both of every
//! structure it tries; a hysteresis structure's columns include a Bouc-Wen cycle, and each
//! column is band-limited to the measured harmonics).

use std::sync::Arc;

use super::cycles::StepCycle;
use super::effects::Structure;
use super::fit::{
    Fitted, all_terms, columns, fit_on_columns, residual_sums_of, root_ratio_percent,
};
use crate::basis::Term;
use crate::lstsq::LstsqError;
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

    /// [`super::fit::cross_validated_percent`].
    pub fn cross_validated_percent(&self) -> Option<f64> {
        let cycles = self.cycles;
        if cycles.len() < 3 {
            return None;
        }
        let (mut num, mut den) = (0.0, 0.0);
        for (k, c) in cycles.iter().enumerate() {
            let (b, s, terms) = (self.baseline, self.s, self.terms.clone());
            let f = fit_on_columns(b, s, terms, cycles, &self.cols, Some(k)).ok()?;
            // A stuck cycle keeps no point: it adds nothing to either sum.
            let Some(ck) = &self.cols[k] else { continue };
            let (n, d) = residual_sums_of(&f.predict_on_columns(c, ck), c);
            num += n;
            den += d;
        }
        Some(root_ratio_percent(num, den))
    }
}
