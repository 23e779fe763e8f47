//! The identifier's logic without the middleware: phasors and rig constants in, theta, status
//! and log lines out, so that it can be tested alone (and the live theta compared with
//! `forcemap identify` without DDS).

use anyhow::bail;
use forcemap_math::identify::{
    EquationAccumulator, Identification, IdentifyError, IdentifyWarning, Method, Weighting,
    multisine_equations, step_equations,
};
use forcemap_math::lstsq::LstsqError;
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::phasor::PhasorOptions;
use forcemap_math::recipe::{
    ModelSpec, Recipe, SetupConstants, SetupSpec, Tracking, check_mass_kg, live_refusal,
};
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::DiagnosticStatus;
use forcemap_msgs::msg::{HarmonicPhasors, IdentifiedParameters};
use forcemap_msgs::std_msgs::Header;

use super::provisional::data_end_time;
use super::state::{Admit, IdentifierState, admit};
use crate::node::setup_gate::{Input, Ready, SetupGate};
use forcemap_io::params::Params;
use forcemap_io::rig_constants;

/// The parts of the recipe the node's parameters fix from the start: model, method,
/// weighting and the setup constants it was given (`mass_kg`, `substructure...`). The setup
/// itself waits for the first step's channels (and, on a rig, for its mass).
#[derive(Debug, Clone)]
pub struct RecipeParameters {
    pub model: ModelSpec,
    pub method: Method,
    pub weighting: Weighting,
    pub tracking: Tracking,
    pub constants: SetupConstants,
}

impl RecipeParameters {
    /// Reads `model` (`coulomb`), `method` (`fd-multi`), `weighting` (`robust`),
    /// `forgetting_per_step` (1: converged; below 1 theta tracks drifting parameters),
    /// `atan_m`, `poly_order` (`[P, Q]`), `mass_kg` and `substructure...`; refuses a method the
    /// live identifier cannot run.
    pub fn from_params(p: &Params) -> anyhow::Result<RecipeParameters> {
        let poly = match p.opt_i64_array("poly_order")? {
            None => None,
            Some(v) if v.len() == 2 && v.iter().all(|x| (0..=64).contains(x)) => {
                Some((v[0] as u32, v[1] as u32))
            }
            Some(v) => bail!("poly_order = {v:?}: expected [P, Q] with 0 <= P, Q <= 64"),
        };
        let model = p
            .opt_str("model")?
            .unwrap_or("coulomb")
            .parse::<ModelSpec>()?
            .with_options(ModelOptions {
                atan_slope_s_per_m: p.opt_f64("atan_m")?,
                polynomial_order: poly,
            });
        // The model must build (an atan model needs its slope) before the first step.
        model.build()?;
        let method: Method = p.opt_str("method")?.unwrap_or("fd-multi").parse()?;
        if let Some(why) = live_refusal(method) {
            bail!("method = {method}: {why}");
        }
        let weighting: Weighting = match p.opt_str("weighting")? {
            Some(w) => w.parse()?,
            None => Weighting::default(),
        };
        let tracking = Tracking::from_factor(p.opt_f64("forgetting_per_step")?.unwrap_or(1.0))?;
        let constants = rig_constants::from_params(p)?;
        // Refused at once where no setup takes it; zero is an element test's load cell at the
        // fixed end (a rig refuses it when its first step resolves the setup).
        if let Some(m) = constants.mass_kg.filter(|m| *m != 0.0) {
            check_mass_kg(m)?;
        }
        Ok(RecipeParameters {
            model,
            method,
            weighting,
            tracking,
            constants,
        })
    }

    /// The recipe of steps of `setup`.
    pub fn recipe(&self, setup: SetupSpec) -> Recipe {
        Recipe {
            setup,
            model: self.model.clone(),
            method: self.method,
            weighting: self.weighting,
            phasor: PhasorOptions::for_identification(),
            tracking: self.tracking,
        }
    }
}

/// What the identifier does about it.
#[derive(Debug, Clone, PartialEq)]
pub enum Output {
    Log(String),
    Theta(IdentifiedParameters),
    /// The identifier's health for /diagnostics (with the recipe it runs).
    Status(DiagnosticStatus),
    /// The accumulated state changed: persist it.
    Persist,
}

/// The identifier's state machine.
pub struct IdentifierCore {
    pub(super) parameters: RecipeParameters,
    pub(super) model: Model,
    pub(super) gate: SetupGate,
    pub(super) state: Option<IdentifierState>,
    /// The recipe of the steps so far, published with every status.
    pub(super) recipe: Option<Recipe>,
    pub(super) status_name: String,
}

impl IdentifierCore {
    /// A core for `parameters`, reporting its status as `status_name`, resuming from `resumed`
    /// when that holds equations of this model, method and weighting, or else re-solving the
    /// phasors it keeps for them (a version-1 state without phasors is not resumed then). Returns the log lines
    /// and, for a resumed state, its theta (a control node may have missed the last one).
    pub fn new(
        parameters: RecipeParameters,
        status_name: &str,
        resumed: Option<(IdentifierState, String)>,
        now: Time,
    ) -> anyhow::Result<(IdentifierCore, Vec<Output>)> {
        let model = parameters.model.build()?;
        let mut out = Vec::new();
        let mut state = None;
        if let Some((s, source)) = resumed {
            if s.accumulator.is_for(&model, parameters.method)
                && s.weighting == parameters.weighting
            {
                out.push(Output::Log(format!(
                    "resuming from {source}: {} steps, {} equations, last step {:?}",
                    s.steps_added(),
                    s.accumulator.equations(),
                    s.last_step
                )));
                if s.steps_added() > 0
                    && let Ok((id, _)) = solve_state(&s, &s.accumulator, &model, &parameters)
                {
                    out.push(Output::Log(format!("resumed theta: {}", theta_line(&id))));
                    let stamp = s.phasors.last().map_or(now, data_end_time);
                    out.push(Output::Theta(IdentifiedParameters::from_identification(
                        &id,
                        Header::new(stamp, "rig"),
                    )));
                }
                state = Some(s);
            } else {
                let held = format!(
                    "{source} holds equations of model '{}' by {} ({} weighting)",
                    s.accumulator.model,
                    s.accumulator.method,
                    s.weighting.name()
                );
                // The kept phasors give this identifier's equations for the same steps.
                if s.keeps_all_phasors() && !s.phasors.is_empty() {
                    let steps = s.phasors.len();
                    let old = IdentifierCore {
                        gate: SetupGate::new(parameters.constants.clone()),
                        parameters: parameters.clone(),
                        model: model.clone(),
                        state: Some(s),
                        recipe: None,
                        status_name: status_name.to_string(),
                    };
                    match old.rebuilt(parameters.clone(), now) {
                        Ok((core, said)) => {
                            out.push(Output::Log(format!(
                                "{held}: re-solving the phasors of its {steps} steps for this identifier"
                            )));
                            out.extend(said);
                            return Ok((core, out));
                        }
                        Err(e) => out.push(Output::Log(format!(
                            "{held}, which cannot be re-solved ({e}); starting afresh"
                        ))),
                    }
                } else {
                    out.push(Output::Log(format!(
                        "{held}, without the phasors to re-solve them: not this identifier's; starting afresh"
                    )));
                }
            }
        }
        Ok((
            IdentifierCore {
                gate: SetupGate::new(parameters.constants.clone()),
                parameters,
                model,
                state,
                recipe: None,
                status_name: status_name.to_string(),
            },
            out,
        ))
    }

    pub fn model(&self) -> &Model {
        &self.model
    }

    pub fn parameters(&self) -> &RecipeParameters {
        &self.parameters
    }

    /// The accumulated state, once a step has been seen.
    pub fn state(&self) -> Option<&IdentifierState> {
        self.state.as_ref()
    }

    /// The recipe of the steps so far.
    pub fn recipe(&self) -> Option<&Recipe> {
        self.recipe.as_ref()
    }

    /// Handles one input at wall-clock time `now` (the stamp of what it publishes). An error
    /// is a configuration the node cannot run with (e.g. an inconsistent substructure).
    pub fn handle(&mut self, input: Input, now: Time) -> anyhow::Result<Vec<Output>> {
        let mut log = Vec::new();
        let ready = self.gate.admit(input, &mut log)?;
        let mut out: Vec<Output> = log.into_iter().map(Output::Log).collect();
        for r in ready {
            self.step(r, now, &mut out)?;
        }
        Ok(out)
    }

    fn step(&mut self, ready: Ready, now: Time, out: &mut Vec<Output>) -> anyhow::Result<()> {
        let step = ready.phasors.step;
        let frame = ready.phasors.header.frame_id.clone();
        if self.add_step(ready, out)? {
            self.publish_solution(
                &format!("step {step}"),
                &format!("theta after step {step}"),
                now,
                &frame,
                out,
            )?;
        }
        Ok(())
    }

    /// Admits one step into the state and adds its equations; true when it added equations
    /// (then theta is solved). The same path serves live steps and the replay of the kept
    /// phasors by [`IdentifierCore::reconfigure`], so both give the same equations.
    pub(super) fn add_step(&mut self, ready: Ready, out: &mut Vec<Output>) -> anyhow::Result<bool> {
        let Ready {
            phasors: ph,
            analysis,
            setup,
            multisine,
        } = ready;
        let step = ph.step;
        let recipe = self.parameters.recipe(setup);
        let step_setup = recipe.setup.setup()?;
        let options = recipe.fd_options();
        let setup_text = recipe.setup.to_string();
        let spec = recipe.setup.clone();
        if self.recipe.as_ref() != Some(&recipe) {
            out.push(Output::Log(format!(
                "recipe: {}",
                serde_json::to_string(&recipe)?
            )));
            self.recipe = Some(recipe);
        }
        let (model, method, weighting) = (
            &self.model,
            self.parameters.method,
            self.parameters.weighting,
        );
        let st = self.state.get_or_insert_with(|| {
            IdentifierState::new(model, method, weighting, &step_setup, &spec)
        });
        if st.setup != setup_text {
            // E.g. an element test's moving mass arrived after its first steps: the equations
            // have other unknowns now.
            out.push(Output::Log(format!(
                "step {step}: the setup is now {setup_text} (was {}): starting the equations afresh",
                st.setup
            )));
            *st = IdentifierState::new(model, method, weighting, &step_setup, &spec);
        }
        match admit(st, step, ph.t_ref) {
            Admit::Duplicate => {
                out.push(Output::Log(format!(
                    "step {step}: already in the accumulated equations; skipped"
                )));
                return Ok(false);
            }
            Admit::NewRun => {
                out.push(Output::Log(format!(
                    "step {step} again, later in time: a new run; starting the equations afresh"
                )));
                *st = IdentifierState::new(model, method, weighting, &step_setup, &spec);
            }
            Admit::Add => {}
        }
        let forgetting = self.parameters.tracking.factor_per_step();
        let added = match multisine {
            // Not accumulated: solved with the accumulated equations whenever theta is, in two
            // passes (IdentifierState::solve_with_flags); its equations are written here only
            // to refuse a step that gives none.
            Some(ms) => {
                if forgetting < 1.0 {
                    Err(MULTISINE_NOT_TRACKED.to_string())
                } else {
                    multisine_equations(model, &step_setup, &ms, &options)
                        .map(|_| {
                            st.phasors.push(ph.clone());
                            st.multisine_lines.insert(step, ms.lines);
                            // With multisines, `forcemap identify` weighs no moving-mass hint.
                            if st.moving_mass_hint_kg.is_some() {
                                st.rebuild_sine_equations(model, &step_setup, method, &options);
                            }
                        })
                        .map_err(|e| e.to_string())
                }
            }
            None => {
                st.phasors.push(ph.clone());
                prune_forgotten(&mut st.phasors, forgetting);
                let hint = st.moving_mass_hint(model, &step_setup, method, forgetting, &options);
                let options = forcemap_math::identify::FdMultiOptions {
                    moving_mass_hint_kg: hint,
                    ..options
                };
                let block = step_equations(model, &step_setup, method, &analysis, &options)
                    .map_err(|e| e.to_string());
                if hint == st.moving_mass_hint_kg {
                    block.and_then(|blk| {
                        // The steps so far weigh less only once the new one has equations.
                        st.accumulator.forget(forgetting);
                        st.accumulator.add(&blk).map_err(|e| e.to_string())
                    })
                } else {
                    // Every kept step's weights change with the hint: written afresh (converged
                    // only, so no forgetting), this step among them.
                    st.rebuild_sine_equations(model, &step_setup, method, &options);
                    block.map(|_| ())
                }
            }
        };
        if let Err(e) = added {
            out.push(Output::Log(format!("step {step}: no equations: {e}")));
            out.push(self.status(
                DiagnosticStatus::WARN,
                &format!("step {step} gave no equations: {e}"),
            )?);
            return Ok(false);
        }
        st.last_step = Some(step);
        st.last_t_ref = Some(ph.t_ref);
        out.push(Output::Persist);
        Ok(true)
    }

    /// Solves the equations so far and says so: a log line headed `what`, theta (stamped with
    /// the time it describes, [`data_end_time`] of the newest step, or `now` without kept
    /// phasors; in `frame`) and the status, OK with `ok_message` unless a flag or an error says more.
    pub(super) fn publish_solution(
        &self,
        what: &str,
        ok_message: &str,
        now: Time,
        frame: &str,
        out: &mut Vec<Output>,
    ) -> anyhow::Result<()> {
        let Some(st) = &self.state else {
            return Ok(());
        };
        match solve_state(st, &st.accumulator, &self.model, &self.parameters) {
            Ok((id, flags)) => {
                out.push(Output::Log(format!(
                    "{what}: {} ({} equations, cond {:.2e})",
                    theta_line(&id),
                    id.equations,
                    id.condition_number
                )));
                let stamp = st.phasors.last().map_or(now, data_end_time);
                out.push(Output::Theta(IdentifiedParameters::from_identification(
                    &id,
                    Header::new(stamp, frame),
                )));
                // Each flag (badly conditioned, few equations) is a WARN; the first is the
                // message.
                let (level, message) = match flags.first() {
                    Some(w) => (DiagnosticStatus::WARN, w.to_string()),
                    None => (DiagnosticStatus::OK, ok_message.to_string()),
                };
                out.push(self.status(level, &message)?);
            }
            Err(IdentifyError::Lstsq(e @ LstsqError::Underdetermined { .. }))
            | Err(IdentifyError::Lstsq(e @ LstsqError::IllConditioned { .. })) => {
                out.push(Output::Log(format!("{what}: no theta yet: {e}")));
                out.push(self.status(DiagnosticStatus::WARN, &e.to_string())?);
            }
            Err(e) => {
                out.push(Output::Log(format!("{what}: {e}")));
                out.push(self.status(DiagnosticStatus::ERROR, &e.to_string())?);
            }
        }
        Ok(())
    }

    /// The status for /diagnostics, with the recipe it runs (JSON, as `forcemap identify
    /// --json` prints it) so that a recorded bag keeps it.
    pub(super) fn status(&self, level: u8, message: &str) -> anyhow::Result<Output> {
        self.status_of(level, message, self.recipe.as_ref())
    }

    /// [`IdentifierCore::status`] naming `recipe` (a provisional theta's, before any step is in).
    pub(super) fn status_of(
        &self,
        level: u8,
        message: &str,
        recipe: Option<&Recipe>,
    ) -> anyhow::Result<Output> {
        let mut status = DiagnosticStatus::new(level, &self.status_name, message, "identifier")
            .with_value("recipe", serde_json::to_string(&recipe)?);
        if let Some(st) = &self.state {
            status = status
                .with_value("model", &st.accumulator.model)
                .with_value("method", &st.accumulator.method)
                .with_value("steps_added", st.steps_added())
                .with_value("equations", st.accumulator.equations());
        }
        Ok(Output::Status(status))
    }
}

/// Why a multisine step is refused while tracking (as `forcemap identify` refuses it).
const MULTISINE_NOT_TRACKED: &str = "tracking forgets per sine step; a periodic multisine record cannot be tracked (forgetting_per_step 1 identifies it)";

/// Theta of `sines` (the state's accumulated equations, or them with a provisional step) and
/// the state's multisine steps, with the options of `parameters`' recipe.
pub(super) fn solve_state(
    st: &IdentifierState,
    sines: &EquationAccumulator,
    model: &Model,
    parameters: &RecipeParameters,
) -> Result<(Identification, Vec<IdentifyWarning>), IdentifyError> {
    let options = match &st.setup_spec {
        Some(spec) => parameters.recipe(spec.clone()).fd_options(),
        None => return sines.solve_with_flags(),
    };
    st.solve_with_flags(sines, model, &options)
}

/// Below this weight a step does not change theta in double precision: with forgetting, the
/// phasors of older steps are let go, so that a tracking identifier's memory stays flat.
const NEGLIGIBLE_STEP_WEIGHT: f64 = 1e-16;

/// Drops the kept phasors of the steps whose weight `factor`^age has fallen below
/// [`NEGLIGIBLE_STEP_WEIGHT`] (none when converged).
fn prune_forgotten(phasors: &mut Vec<HarmonicPhasors>, factor: f64) {
    if factor < 1.0 {
        let keep = (NEGLIGIBLE_STEP_WEIGHT.ln() / factor.ln()).floor() as usize + 1;
        if phasors.len() > keep {
            phasors.drain(..phasors.len() - keep);
        }
    }
}

pub fn theta_line(id: &Identification) -> String {
    id.parameters
        .iter()
        .map(|p| format!("{} = {:.6} ± {:.3}", p.name, p.value, p.std))
        .collect::<Vec<_>>()
        .join(", ")
}
