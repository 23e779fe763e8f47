//! The identifier node: accumulates the equations of every step's phasors and publishes theta
//! with its standard deviations after each new step, plus its health on /diagnostics.
//!
//! Memory is constant in the number of samples: the triangular factor of the stacked
//! equations ([`EquationAccumulator`]) and each step's phasors (a few kilobytes, for a live
//! change of model) are kept, never samples. The same
//! accumulator stacks the steps of `forcemap identify`, so the live theta equals the offline
//! one on the same data.
//!
//! Parameters:
//! - `model` (`coulomb`), `method` (`fd-multi` or `fd`), `weighting` (`robust`, `noise` or
//!   `uniform`, fd-multi only), `atan_m`, `poly_order` (`[P, Q]`), as `forcemap identify`;
//! - `mass_kg`: the rig's mass; without it the value on the rig's `parameters` topic is used;
//! - `substructure...`: the linear substructure of a drive-point setup (see
//!   launch_configs/three_dof.params.yaml);
//! - `state_file`: where the accumulated equations and the kept phasors are persisted after
//!   every step (empty: not persisted). A restarted identifier resumes from it and skips the
//!   steps it already has.
//!
//! A periodic multisine step's phasors (its averaged period's bins) are identified too: their
//! excited lines are found on the driven channel its `ExcitationState` names (the identifier
//! subscribes to the excitation topic for that), and their per-line equations are solved with
//! the accumulated sine steps' in the two passes of `forcemap identify`
//! (`identify::accumulate_multisines`) whenever theta is, so the live theta equals the offline
//! one for multisine and mixed runs alike. Tracking (`forgetting_per_step` below 1) refuses
//! them, as offline tracking does.
//!
//! Provisional phasors of a step in progress (`phasors/provisional`, the harmonic node's
//! `update_period_s`) give a theta with that step in place, never added to the equations
//! ([`IdentifierCore::handle_provisional`]). Every theta's header stamp is the time it
//! describes: the end of the data of its newest step ([`data_end_time`]).
//!
//! The parameter services answer list/get/describe for all of them; `model`, `method`,
//! `weighting` and `forgetting_per_step` can be set while it runs (the kept phasors of every
//! step are re-solved and theta is published before the set is answered), the others are
//! read-only.

mod core;
mod provisional;
mod reconfigure;
mod state;

pub use crate::node::setup_gate::Input;
pub use core::{IdentifierCore, Output, RecipeParameters, theta_line};
pub use provisional::data_end_time;
pub use reconfigure::{ParameterSetResults, Refusal, SETTABLE, Setting};
pub use state::{Admit, IdentifierState, admit};

use std::path::PathBuf;
use std::time::Duration;

use forcemap_msgs::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus};
use forcemap_msgs::msg::{ExcitationState, HarmonicPhasors, IdentifiedParameters};
use forcemap_msgs::std_msgs::Header;
use tokio::sync::mpsc;

use crate::latency_trace;
use crate::log_line;
use crate::parameter_services::{ParameterTable, SetRequest};
use crate::ros::{NodeSetup, OnTakeError, RosNode, forward, now_time, qos, rig_mass_kg};
use forcemap_io::params::ParamValue;
use forcemap_io::topics;
use forcemap_math::model::MODEL_NAMES;

/// The node: [`IdentifierCore`] behind its subscriptions and publishers.
pub async fn run(setup: NodeSetup) -> anyhow::Result<()> {
    let p = setup.params.clone();
    let parameters = RecipeParameters::from_params(&p)?;
    let state_file: Option<PathBuf> = p
        .opt_str("state_file")?
        .filter(|s| !s.is_empty())
        .map(PathBuf::from);
    let fq = setup.fully_qualified_name();
    let resumed = match &state_file {
        Some(path) => IdentifierState::load(path)?.map(|s| (s, path.display().to_string())),
        None => None,
    };
    let status_name = format!("{fq}: identification");
    let (mut core, startup) = IdentifierCore::new(parameters, &status_name, resumed, now_time())?;

    let table = declared_parameters(&setup, &core);
    let (sets_tx, mut sets) = mpsc::unbounded_channel::<SetRequest>();
    let mut ros = RosNode::start_with_parameters(setup.clone(), table.clone(), Some(sets_tx))?;
    let phasors = ros.subscription::<HarmonicPhasors>(topics::PHASORS, qos::phasors())?;
    let provisional =
        ros.subscription::<HarmonicPhasors>(topics::PROVISIONAL_PHASORS, qos::phasors())?;
    let rig = ros.subscription::<DiagnosticStatus>(topics::PARAMETERS, qos::parameters())?;
    // A multisine step's state names the driven channel its lines are found on.
    let excitation = ros.subscription::<ExcitationState>(topics::EXCITATION, qos::excitation())?;
    let theta_pub = ros.publisher::<IdentifiedParameters>(topics::THETA, qos::theta())?;
    let diag_pub = ros.publisher::<DiagnosticArray>(topics::DIAGNOSTICS, qos::diagnostics())?;

    let (tx, mut rx) = mpsc::unbounded_channel::<Input>();
    forward(phasors, tx.clone(), OnTakeError::Warn("phasors"), |m, _| {
        Some(Input::Phasors(Box::new(m)))
    });
    let (ptx, mut provisionals) = mpsc::unbounded_channel::<HarmonicPhasors>();
    forward(
        provisional,
        ptx,
        OnTakeError::Warn("provisional phasors"),
        |m, _| Some(m),
    );
    forward(
        excitation,
        tx.clone(),
        OnTakeError::Warn("an excitation state"),
        |m, _| Some(Input::Excitation(Box::new(m))),
    );
    forward(rig, tx, OnTakeError::Warn("the rig constants"), |m, _| {
        rig_mass_kg(&m).map(Input::RigMass)
    });

    let rp = core.parameters();
    log_line!(
        "identifying model '{}' ({}) by {} with {} weighting from {}",
        core.model().name,
        core.model().symbols().join(", "),
        rp.method.name(),
        rp.weighting.name(),
        setup.absolute_topic(topics::PHASORS)
    );
    let shell = Shell {
        theta_pub: &theta_pub,
        diag_pub: &diag_pub,
        state_file: state_file.as_ref(),
    };
    shell.apply(&core, startup).await?;
    loop {
        tokio::select! {
            // A step's phasors before provisional ones of the next step queued with them.
            biased;
            i = rx.recv() => match i {
                Some(input) => {
                    let traced_step = match &input {
                        Input::Phasors(ph) if latency_trace::enabled() => Some(ph.step),
                        _ => None,
                    };
                    if let Some(step) = traced_step {
                        latency_trace::mark_now("identifier.phasors_in", step, None);
                    }
                    let (outputs, cpu_ns) = latency_trace::cpu_of(|| core.handle(input, now_time()));
                    if let Some(step) = traced_step {
                        latency_trace::mark_now("identifier.solved", step, cpu_ns);
                    }
                    shell.apply(&core, outputs?).await?;
                }
                None => break,
            },
            Some(ph) = provisionals.recv() => {
                shell.apply(&core, core.handle_provisional(&ph)).await?;
            }
            Some(request) = sets.recv() => {
                let (done, outputs) =
                    core.apply_parameters(&request.params, request.atomically, now_time());
                // Theta and status are out before the caller hears the set succeeded.
                shell.apply(&core, outputs).await?;
                for (name, value) in done.applied {
                    table.store(&name, value);
                }
                request.reply(done.results);
            }
            () = crate::ros::shutdown_signal() => break,
        }
    }
    // Give the last messages a moment to leave.
    tokio::time::sleep(Duration::from_millis(200)).await;
    Ok(())
}

/// The identifier's parameters for the parameter services: the settable ones with the values
/// it runs with, and every other one it was given, read-only.
fn declared_parameters(setup: &NodeSetup, core: &IdentifierCore) -> ParameterTable {
    let table = ParameterTable::read_only(&setup.params);
    let p = core.parameters();
    let settable = "; settable while running: the equations are re-solved from the kept phasors and theta is published at once";
    let models: Vec<&str> = MODEL_NAMES.iter().map(|(n, _)| *n).collect();
    for (name, value, description) in [
        (
            "model",
            ParamValue::String(p.model.name.clone()),
            format!("element model, one of {}{settable}", models.join(", ")),
        ),
        (
            "method",
            ParamValue::String(p.method.name()),
            format!("fd-multi or fd (output-error and td need the samples: refused){settable}"),
        ),
        (
            "weighting",
            ParamValue::String(p.weighting.name().to_string()),
            format!("robust, noise or uniform weighting of fd-multi's equations{settable}"),
        ),
        (
            "forgetting_per_step",
            ParamValue::Double(p.tracking.factor_per_step()),
            format!(
                "weight of the steps so far against each new one, in (0, 1]; 1 converges{settable}"
            ),
        ),
    ] {
        table.declare(name, value, &description, false);
    }
    table
}

/// Where the core's outputs go.
struct Shell<'a> {
    theta_pub: &'a ros2_client::Publisher<IdentifiedParameters>,
    diag_pub: &'a ros2_client::Publisher<DiagnosticArray>,
    state_file: Option<&'a PathBuf>,
}

impl Shell<'_> {
    /// Publishes theta first and persists the state next (its write and fsync took
    /// milliseconds), then the status and log lines: what a control node waits for is not
    /// delayed by the rest, and a log line still says its step is persisted.
    async fn apply(&self, core: &IdentifierCore, outputs: Vec<Output>) -> anyhow::Result<()> {
        let (mut first, rest): (Vec<Output>, Vec<Output>) = outputs
            .into_iter()
            .partition(|o| matches!(o, Output::Theta(_)));
        if rest.iter().any(|o| matches!(o, Output::Persist)) {
            first.push(Output::Persist);
        }
        first.extend(rest.into_iter().filter(|o| !matches!(o, Output::Persist)));
        for o in first {
            match o {
                Output::Log(line) => log_line!("{line}"),
                Output::Theta(msg) => {
                    let step = msg.steps_used.last().copied();
                    if let Err(e) = self.theta_pub.async_publish(msg).await {
                        log_line!("error: publishing theta: {e:?}");
                    }
                    if let Some(step) = step {
                        latency_trace::mark_now("identifier.theta_published", step, None);
                    }
                }
                Output::Status(status) => {
                    let _ = self
                        .diag_pub
                        .async_publish(DiagnosticArray {
                            header: Header::new(now_time(), ""),
                            status: vec![status],
                        })
                        .await;
                }
                Output::Persist => {
                    if let (Some(path), Some(st)) = (self.state_file, core.state()) {
                        let (saved, cpu_ns) = latency_trace::cpu_of(|| st.save(path));
                        saved?;
                        if let Some(step) = st.last_step {
                            latency_trace::mark_now("identifier.state_saved", step, cpu_ns);
                        }
                    }
                }
            }
        }
        latency_trace::flush();
        Ok(())
    }
}
