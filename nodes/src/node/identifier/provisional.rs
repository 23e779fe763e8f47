//! Theta within a long step: the provisional phasors of the step in progress (the harmonic
//! node's `update_period_s`) solved with the steps so far, never added to them. The next
//! provisional phasors of the step, or its final ones, replace them; with forgetting, the
//! provisional step is the newest (the steps so far are weighed as if it had been added).

use forcemap_math::identify::step_equations;
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::DiagnosticStatus;
use forcemap_msgs::msg::{HarmonicPhasors, IdentifiedParameters};
use forcemap_msgs::std_msgs::Header;

use super::core::{IdentifierCore, Output, solve_state, theta_line};
use super::state::{Admit, IdentifierState, admit};

/// The time a theta describes: the end of the data of the newest step in it, the end of that
/// step's last fitted whole period, `t_ref + periods_used / frequency_hz` (less than one
/// sample interval after the last sample fitted). Theta's header stamp.
pub fn data_end_time(ph: &HarmonicPhasors) -> Time {
    ph.t_ref
        .add_secs_f64(f64::from(ph.periods_used) / ph.frequency_hz)
}

impl IdentifierCore {
    /// Provisional phasors of the step in progress: theta of the steps so far with them in
    /// place of that step, stamped with the end of their data, and a status for /diagnostics
    /// (that of a final theta, with `provisional_step` and `provisional_periods`: OK, or WARN
    /// with the solve's first flag or why there is no theta). Nothing when they are of a step
    /// already added (its final phasors overtook them), of another setup than the equations',
    /// or when their setup is not known yet or the equations do not determine theta; the
    /// accumulated state is never changed.
    pub fn handle_provisional(&self, ph: &HarmonicPhasors) -> Vec<Output> {
        let mut out = Vec::new();
        let step = ph.step;
        let Some((analysis, spec)) = self.gate.resolve_now(ph) else {
            return out;
        };
        let recipe = self.parameters.recipe(spec);
        let Ok(setup) = recipe.setup.setup() else {
            return out;
        };
        let (model, method) = (&self.model, self.parameters.method);
        let fresh;
        let st = match &self.state {
            Some(st) => {
                if st.setup != recipe.setup.to_string() || admit(st, step, ph.t_ref) != Admit::Add {
                    return out;
                }
                st
            }
            None => {
                fresh = IdentifierState::new(
                    model,
                    method,
                    self.parameters.weighting,
                    &setup,
                    &recipe.setup,
                );
                &fresh
            }
        };
        // Weighted as the accumulated steps are (their moving-mass hint).
        let options = forcemap_math::identify::FdMultiOptions {
            moving_mass_hint_kg: st.moving_mass_hint_kg,
            ..recipe.fd_options()
        };
        let solved = step_equations(model, &setup, method, &analysis, &options)
            .and_then(|blk| {
                st.accumulator
                    .with_provisional(self.parameters.tracking.factor_per_step(), &blk)
            })
            .and_then(|acc| solve_state(st, &acc, model, &self.parameters));
        let what = format!("step {step} (provisional, {} periods)", ph.periods_used);
        let (level, message) = match solved {
            Ok((id, flags)) => {
                out.push(Output::Log(format!("{what}: {}", theta_line(&id))));
                out.push(Output::Theta(IdentifiedParameters::from_identification(
                    &id,
                    Header::new(data_end_time(ph), &ph.header.frame_id),
                )));
                // As for a final theta: each flag is a WARN, the first is the message.
                match flags.first() {
                    Some(w) => (DiagnosticStatus::WARN, format!("{what}: {w}")),
                    None => (DiagnosticStatus::OK, format!("{what}: theta published")),
                }
            }
            Err(e) => {
                out.push(Output::Log(format!("{what}: no theta: {e}")));
                (DiagnosticStatus::WARN, format!("{what}: no theta: {e}"))
            }
        };
        // The status of a final theta, marked provisional, with the recipe it was solved by.
        if let Ok(Output::Status(s)) = self.status_of(level, &message, Some(&recipe)) {
            out.push(Output::Status(
                s.with_value("provisional_step", step)
                    .with_value("provisional_periods", ph.periods_used),
            ));
        }
        out
    }
}
