//! The identification an output-error fit of records gives: its parameters, the standard
//! deviations from the sandwich covariance, and the misfit against the noise (in each compared
//! channel's unit where the noise cannot be measured).

use nalgebra::DMatrix;

use super::RecordsOutputError;
use super::SampledDrive;
use crate::identify::output_error::{FORM_MAY_BE_WRONG, FORM_MISFIT_VARIANCE, lm};
use crate::identify::{Identification, Method, Parameter};
use crate::measured_state::CUTOFF_MULTIPLE;
use crate::record::Channel;

impl RecordsOutputError<'_> {
    pub(super) fn identification(
        &self,
        start: &Identification,
        fit: &lm::Fit,
        cov: &DMatrix<f64>,
    ) -> Identification {
        let np = self.p_element();
        // Over the compared samples, a hysteresis state's priors left out (and a low-pass's
        // left-out start, whose rows are zeros).
        let data = &fit.residual[..self.data_rows()];
        let compared = self.compared_rows();
        let rms = (data.iter().map(|r| r * r).sum::<f64>() / compared.max(1) as f64).sqrt();
        let parameters: Vec<Parameter> = (0..np)
            .map(|i| Parameter {
                name: start.parameters[i].name.clone(),
                value: fit.p[i],
                std: cov[(i, i)].sqrt(),
            })
            .collect();
        let covariance = (0..np)
            .map(|i| (0..np).map(|j| cov[(i, j)]).collect())
            .collect();
        let mut warnings = start.warnings.clone();
        let (input, outputs) = match self.drive {
            SampledDrive::Force { .. } => ("force", "displacement"),
            SampledDrive::Base { .. } => (
                "base displacement",
                "mass acceleration and relative displacement",
            ),
        };
        let simulated = format!(
            "output error: the mass simulated under the measured {input} of {} record(s), each from its fitted initial state; {} samples",
            self.records.len(),
            compared
        );
        if !self.noise_unmeasured.is_empty() {
            let names: Vec<&str> = self.noise_unmeasured.iter().map(|c| c.name()).collect();
            warnings.push(format!(
                "{simulated}; RMS misfit {}: the noise of {} cannot be measured (the records hold no band above {CUTOFF_MULTIPLE} times their excitation's top frequency below the Nyquist frequency), so the misfit is not compared with noise; held-out records measure the fit",
                self.misfit_in_units(data),
                names.join(" and ")
            ));
        } else {
            warnings.push(format!("{simulated}, RMS misfit {rms:.3} noise std"));
        }
        if self.noise_unmeasured.is_empty() && rms * rms > FORM_MISFIT_VARIANCE {
            warnings.push(format!(
                "output error: the simulated model misses the measured {outputs} by {rms:.1} noise std (RMS); {FORM_MAY_BE_WRONG}"
            ));
        }
        let info = fit.information.clone();
        let sub = info.view((0, 0), (np, np)).into_owned();
        let sv = sub.singular_values();
        Identification {
            model: self.model.name.clone(),
            method: Method::OutputError.name(),
            parameters,
            covariance,
            condition_number: (sv.max() / sv.min()).sqrt(),
            equations: compared,
            r: start.r.clone(),
            residual_rms: rms,
            steps_used: self.records.iter().map(|r| r.step).collect(),
            fit_quality: None,
            misfit_noise_std: self.noise_unmeasured.is_empty().then_some(rms),
            warnings,
        }
    }

    /// Residual rows the fit compares: the data rows less a low-pass's left-out start of each
    /// record's channels ([`RecordsOutputError::filter_transient_samples`]).
    fn compared_rows(&self) -> usize {
        let left_out: usize = (0..self.records.len())
            .map(|k| self.filter_transient_samples(k) * self.compared[k].len())
            .sum();
        self.data_rows() - left_out
    }

    /// The RMS of `residual` (rows divided by each channel's noise std) in each compared
    /// channel's own unit: "relative_displacement_m 4.553e-4".
    fn misfit_in_units(&self, residual: &[f64]) -> String {
        let mut per: Vec<(Channel, f64, usize)> = Vec::new();
        let mut blocks = self.blocks.iter();
        for (k, channels) in self.compared.iter().enumerate() {
            let left_out = self.filter_transient_samples(k);
            for ((c, sigma), rows) in channels.iter().zip(blocks.by_ref()) {
                let sum: f64 = residual[rows.clone()]
                    .iter()
                    .map(|r| (r * sigma).powi(2))
                    .sum();
                let n = rows.len() - left_out;
                match per.iter_mut().find(|(d, ..)| d == c) {
                    Some((_, s, m)) => {
                        *s += sum;
                        *m += n;
                    }
                    None => per.push((*c, sum, n)),
                }
            }
        }
        per.iter()
            .map(|(c, s, n)| format!("{} {:.3e}", c.name(), (s / (*n).max(1) as f64).sqrt()))
            .collect::<Vec<_>>()
            .join(", ")
    }
}
