//! Held-out records of an element test (a sine step, a sweep or a band-random record the
//! diagnosis, or an identification, was not fitted on): the measured force predicted from the
//! measured motion by the baseline and by the model with the top effect, F = m x'' + f(x, x'),
//! and the NMSE of the force before and after.
//!
//! No simulation: the element sits between the measured displacement and the measured force
//! whatever drives it (a displacement-controlled dyno or a force-driven shaker), so the force
//! follows from the measured state ([`MeasuredState`]).

use std::sync::Arc;

use crate::basis::Term;
use crate::pipeline::nmse_percent;
use crate::signal::bouc_wen::HysteresisLaw;

use crate::measured_state::MeasuredState;
use crate::model::Model;
use crate::recipe::Setup;

/// A model of the element force with its fitted coefficients (extra element terms, and a
/// hysteresis state where it was fitted on records' samples), and the moving mass it was
/// fitted with.
#[derive(Debug, Clone)]
pub struct TermFit {
    pub terms: Vec<Arc<dyn Term>>,
    pub theta: Vec<f64>,
    pub mass_kg: f64,
    /// A Bouc-Wen law and its force coefficient alpha [N/m]: the force alpha z, z integrated
    /// along the record's measured velocity from its start.
    pub hysteresis: Option<(HysteresisLaw, f64)>,
}

impl TermFit {
    /// The measured force's prediction at (x, x', x''), the hysteresis force aside.
    pub fn force(&self, x: f64, v: f64, a: f64) -> f64 {
        self.mass_kg * a
            + self
                .terms
                .iter()
                .zip(&self.theta)
                .map(|(t, th)| th * t.eval(x, v))
                .sum::<f64>()
    }
}

impl TermFit {
    /// `model`'s terms at `theta` (its coefficients, then the moving mass where `setup` leaves
    /// it unknown) with the setup's moving mass: an identification's element force.
    pub fn of_model(model: &Model, setup: &Setup, theta: &[f64]) -> TermFit {
        let p = model.terms.len();
        let mass_kg = match setup {
            Setup::Element {
                moving_mass_kg: Some(m),
                ..
            } => *m,
            _ => theta.get(p).copied().unwrap_or(0.0),
        };
        TermFit {
            terms: model.terms.clone(),
            theta: theta[..p].to_vec(),
            mass_kg,
            hysteresis: None,
        }
    }
}

impl MeasuredState {
    /// NMSE of the measured force against `fit`'s prediction over the scored samples [%].
    pub fn force_nmse_percent(&self, fit: &TermFit) -> f64 {
        nmse_percent(
            &self.force_n[self.scored.clone()],
            &self.predicted_force(fit),
        )
    }

    /// `fit`'s prediction of the measured force over the scored samples [N].
    pub fn predicted_force(&self, fit: &TermFit) -> Vec<f64> {
        let s = self.scored.clone();
        let hysteresis = fit.hysteresis.map(|(law, alpha)| {
            let z = law.integrate_record(&self.velocity_mps, 1.0 / self.sample_rate_hz);
            (z, alpha)
        });
        s.map(|i| {
            fit.force(
                self.displacement_m[i],
                self.velocity_mps[i],
                self.acceleration_mps2[i],
            ) + hysteresis.as_ref().map_or(0.0, |(z, alpha)| alpha * z[i])
        })
        .collect()
    }
}
