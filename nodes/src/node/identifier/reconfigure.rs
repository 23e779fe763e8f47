//! Live parameters of the identifier: which parameters may change while it runs, how a new
//! value is checked, and the re-solve of the kept phasors for a new model, method, weighting
//! or forgetting factor.

use forcemap_io::params::ParamValue;
use forcemap_math::identify::{Method, Weighting};
use forcemap_math::recipe::{ModelSpec, Tracking, live_refusal};
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::msg::HarmonicPhasors;

use super::core::{IdentifierCore, Output, RecipeParameters};
use crate::node::setup_gate::Ready;

/// The parameters a running identifier accepts new values of; every other parameter is fixed
/// at start.
pub const SETTABLE: [&str; 4] = ["model", "method", "weighting", "forgetting_per_step"];

/// One new parameter value, checked for its type and name.
#[derive(Debug, Clone, PartialEq)]
pub enum Setting {
    /// The model's name; its options (atan_m, poly_order) stay as started.
    Model(ModelSpec),
    Method(Method),
    Weighting(Weighting),
    ForgettingPerStep(Tracking),
}

/// Why a set was not applied (what `SetParametersResult.reason` says); the identifier is left
/// as it was.
#[derive(Debug, Clone, PartialEq)]
pub struct Refusal {
    pub reason: String,
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.reason)
    }
}

fn refuse(reason: String) -> Refusal {
    Refusal { reason }
}

impl Setting {
    /// The setting of parameter `name` to `value`, refused when the name is not settable or
    /// the value is of the wrong type or no known model, method or weighting.
    pub fn parse(name: &str, value: &ParamValue) -> Result<Setting, Refusal> {
        let text = || match value {
            ParamValue::String(s) => Ok(s.as_str()),
            other => Err(refuse(format!(
                "{name} must be a string (got a {})",
                other.type_name()
            ))),
        };
        match name {
            "model" => {
                let s = text()?;
                let spec = s
                    .parse::<ModelSpec>()
                    .map_err(|e| refuse(format!("model = '{s}': {e}")))?;
                Ok(Setting::Model(spec))
            }
            "method" => {
                let s = text()?;
                let m: Method = s
                    .parse()
                    .map_err(|e| refuse(format!("method = '{s}': {e}")))?;
                if let Some(why) = live_refusal(m) {
                    return Err(refuse(format!("method = '{s}': {why}")));
                }
                Ok(Setting::Method(m))
            }
            "weighting" => {
                let s = text()?;
                let w: Weighting = s
                    .parse()
                    .map_err(|e| refuse(format!("weighting = '{s}': {e}")))?;
                Ok(Setting::Weighting(w))
            }
            "forgetting_per_step" => {
                let f = match value {
                    ParamValue::Double(f) => *f,
                    ParamValue::Integer(i) => *i as f64,
                    other => {
                        return Err(refuse(format!(
                            "forgetting_per_step must be a double (got a {})",
                            other.type_name()
                        )));
                    }
                };
                let tracking = Tracking::from_factor(f)
                    .map_err(|e| refuse(format!("forgetting_per_step = {f}: {e}")))?;
                Ok(Setting::ForgettingPerStep(tracking))
            }
            other => Err(refuse(format!(
                "parameter '{other}' cannot change while the identifier runs (settable: {}); restart the node with -p {other}:=VALUE",
                SETTABLE.join(", ")
            ))),
        }
    }
}

impl RecipeParameters {
    /// These parameters with `settings` applied in order, refused as a whole when the model
    /// they give does not build (an atan model without its slope).
    pub fn with_settings(&self, settings: &[Setting]) -> Result<RecipeParameters, Refusal> {
        let mut p = self.clone();
        for s in settings {
            match s {
                Setting::Model(spec) => p.model = spec.clone().with_options(p.model.options()),
                Setting::Method(m) => p.method = *m,
                Setting::Weighting(w) => p.weighting = *w,
                Setting::ForgettingPerStep(t) => p.tracking = *t,
            }
        }
        p.model
            .build()
            .map_err(|e| refuse(format!("model = '{}': {e}", p.model.name)))?;
        Ok(p)
    }
}

impl IdentifierCore {
    /// Applies `settings` together: the equations are rebuilt from the kept phasors of every
    /// step (with the same per-step forgetting weights), solved, and theta and the status
    /// published at once (stamped `now`). Refused, with the identifier unchanged, when a
    /// value cannot be applied or the state keeps no phasors to rebuild from.
    pub fn reconfigure(&mut self, settings: &[Setting], now: Time) -> Result<Vec<Output>, Refusal> {
        let parameters = self.parameters.with_settings(settings)?;
        let (fresh, out) = self.rebuilt(parameters, now)?;
        *self = fresh;
        Ok(out)
    }

    /// A core running `parameters` whose equations are rebuilt from this one's kept phasors,
    /// with what it says (theta and status included, stamped `now`); this one is untouched.
    pub(super) fn rebuilt(
        &self,
        parameters: RecipeParameters,
        now: Time,
    ) -> Result<(IdentifierCore, Vec<Output>), Refusal> {
        let model = parameters
            .model
            .build()
            .map_err(|e| refuse(format!("model = '{}': {e}", parameters.model.name)))?;
        let described = describe(&parameters);
        let mut fresh = IdentifierCore {
            parameters,
            model,
            gate: self.gate.clone(),
            state: None,
            recipe: None,
            status_name: self.status_name.clone(),
        };
        let mut out = Vec::new();
        let Some(st) = &self.state else {
            // No step yet: the next one is taken with the new recipe.
            out.push(Output::Log(format!("now identifying {described}")));
            return Ok((fresh, out));
        };
        if !st.keeps_all_phasors() {
            return Err(refuse(format!(
                "the accumulated equations were resumed from a version-1 state file, which keeps no phasors of {} earlier steps: cannot re-solve them for another recipe; restart the node with the new values and an empty state_file",
                st.accumulator.steps_added()
            )));
        }
        let setup = st
            .setup_spec
            .clone()
            .ok_or_else(|| refuse("the state keeps no setup".into()))?;
        let mut frame = String::from("rig");
        let mut replay_log = Vec::new();
        let mut multisines = st
            .multisine_analyses()
            .map_err(|e| refuse(format!("re-solving: {e}")))?
            .into_iter();
        for ph in &st.phasors {
            let analysis = ph
                .to_analysis(Time::ZERO)
                .map_err(|e| refuse(format!("re-solving: step {}: {e}", ph.step)))?;
            let multisine = if ph.harmonic_cap == HarmonicPhasors::MULTISINE_CAP {
                multisines.next()
            } else {
                None
            };
            frame.clone_from(&ph.header.frame_id);
            fresh
                .add_step(
                    Ready {
                        phasors: ph.clone(),
                        analysis,
                        setup: setup.clone(),
                        multisine,
                    },
                    &mut replay_log,
                )
                .map_err(|e| refuse(format!("re-solving: {e:#}")))?;
        }
        // A step without equations is worth a line; the replay's other lines repeat the run.
        out.extend(
            replay_log
                .into_iter()
                .filter(|o| matches!(o, Output::Log(l) if l.contains("no equations"))),
        );
        let steps = fresh.state.as_ref().map_or(0, |s| s.phasors.len());
        out.push(Output::Log(format!(
            "now identifying {described}: re-solved from the phasors of {steps} steps"
        )));
        let what = format!("re-solved for {described}");
        fresh
            .publish_solution(&what, &what, now, &frame, &mut out)
            .map_err(|e| refuse(format!("re-solving: {e:#}")))?;
        out.push(Output::Persist);
        Ok((fresh, out))
    }
}

impl IdentifierCore {
    /// A parameter set as the parameter services deliver it: `atomically`, all values in one
    /// reconfiguration (one result); otherwise each on its own, in order (one result each).
    /// Returns the results (`Err` holds the reason), the values to store for what was applied
    /// (as the parameter table keeps them) and the outputs to publish.
    pub fn apply_parameters(
        &mut self,
        params: &[(String, ParamValue)],
        atomically: bool,
        now: Time,
    ) -> (ParameterSetResults, Vec<Output>) {
        let mut results = Vec::new();
        let mut stored = Vec::new();
        let mut out = Vec::new();
        let groups: Vec<&[(String, ParamValue)]> = if atomically {
            vec![params]
        } else {
            params.chunks(1).collect()
        };
        for group in groups {
            let parsed: Result<Vec<Setting>, Refusal> = group
                .iter()
                .map(|(name, value)| Setting::parse(name, value))
                .collect();
            match parsed.and_then(|settings| self.reconfigure(&settings, now)) {
                Ok(o) => {
                    out.extend(o);
                    stored.extend(group.iter().map(|(name, value)| match value {
                        // Declared as a double, whatever number was sent.
                        ParamValue::Integer(i) => (name.clone(), ParamValue::Double(*i as f64)),
                        v => (name.clone(), v.clone()),
                    }));
                    results.push(Ok(()));
                }
                Err(e) => {
                    out.push(Output::Log(format!("parameter set refused: {e}")));
                    results.push(Err(e.reason));
                }
            }
        }
        (
            ParameterSetResults {
                results,
                applied: stored,
            },
            out,
        )
    }
}

/// What [`IdentifierCore::apply_parameters`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct ParameterSetResults {
    /// One per parameter, or one for an atomic set; `Err` holds the reason.
    pub results: Vec<Result<(), String>>,
    /// The values applied, to store in the parameter table.
    pub applied: Vec<(String, ParamValue)>,
}

/// `model 'coulomb' by fd-multi, noise weighting, forgetting 1`.
fn describe(p: &RecipeParameters) -> String {
    format!(
        "model '{}' by {}, {} weighting, forgetting {} per step",
        p.model.name,
        p.method.name(),
        p.weighting.name(),
        p.tracking.factor_per_step()
    )
}
