//! A fitted baseline + structure as an element the rig simulator runs: its smooth terms,
//! friction from its sgn-like terms, and the internal states the structure adds (Bouc-Wen
//! hysteresis, a series spring's force, a drifting damper's clock).

use std::sync::Arc;

use super::element_heldout::TermFit;
use crate::basis::Term;
use crate::element::{Element, Friction};
use crate::signal::bouc_wen::HysteresisLaw;

/// A fitted model as an element: smooth terms, Coulomb/Stribeck friction from the sgn-like
/// terms (kinetic level from sgn, breakaway excess from the Stribeck term), and Bouc-Wen
/// hysteresis with one internal state.
#[derive(Debug, Clone)]
pub struct FittedElement {
    pub terms: Vec<Arc<dyn Term>>,
    pub theta: Vec<f64>,
    /// (alpha [N/m], the member of the Bouc-Wen family).
    pub hysteresis: Option<(f64, HysteresisLaw)>,
    /// (index of the damper term, relaxation time c / ks [s]): that term's force is the
    /// series spring's, an internal state with `f' = (c x' - f) / tau`.
    pub series: Option<(usize, f64)>,
    /// (index of the damper term, its rate [N s/m per s], the run's time at the record's
    /// start [s]): the damper's force is `(c + rate t) x'`, t from an internal clock state.
    pub drift: Option<(usize, f64, f64)>,
    /// Indices of the terms in the smooth force (not the friction terms, not the damper term
    /// a series spring replaces), listed once: the simulators ask for the force at every RK4
    /// stage.
    smooth_terms: Vec<usize>,
}

impl FittedElement {
    /// The element of `terms` with coefficients `theta`, and the states a structure adds.
    pub fn new(
        terms: Vec<Arc<dyn Term>>,
        theta: Vec<f64>,
        hysteresis: Option<(f64, HysteresisLaw)>,
        series: Option<(usize, f64)>,
        drift: Option<(usize, f64, f64)>,
    ) -> FittedElement {
        let series_term = series.map(|(i, _)| i);
        let smooth_terms = (0..terms.len())
            .filter(|&i| !terms[i].jumps_at_zero_velocity() && Some(i) != series_term)
            .collect();
        FittedElement {
            terms,
            theta,
            hysteresis,
            series,
            drift,
            smooth_terms,
        }
    }

    /// The element of a fit along the measured motion (its terms and its Bouc-Wen state, no
    /// series spring or drift).
    pub fn of_term_fit(fit: &TermFit) -> FittedElement {
        FittedElement::new(
            fit.terms.clone(),
            fit.theta.clone(),
            fit.hysteresis.map(|(law, alpha)| (alpha, law)),
            None,
            None,
        )
    }

    /// Offsets of the (series force, clock) internal states, after the hysteresis state.
    fn state_offsets(&self) -> (usize, usize) {
        let h = usize::from(self.hysteresis.is_some());
        (h, h + usize::from(self.series.is_some()))
    }
}

impl Element for FittedElement {
    fn smooth_force(&self, x: f64, v: f64, z: &[f64]) -> f64 {
        let (is, it) = self.state_offsets();
        let mut f: f64 = self
            .smooth_terms
            .iter()
            .map(|&i| self.theta[i] * self.terms[i].eval(x, v))
            .sum();
        if let (Some((alpha, _)), Some(zz)) = (self.hysteresis, z.first()) {
            f += alpha * zz;
        }
        if self.series.is_some() {
            f += z[is];
        }
        if let Some((i, rate, t0)) = self.drift {
            f += rate * (t0 + z[it]) * self.terms[i].eval(x, v);
        }
        f
    }

    /// The Stribeck term's own law (velocity and shape exponent): the replay runs the law
    /// that was fitted.
    fn friction(&self) -> Option<Friction> {
        Friction::from_terms(&self.terms, &self.theta)
    }

    fn internal_states(&self) -> usize {
        let (_, it) = self.state_offsets();
        it + usize::from(self.drift.is_some())
    }

    fn internal_rates(&self, x: f64, v: f64, z: &[f64], dz: &mut [f64]) {
        if let (Some((_, law)), Some(&zz), Some(d)) = (self.hysteresis, z.first(), dz.first_mut()) {
            *d = law.rate(zz, v);
        }
        let (is, it) = self.state_offsets();
        if let Some((i, tau)) = self.series {
            dz[is] = (self.theta[i] * self.terms[i].eval(x, v) - z[is]) / tau;
        }
        if self.drift.is_some() {
            dz[it] = 1.0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::StribeckVelocity;

    #[test]
    fn the_fitted_friction_law_is_the_stribeck_term_with_its_exponent() {
        // Slipping, the friction law of the fitted element is fd + fs exp(-|v/vs|^delta): the
        // term's own curve, not the Gaussian one (e^-1 of the excess left at v = vs, and
        // exp(-2^0.7) at 2 vs, where the Gaussian law leaves exp(-4)).
        let (fd, fs, vs, delta) = (10.0, 4.0, 0.02, 0.7);
        let terms: Vec<Arc<dyn Term>> = vec![
            Arc::new(crate::basis::SignVelocity),
            Arc::new(StribeckVelocity {
                velocity_mps: vs,
                exponent: delta,
            }),
        ];
        let e = FittedElement::new(terms, vec![fd, fs], None, None, None);
        let f = e.friction().unwrap();
        assert_eq!((f.kinetic_n, f.breakaway_n), (fd, fd + fs));
        assert_eq!((f.stribeck_velocity_mps, f.stribeck_exponent), (vs, delta));
        let at_vs = fd + fs * (-1.0f64).exp();
        assert!((f.slip_force_n(vs) - at_vs).abs() < 1e-12);
        assert!((f.slip_force_n(-vs) + at_vs).abs() < 1e-12);
        let at_2vs = fd + fs * (-(2.0f64.powf(0.7))).exp();
        assert!((f.slip_force_n(2.0 * vs) - at_2vs).abs() < 1e-12);
        assert!((at_2vs - (fd + fs * (-4.0f64).exp())).abs() > 0.5);
    }
}
