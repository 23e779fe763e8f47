//! The equations of an identification, accumulated step by step in constant memory: what the
//! live identifier keeps (and persists) instead of samples, and what the offline path stacks
//! its steps into, so that both give the same theta from the same steps.

use serde::{Deserialize, Serialize};

use super::quality::{FitQuality, QualitySums};
use super::{Identification, IdentifyError, IdentifyWarning, Method, Parameter, StepEquations};
use crate::lstsq::{QrAccumulator, WARN_CONDITION_NUMBER};
use crate::model::Model;
use crate::recipe::Setup;

/// At most this many step notes are kept (the rest are counted), so that memory stays flat.
const MAX_NOTES: usize = 64;

/// The accumulated equations of one model and method.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EquationAccumulator {
    /// What the equations belong to; a state is only resumed for the same model and method.
    pub model: String,
    pub method: String,
    pub parameter_names: Vec<String>,
    qr: QrAccumulator,
    /// Sum over steps of each term's mean square over the step's cycle (for the r values).
    term_ms_sum: Vec<f64>,
    /// Steps added, including those that gave no equations.
    blocks: usize,
    independent_equations: f64,
    /// Steps that gave equations, in the order added.
    steps_used: Vec<usize>,
    notes: Vec<String>,
    notes_dropped: usize,
    /// Steps' worth of weight taken away by [`EquationAccumulator::forget`] (0 in the
    /// converged mode, and in states saved before tracking existed).
    #[serde(default)]
    forgotten_blocks: f64,
    /// The residual sums by band of harmonics, for the fit's quality against the noise
    /// (empty in states saved before they existed).
    #[serde(default)]
    quality: QualitySums,
}

impl EquationAccumulator {
    /// The accumulator of `model`'s equations by `method`, with the parameters `setup` adds
    /// (an element test's unknown moving mass) after the model's.
    pub fn new(model: &Model, setup: &Setup, method: Method) -> EquationAccumulator {
        let mut parameter_names = model.symbols();
        parameter_names.extend(setup.extra_parameters().iter().map(ToString::to_string));
        let p = parameter_names.len();
        EquationAccumulator {
            model: model.name.clone(),
            method: method.name(),
            parameter_names,
            qr: QrAccumulator::new(p),
            term_ms_sum: vec![0.0; p],
            blocks: 0,
            independent_equations: 0.0,
            steps_used: Vec::new(),
            notes: Vec::new(),
            notes_dropped: 0,
            forgotten_blocks: 0.0,
            quality: QualitySums::default(),
        }
    }

    /// This (empty) accumulator with one more parameter after the others: the coefficient of
    /// a column the blocks carry last that is no term of the model (a hysteresis state along a
    /// record's measured motion, in the diagnosis).
    pub fn with_state_parameter(mut self, name: &str) -> EquationAccumulator {
        debug_assert_eq!(self.blocks, 0, "parameters are added before any equations");
        self.parameter_names.push(name.to_string());
        let p = self.parameter_names.len();
        self.qr = QrAccumulator::new(p);
        self.term_ms_sum = vec![0.0; p];
        self
    }

    /// Weights every step so far by `factor` (0 < factor <= 1) against the steps added later:
    /// exponential forgetting, for tracking parameters that drift (a damper that heats up).
    /// Called before each [`add`](Self::add), the equations of the step `a` steps back weigh
    /// factor^a; the window's mean age is factor / (1 - factor) steps, the lag of a linear
    /// drift's estimate. A factor of 1 keeps the converged behaviour.
    pub fn forget(&mut self, factor: f64) {
        if factor >= 1.0 {
            return;
        }
        self.qr.forget(factor);
        self.quality.forget(factor);
        self.term_ms_sum.iter_mut().for_each(|s| *s *= factor);
        self.independent_equations *= factor;
        self.forgotten_blocks += (1.0 - factor) * (self.blocks as f64 - self.forgotten_blocks);
    }

    /// The equations as they would be with the step in progress, `blk`, added after forgetting
    /// by `factor`, leaving these as they are: a provisional step is solved this way, and the
    /// next provisional block or the step's final one replaces it (it is never added twice).
    pub fn with_provisional(
        &self,
        factor: f64,
        blk: &StepEquations,
    ) -> Result<EquationAccumulator, IdentifyError> {
        let mut acc = self.clone();
        acc.forget(factor);
        acc.add(blk)?;
        Ok(acc)
    }

    /// Whether this state holds equations of `model` by `method` (the model's parameters
    /// first, then any its setup added).
    pub fn is_for(&self, model: &Model, method: Method) -> bool {
        self.model == model.name
            && self.method == method.name()
            && self.parameter_names.starts_with(&model.symbols())
    }

    /// Steps added so far (with or without equations).
    pub fn steps_added(&self) -> usize {
        self.blocks
    }

    pub fn steps_used(&self) -> &[usize] {
        &self.steps_used
    }

    /// Real equations so far.
    pub fn equations(&self) -> usize {
        self.qr.rows()
    }

    /// Adds one step's block of equations.
    pub fn add(&mut self, blk: &StepEquations) -> Result<(), IdentifyError> {
        self.qr.add_rows(&blk.a, &blk.b)?;
        self.quality.add(blk);
        for (s, t) in self.term_ms_sum.iter_mut().zip(&blk.term_rms) {
            *s += t * t;
        }
        self.blocks += 1;
        self.independent_equations += blk.independent_equations;
        // A sweep record gives one block per window, all with the record's step.
        if blk.a.nrows() > 0 && self.steps_used.last() != Some(&blk.step) {
            self.steps_used.push(blk.step);
        }
        for n in &blk.notes {
            if self.notes.len() < MAX_NOTES {
                self.notes.push(n.clone());
            } else {
                self.notes_dropped += 1;
            }
        }
        Ok(())
    }

    /// Solves the equations so far.
    pub fn solve(&self) -> Result<Identification, IdentifyError> {
        self.solve_with_flags().map(|(id, _)| id)
    }

    /// Solves the equations so far, with the warnings code acts on as flags (in the order
    /// their texts appear in the identification's `warnings`).
    pub fn solve_with_flags(
        &self,
    ) -> Result<(Identification, Vec<IdentifyWarning>), IdentifyError> {
        if self.blocks == 0 {
            return Err(IdentifyError::NoSteps);
        }
        let p = self.parameter_names.len();
        let independent = self.independent_equations;
        let names = &self.parameter_names;
        let rows_weight = self.qr.effective_rows();
        let variance_scale = if independent > p as f64 {
            ((rows_weight - p as f64).max(0.0) / (independent - p as f64)).max(1.0)
        } else {
            1.0
        };
        let sol = self.qr.solve(names, variance_scale)?;
        let std = sol.std();
        // r: each term's share of the RMS transmitted force over the fitting data.
        let contrib: Vec<f64> = (0..p)
            .map(|i| {
                let blocks = self.blocks as f64 - self.forgotten_blocks;
                (sol.theta[i] * (self.term_ms_sum[i] / blocks).sqrt()).abs()
            })
            .collect();
        let total: f64 = contrib.iter().sum();
        let mut warnings = self.notes.clone();
        if self.notes_dropped > 0 {
            warnings.push(format!("... and {} more step notes", self.notes_dropped));
        }
        warnings.extend(sol.warnings.iter().cloned());
        let mut flags = Vec::new();
        // The solver's only warning is this one, given under the same test.
        if sol.condition_number > WARN_CONDITION_NUMBER {
            flags.push(IdentifyWarning::BadlyConditioned {
                condition_number: sol.condition_number,
                text: sol.warnings.join("; "),
            });
        }
        if (independent as usize) < 2 * p {
            let few = IdentifyWarning::FewEquations {
                independent,
                parameters: p,
            };
            warnings.push(few.to_string());
            flags.push(few);
        }
        let fit_quality = self.quality.quality(&sol.theta);
        if let Some(wrong) = fit_quality.as_ref().and_then(FitQuality::warning) {
            warnings.push(wrong.to_string());
            flags.push(wrong);
        }
        let id = Identification {
            model: self.model.clone(),
            method: self.method.clone(),
            parameters: names
                .iter()
                .zip(&sol.theta)
                .zip(&std)
                .map(|((n, v), s)| Parameter {
                    name: n.clone(),
                    value: *v,
                    std: *s,
                })
                .collect(),
            covariance: (0..p)
                .map(|i| (0..p).map(|j| sol.covariance[(i, j)]).collect())
                .collect(),
            condition_number: sol.condition_number,
            equations: sol.equations,
            r: names
                .iter()
                .zip(&contrib)
                .map(|(n, c)| (n.clone(), 100.0 * c / total.max(f64::MIN_POSITIVE)))
                .collect(),
            residual_rms: sol.residual_rms,
            steps_used: self.steps_used.clone(),
            fit_quality,
            misfit_noise_std: None,
            warnings,
        };
        Ok((id, flags))
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{DMatrix, DVector};

    use super::*;
    use crate::model::ModelOptions;

    fn block(step: usize, a: DMatrix<f64>, b: DVector<f64>, independent: f64) -> StepEquations {
        StepEquations {
            step,
            a,
            b,
            independent_equations: independent,
            term_rms: vec![1.0; 2],
            notes: vec![],
            row_noise: vec![],
            form_variance: 0.0,
        }
    }

    /// The flags are what the warnings' texts say, in the same order.
    #[test]
    fn warning_flags_match_the_warning_texts() {
        let model = Model::by_name("linear", &ModelOptions::default()).unwrap();
        assert_eq!(model.terms.len(), 2);
        let mut acc = EquationAccumulator::new(
            &model,
            &Setup::BaseExcited { mass_kg: 1.0 },
            Method::FdMulti,
        );
        // Well conditioned and plenty of equations: no flags.
        let a = DMatrix::from_row_slice(4, 2, &[1.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0, -1.0]);
        let b = DVector::from_column_slice(&[1.0, 2.0, 3.1, -0.9]);
        acc.add(&block(0, a, b, 4.0)).unwrap();
        let (id, flags) = acc.solve_with_flags().unwrap();
        assert!(flags.is_empty(), "{flags:?}");
        assert!(id.warnings.is_empty(), "{:?}", id.warnings);

        // Two nearly parallel columns and only three equations: both flags.
        let mut acc = EquationAccumulator::new(
            &model,
            &Setup::BaseExcited { mass_kg: 1.0 },
            Method::FdMulti,
        );
        let a = DMatrix::from_row_slice(3, 2, &[1.0, 1.0, 2.0, 2.0 + 1e-8, 3.0, 3.0]);
        let b = DVector::from_column_slice(&[1.0, 2.0, 3.0]);
        acc.add(&block(0, a, b, 3.0)).unwrap();
        let (id, flags) = acc.solve_with_flags().unwrap();
        assert!(matches!(
            flags.as_slice(),
            [
                IdentifyWarning::BadlyConditioned { .. },
                IdentifyWarning::FewEquations { parameters: 2, .. }
            ]
        ));
        let texts: Vec<String> = flags.iter().map(ToString::to_string).collect();
        assert_eq!(id.warnings, texts);
        assert!(texts[0].starts_with("badly conditioned"), "{}", texts[0]);
        assert_eq!(
            texts[1],
            "few equations: 3 independent real equations for 2 parameters"
        );
        assert_eq!(acc.solve().unwrap().warnings, id.warnings);
    }
}
