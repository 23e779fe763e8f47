//! The ROS 2 nodes, thin adapters around forcemap_math: each runs as its own process
//! (`forcemap node KIND --ros-args ...`), as `forcemap launch` starts them.
//!
//! - [`sensor`]: rig samples, excitation state and rig constants (simulated rig or bag);
//! - [`harmonic`]: per-step phasors;
//! - [`identifier`]: accumulated equations and live theta;
//! - [`recorder`]: topics into a rosbag2 MCAP bag;
//! - [`monitor`]: prints live theta and a summary at the end of a run;
//! - [`diagnoser`]: the gap diagnosis of a baseline model, live from the phasors;
//! - [`foreign`]: rig samples from a bench's own topics, through a channel map.

pub mod diagnoser;
pub mod foreign;
pub mod harmonic;
pub mod identifier;
pub mod monitor;
pub mod recorder;
pub mod sensor;
pub mod setup_gate;

use crate::ros::{NodeSetup, RosArgs, run_node};

/// The node kinds, as `exec` names in launch files.
pub const KINDS: [&str; 7] = [
    "sensor",
    "harmonic",
    "identifier",
    "recorder",
    "monitor",
    "diagnoser",
    "foreign",
];

/// Runs the node `kind` with its ROS arguments until it is done or stopped.
pub fn run(kind: &str, args: &[String]) -> anyhow::Result<()> {
    let ros_args = RosArgs::parse(args)?;
    let setup = NodeSetup::from_args(kind, &ros_args)?;
    match kind {
        "sensor" => run_node(|| sensor::run(setup)),
        "harmonic" => run_node(|| harmonic::run(setup)),
        "identifier" => run_node(|| identifier::run(setup)),
        "recorder" => run_node(|| recorder::run(setup)),
        "monitor" => run_node(|| monitor::run(setup)),
        "diagnoser" => run_node(|| diagnoser::run(setup)),
        "foreign" => run_node(|| foreign::run(setup)),
        other => anyhow::bail!(
            "unknown node '{other}': forcemap's nodes are {}",
            KINDS.join(", ")
        ),
    }
}
