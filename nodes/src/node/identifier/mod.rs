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

mod core;
mod reconfigure;
mod state;

pub use crate::node::setup_gate::Input;
pub use core::{IdentifierCore, Output, RecipeParameters, theta_line};
pub use reconfigure::{Refusal, SETTABLE, Setting};
pub use state::{Admit, IdentifierState, admit};

use std::path::PathBuf;
use std::time::Duration;

use forcemap_msgs::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus};
use forcemap_msgs::msg::{HarmonicPhasors, IdentifiedParameters};
use forcemap_msgs::std_msgs::Header;
use tokio::sync::mpsc;

use crate::log_line;
use crate::ros::{NodeSetup, OnTakeError, RosNode, forward, now_time, qos, rig_mass_kg};
use forcemap_io::topics;

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
        let input = tokio::select! {
            i = rx.recv() => match i { Some(i) => i, None => break },
            () = crate::ros::shutdown_signal() => break,
        };
        let outputs = core.handle(input, now_time())?;
        shell.apply(&core, outputs).await?;
    }
    // Give the last messages a moment to leave.
    tokio::time::sleep(Duration::from_millis(200)).await;
    Ok(())
}

/// Where the core's outputs go.
struct Shell<'a> {
    theta_pub: &'a ros2_client::Publisher<IdentifiedParameters>,
    diag_pub: &'a ros2_client::Publisher<DiagnosticArray>,
    state_file: Option<&'a PathBuf>,
}

impl Shell<'_> {
    async fn apply(&self, core: &IdentifierCore, outputs: Vec<Output>) -> anyhow::Result<()> {
        for o in outputs {
            match o {
                Output::Log(line) => log_line!("{line}"),
                Output::Theta(msg) => {
                    if let Err(e) = self.theta_pub.async_publish(msg).await {
                        log_line!("error: publishing theta: {e:?}");
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
                        st.save(path)?;
                    }
                }
            }
        }
        Ok(())
    }
}
