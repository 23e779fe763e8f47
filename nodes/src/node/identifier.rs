//! The identifier node: accumulates the equations of every step's phasors and publishes theta
//! with its standard deviations after each new step, plus its health on /diagnostics.
//!
//! Memory is constant in the number of samples: only the triangular factor of the stacked
//! equations is kept ([`EquationAccumulator`]), never samples or phasors. The same
//! accumulator stacks the steps of `forcemap identify`, so the live theta equals the offline
//! one on the same data.
//!
//! Parameters:
//! - `model` (`coulomb`), `method` (`fd-multi` or `fd`), `weighting` (`noise` or `uniform`,
//!   fd-multi only), `atan_m`, `poly_order` (`[P, Q]`), as `forcemap identify`;
//! - `mass_kg`: the rig's mass; without it the value on the rig's `parameters` topic is used;
//! - `substructure...`: the linear substructure of a drive-point setup (see
//!   launch_configs/three_dof.params.yaml);
//! - `state_file`: where the accumulated equations are persisted after every step (empty: not
//!   persisted). A restarted identifier resumes from it and skips the steps it already has.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Context as _, bail};
use forcemap_math::identify::{
    EquationAccumulator, Identification, IdentifyError, Method, Weighting, step_equations,
};
use forcemap_math::lstsq::LstsqError;
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::phasor::{HarmonicAnalysis, PhasorOptions};
use forcemap_math::recipe::{
    ModelSpec, Recipe, RecipeError, SetupConstants, SetupKind, SetupSpec, check_mass_kg,
    live_refusal,
};
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus};
use forcemap_msgs::msg::{HarmonicPhasors, IdentifiedParameters};
use forcemap_msgs::std_msgs::Header;
use serde::{Deserialize, Serialize};
use tokio::sync::mpsc;

use crate::log_line;
use crate::ros::{NodeSetup, OnTakeError, RosNode, forward, now_time, qos, rig_mass_kg};
use forcemap_io::params::Params;
use forcemap_io::rig_constants;
use forcemap_io::topics;

/// What the identifier persists.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IdentifierState {
    pub version: u32,
    pub weighting: Weighting,
    /// The setup the equations were made with (e.g. `base-excited, mass 36 kg`).
    pub setup: String,
    pub accumulator: EquationAccumulator,
    /// The last step added and its phasors' reference time, to skip steps already added
    /// (replayed history after a restart) and to notice a new run.
    pub last_step: Option<u32>,
    pub last_t_ref: Option<Time>,
}

const STATE_VERSION: u32 = 1;

impl IdentifierState {
    pub fn new(model: &Model, method: Method, weighting: Weighting, setup: &str) -> Self {
        IdentifierState {
            version: STATE_VERSION,
            weighting,
            setup: setup.to_string(),
            accumulator: EquationAccumulator::new(model, method),
            last_step: None,
            last_t_ref: None,
        }
    }

    /// Reads a persisted state; `None` when there is no file.
    pub fn load(path: &Path) -> anyhow::Result<Option<IdentifierState>> {
        let text = match std::fs::read_to_string(path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
        };
        let s: IdentifierState = serde_json::from_str(&text)
            .with_context(|| format!("{}: not an identifier state file", path.display()))?;
        if s.version != STATE_VERSION {
            bail!(
                "{}: state version {} (this identifier writes version {STATE_VERSION})",
                path.display(),
                s.version
            );
        }
        Ok(Some(s))
    }

    /// Writes the state atomically (temporary file, fsync, rename), so a crash leaves either
    /// the old or the new state, never a torn one.
    pub fn save(&self, path: &Path) -> anyhow::Result<()> {
        use std::io::Write as _;
        let dir = path.parent().filter(|d| !d.as_os_str().is_empty());
        if let Some(d) = dir {
            std::fs::create_dir_all(d).with_context(|| format!("creating {}", d.display()))?;
        }
        let tmp = path.with_extension("json.partial");
        let text = serde_json::to_string(self).context("serialising the identifier state")?;
        let mut f =
            std::fs::File::create(&tmp).with_context(|| format!("creating {}", tmp.display()))?;
        f.write_all(text.as_bytes())
            .and_then(|()| f.sync_all())
            .with_context(|| format!("writing {}", tmp.display()))?;
        std::fs::rename(&tmp, path)
            .with_context(|| format!("renaming {} to {}", tmp.display(), path.display()))?;
        Ok(())
    }
}

/// What to do with a step's phasors given the state.
#[derive(Debug, PartialEq)]
pub enum Admit {
    Add,
    /// Already added (history replayed to a restarted identifier).
    Duplicate,
    /// An earlier step number with a later time: a new run; start over.
    NewRun,
}

pub fn admit(state: &IdentifierState, step: u32, t_ref: Time) -> Admit {
    match (state.last_step, state.last_t_ref) {
        (Some(ls), Some(lt)) => {
            if t_ref <= lt {
                Admit::Duplicate
            } else if step <= ls {
                Admit::NewRun
            } else {
                Admit::Add
            }
        }
        _ => Admit::Add,
    }
}

/// The parts of the recipe the node's parameters fix from the start: model, method,
/// weighting and the setup constants it was given (`mass_kg`, `substructure...`). The setup
/// itself waits for the first step's channels (and, on a rig, for its mass).
#[derive(Debug, Clone)]
pub struct RecipeParameters {
    pub model: ModelSpec,
    pub method: Method,
    pub weighting: Weighting,
    pub constants: SetupConstants,
}

impl RecipeParameters {
    /// Reads `model` (`coulomb`), `method` (`fd-multi`), `weighting` (`noise`), `atan_m`,
    /// `poly_order` (`[P, Q]`), `mass_kg` and `substructure...`; refuses a method the live
    /// identifier cannot run.
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
        let weighting: Weighting = p.opt_str("weighting")?.unwrap_or("noise").parse()?;
        let constants = rig_constants::from_params(p)?;
        if let Some(m) = constants.mass_kg {
            check_mass_kg(m)?;
        }
        Ok(RecipeParameters {
            model,
            method,
            weighting,
            constants,
        })
    }

    /// The recipe of a step's phasors, or `None` while the rig's mass is unknown.
    pub fn recipe_for(
        &self,
        analysis: &HarmonicAnalysis,
        carried: &SetupConstants,
    ) -> anyhow::Result<Option<Recipe>> {
        let Some(setup) = step_setup(analysis, &self.constants.clone().or(carried.clone()))? else {
            return Ok(None);
        };
        Ok(Some(Recipe {
            setup,
            model: self.model.clone(),
            method: self.method,
            weighting: self.weighting,
            phasor: PhasorOptions::for_identification(),
        }))
    }
}

/// The setup of a step's phasors, from the channels they hold and the constants known;
/// `None` while a rig's mass is unknown (the node waits for the rig's parameters topic).
pub fn step_setup(
    analysis: &HarmonicAnalysis,
    constants: &SetupConstants,
) -> anyhow::Result<Option<SetupSpec>> {
    let kind = SetupKind::of_channels(|c| analysis.channels.iter().any(|ch| ch.channel == c))
        .map_err(|e| anyhow::anyhow!("step {}: {e}", analysis.step))?;
    match kind.resolve(constants) {
        Ok(s) => Ok(Some(s)),
        Err(RecipeError::MissingMass) => Ok(None),
        Err(e) => Err(anyhow::anyhow!("the node's parameters: {e}")),
    }
}

fn theta_line(id: &Identification) -> String {
    id.parameters
        .iter()
        .map(|p| format!("{} = {:.6} ± {:.3}", p.name, p.value, p.std))
        .collect::<Vec<_>>()
        .join(", ")
}

enum Input {
    Phasors(Box<HarmonicPhasors>),
    RigMass(f64),
}

pub async fn run(setup: NodeSetup) -> anyhow::Result<()> {
    let p = setup.params.clone();
    let rp = RecipeParameters::from_params(&p)?;
    let model = rp.model.build()?;
    let (method, weighting) = (rp.method, rp.weighting);
    // Constants from the rig's parameters topic, used where the node's parameters say nothing.
    let mut carried = SetupConstants::default();
    let state_file: Option<PathBuf> = p
        .opt_str("state_file")?
        .filter(|s| !s.is_empty())
        .map(PathBuf::from);
    let fq = setup.fully_qualified_name();

    let mut state: Option<IdentifierState> = None;
    if let Some(path) = &state_file
        && let Some(s) = IdentifierState::load(path)?
    {
        if s.accumulator.is_for(&model, method) && s.weighting == weighting {
            log_line!(
                "resuming from {}: {} steps, {} equations, last step {:?}",
                path.display(),
                s.accumulator.steps_added(),
                s.accumulator.equations(),
                s.last_step
            );
            state = Some(s);
        } else {
            log_line!(
                "{} holds equations of model '{}' by {} ({} weighting): not this identifier's; starting afresh",
                path.display(),
                s.accumulator.model,
                s.accumulator.method,
                s.weighting.name()
            );
        }
    }

    let mut ros = RosNode::start(setup.clone())?;
    let phasors = ros.subscription::<HarmonicPhasors>(topics::PHASORS, qos::phasors())?;
    let rig = ros.subscription::<DiagnosticStatus>(topics::PARAMETERS, qos::parameters())?;
    let theta_pub = ros.publisher::<IdentifiedParameters>(topics::THETA, qos::theta())?;
    let diag_pub = ros.publisher::<DiagnosticArray>(topics::DIAGNOSTICS, qos::diagnostics())?;

    let (tx, mut rx) = mpsc::unbounded_channel::<Input>();
    forward(phasors, tx.clone(), OnTakeError::Warn("phasors"), |m, _| {
        Some(Input::Phasors(Box::new(m)))
    });
    forward(rig, tx, OnTakeError::Warn("the rig constants"), |m, _| {
        rig_mass_kg(&m).map(Input::RigMass)
    });

    log_line!(
        "identifying model '{}' ({}) by {} with {} weighting from {}",
        model.name,
        model.symbols().join(", "),
        method.name(),
        weighting.name(),
        setup.absolute_topic(topics::PHASORS)
    );
    let status_name = format!("{fq}: identification");
    // A resumed state is published at once: a control node may have missed the last theta.
    if let Some(st) = &state
        && st.accumulator.steps_added() > 0
        && let Ok(id) = st.accumulator.solve()
    {
        log_line!("resumed theta: {}", theta_line(&id));
        let msg = IdentifiedParameters::from_identification(&id, Header::new(now_time(), "rig"));
        if let Err(e) = theta_pub.async_publish(msg).await {
            log_line!("error: publishing theta: {e:?}");
        }
    }
    // Phasors that arrived before the rig's mass was known.
    let mut waiting: Vec<HarmonicPhasors> = Vec::new();
    // The recipe of the steps so far, published with every status.
    let mut current_recipe: Option<Recipe> = None;
    loop {
        let input = tokio::select! {
            i = rx.recv() => match i { Some(i) => i, None => break },
            _ = crate::ros::shutdown_signal() => break,
        };
        let batch = match input {
            Input::RigMass(m) => {
                if rp.constants.mass_kg.is_none() && carried.mass_kg.is_none() {
                    log_line!("rig mass {m} kg (from the rig's parameters topic)");
                    carried.mass_kg = Some(m);
                }
                std::mem::take(&mut waiting)
            }
            Input::Phasors(ph) => {
                let mut b = std::mem::take(&mut waiting);
                b.push(*ph);
                b
            }
        };
        for ph in batch {
            let step = ph.step;
            let analysis = match ph.to_analysis(Time::ZERO) {
                Ok(a) => a,
                Err(e) => {
                    log_line!("step {step}: phasors refused: {e}");
                    continue;
                }
            };
            let Some(recipe) = rp.recipe_for(&analysis, &carried)? else {
                if waiting.is_empty() {
                    log_line!(
                        "step {step}: waiting for the rig's mass (parameter mass_kg or the rig's parameters topic)"
                    );
                }
                waiting.push(ph);
                continue;
            };
            let step_setup = recipe.setup.setup()?;
            let options = recipe.fd_options();
            let setup_text = recipe.setup.to_string();
            if current_recipe.as_ref() != Some(&recipe) {
                log_line!("recipe: {}", serde_json::to_string(&recipe)?);
                current_recipe = Some(recipe);
            }
            let recipe_json = serde_json::to_string(&current_recipe)?;
            let st = state.get_or_insert_with(|| {
                IdentifierState::new(&model, method, weighting, &setup_text)
            });
            match admit(st, step, ph.t_ref) {
                Admit::Duplicate => {
                    log_line!("step {step}: already in the accumulated equations; skipped");
                    continue;
                }
                Admit::NewRun => {
                    log_line!(
                        "step {step} again, later in time: a new run; starting the equations afresh"
                    );
                    *st = IdentifierState::new(&model, method, weighting, &setup_text);
                }
                Admit::Add => {}
            }
            let added = step_equations(&model, &step_setup, method, &analysis, &options)
                .map_err(|e| e.to_string())
                .and_then(|blk| st.accumulator.add(&blk).map_err(|e| e.to_string()));
            if let Err(e) = added {
                log_line!("step {step}: no equations: {e}");
                publish_status(
                    &diag_pub,
                    &status_name,
                    DiagnosticStatus::WARN,
                    &format!("step {step} gave no equations: {e}"),
                    st,
                    &recipe_json,
                )
                .await;
                continue;
            }
            st.last_step = Some(step);
            st.last_t_ref = Some(ph.t_ref);
            if let Some(path) = &state_file {
                st.save(path)?;
            }
            match st.accumulator.solve_with_flags() {
                Ok((id, flags)) => {
                    log_line!(
                        "step {step}: {} ({} equations, cond {:.2e})",
                        theta_line(&id),
                        id.equations,
                        id.condition_number
                    );
                    let msg = IdentifiedParameters::from_identification(
                        &id,
                        Header::new(now_time(), &ph.header.frame_id),
                    );
                    if let Err(e) = theta_pub.async_publish(msg).await {
                        log_line!("error: publishing theta: {e:?}");
                    }
                    // Each flag (badly conditioned, few equations) is a WARN; the first is
                    // the message.
                    let (level, message) = match flags.first() {
                        Some(w) => (DiagnosticStatus::WARN, w.to_string()),
                        None => (DiagnosticStatus::OK, format!("theta after step {step}")),
                    };
                    publish_status(&diag_pub, &status_name, level, &message, st, &recipe_json)
                        .await;
                }
                Err(IdentifyError::Lstsq(e @ LstsqError::Underdetermined { .. }))
                | Err(IdentifyError::Lstsq(e @ LstsqError::IllConditioned { .. })) => {
                    log_line!("step {step}: no theta yet: {e}");
                    publish_status(
                        &diag_pub,
                        &status_name,
                        DiagnosticStatus::WARN,
                        &e.to_string(),
                        st,
                        &recipe_json,
                    )
                    .await;
                }
                Err(e) => {
                    log_line!("step {step}: {e}");
                    publish_status(
                        &diag_pub,
                        &status_name,
                        DiagnosticStatus::ERROR,
                        &e.to_string(),
                        st,
                        &recipe_json,
                    )
                    .await;
                }
            }
        }
    }
    // Give the last messages a moment to leave.
    tokio::time::sleep(Duration::from_millis(200)).await;
    Ok(())
}

/// The identifier's health on /diagnostics, with the recipe it runs (JSON, as
/// `forcemap identify --json` prints it) so that a recorded bag keeps it.
async fn publish_status(
    publisher: &ros2_client::Publisher<DiagnosticArray>,
    name: &str,
    level: u8,
    message: &str,
    st: &IdentifierState,
    recipe_json: &str,
) {
    let status = DiagnosticStatus::new(level, name, message, "identifier")
        .with_value("recipe", recipe_json)
        .with_value("model", &st.accumulator.model)
        .with_value("method", &st.accumulator.method)
        .with_value("steps_added", st.accumulator.steps_added())
        .with_value("equations", st.accumulator.equations());
    let _ = publisher
        .async_publish(DiagnosticArray {
            header: Header::new(now_time(), ""),
            status: vec![status],
        })
        .await;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_are_added_once_and_a_new_run_starts_over() {
        let model = Model::by_name("linear", &ModelOptions::default()).unwrap();
        let mut s = IdentifierState::new(&model, Method::FdMulti, Weighting::Noise, "x");
        let t = |s: i64| Time::from_nanos(s * 1_000_000_000);
        assert_eq!(admit(&s, 0, t(10)), Admit::Add);
        s.last_step = Some(3);
        s.last_t_ref = Some(t(50));
        assert_eq!(admit(&s, 2, t(40)), Admit::Duplicate);
        assert_eq!(admit(&s, 3, t(50)), Admit::Duplicate);
        assert_eq!(admit(&s, 4, t(60)), Admit::Add);
        assert_eq!(admit(&s, 0, t(100)), Admit::NewRun);
    }

    #[test]
    fn state_round_trips_through_its_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sub/state.json");
        let model = Model::by_name("coulomb", &ModelOptions::default()).unwrap();
        let mut s = IdentifierState::new(&model, Method::FdMulti, Weighting::Uniform, "rig");
        s.last_step = Some(7);
        s.last_t_ref = Some(Time::from_nanos(123_456_789));
        s.save(&path).unwrap();
        assert_eq!(IdentifierState::load(&path).unwrap(), Some(s));
        assert!(!path.with_extension("json.partial").exists());
        std::fs::write(&path, "{not json").unwrap();
        let e = IdentifierState::load(&path).unwrap_err();
        assert!(
            format!("{e:#}").contains("not an identifier state file"),
            "{e:#}"
        );
        assert_eq!(
            IdentifierState::load(&dir.path().join("none.json")).unwrap(),
            None
        );
    }
}
