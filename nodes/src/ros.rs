//! What every forcemap node shares: the `--ros-args` command line (node name, namespace,
//! parameters, remaps), the DDS context on `ROS_DOMAIN_ID`, the QoS of each topic, and clean
//! shutdown on SIGINT/SIGTERM.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context as _, bail};
use ros2_client::{
    Context, ContextOptions, MessageInfo, MessageTypeName, Name, Node, NodeName, NodeOptions,
    Publisher, QosProfile, Subscription,
    qos::{Durability, History, WhenFull},
};
use tokio::sync::mpsc;

use crate::parameter_services::{self, ParameterTable, SetRequest};
use forcemap_io::params::{Params, read_params};

/// QoS per topic. Samples: reliable with a deep queue (a step's samples must all arrive).
/// Excitation state, rig constants and the latest theta: transient local, so a late joiner
/// (a control node, a restarted node) gets them at once. Phasors: transient local with a
/// history of a whole run, so that a restarted identifier receives the steps it missed.
pub mod qos {
    use super::*;

    /// The samples writer's history: also its reliable window (unacknowledged samples before
    /// a publish blocks).
    pub const SAMPLES_DEPTH: usize = 10_000;
    /// The samples readers' history: how far a subscribing node may fall behind the samples
    /// that have arrived before it loses any. A reader acknowledges a sample when it reaches
    /// the reader's cache, not when the node takes it, so the writer is never held back by a
    /// slow node, and a KeepLast cache replaces the oldest samples, read or not, once it holds
    /// its depth. With the writer's 10 000, a recorder or harmonic node descheduled for 0.1 s
    /// while the sensor published as fast as acknowledged (about 100 000 samples/s) lost
    /// samples (docs/benchmarks.md, flat memory); 100 000 is 10 s of a 10 kHz rig in real
    /// time and about 1 s flooded, for about 25 MB more per subscriber.
    pub const SAMPLES_READER_DEPTH: usize = 100_000;
    pub const PHASORS_DEPTH: usize = 1_000;

    pub fn samples() -> QosProfile {
        QosProfile::publisher_default()
            .reliability_reliable(WhenFull::Block)
            .history(History::KeepLast {
                depth: SAMPLES_DEPTH,
            })
    }

    /// For nodes that subscribe to samples (history [`SAMPLES_READER_DEPTH`]).
    pub fn samples_reader() -> QosProfile {
        samples().history(History::KeepLast {
            depth: SAMPLES_READER_DEPTH,
        })
    }

    pub fn latched(depth: usize) -> QosProfile {
        QosProfile::publisher_default()
            .reliability_reliable(WhenFull::Wait(Duration::from_millis(500)))
            .durability(Durability::TransientLocal)
            .history(History::KeepLast { depth })
    }

    pub fn excitation() -> QosProfile {
        latched(64)
    }

    pub fn parameters() -> QosProfile {
        latched(1)
    }

    pub fn phasors() -> QosProfile {
        latched(PHASORS_DEPTH)
    }

    pub fn theta() -> QosProfile {
        latched(1)
    }

    /// As ROS tools expect on /diagnostics: reliable, volatile.
    pub fn diagnostics() -> QosProfile {
        QosProfile::publisher_default()
            .reliability_reliable(WhenFull::Wait(Duration::from_millis(100)))
            .history(History::KeepLast { depth: 100 })
    }
}

/// The command line of a node after `--ros-args` (the subset of the rcl arguments forcemap
/// honours: `-p name:=value`, `--params-file FILE`, `-r from:=to` including `__node` and
/// `__ns`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RosArgs {
    pub node_name: Option<String>,
    pub namespace: Option<String>,
    pub params_files: Vec<PathBuf>,
    pub overrides: Vec<String>,
    pub remaps: BTreeMap<String, String>,
}

impl RosArgs {
    /// Parses the arguments of a node. Arguments before `--ros-args` are refused (nodes take
    /// their settings as parameters); `--` ends the ROS arguments.
    pub fn parse(args: &[String]) -> anyhow::Result<RosArgs> {
        let mut out = RosArgs::default();
        let mut it = args.iter().peekable();
        let mut in_ros = false;
        while let Some(a) = it.next() {
            if a == "--ros-args" {
                in_ros = true;
                continue;
            }
            if a == "--" {
                in_ros = false;
                continue;
            }
            if !in_ros {
                bail!(
                    "unexpected argument '{a}': node settings are ROS parameters, e.g. --ros-args -p name:=value or --params-file FILE"
                );
            }
            let mut value = |flag: &str| {
                it.next()
                    .cloned()
                    .with_context(|| format!("{flag} needs a value"))
            };
            match a.as_str() {
                "-p" | "--param" => out.overrides.push(value(a)?),
                "--params-file" => out.params_files.push(PathBuf::from(value(a)?)),
                "-r" | "--remap" => {
                    let v = value(a)?;
                    let Some((from, to)) = v.split_once(":=") else {
                        bail!("remap '{v}': expected from:=to");
                    };
                    match from {
                        "__node" | "__name" => out.node_name = Some(to.to_string()),
                        "__ns" => out.namespace = Some(to.to_string()),
                        _ => {
                            out.remaps.insert(from.to_string(), to.to_string());
                        }
                    }
                }
                "--log-level" | "-e" | "--enclave" => {
                    value(a)?;
                }
                other => bail!(
                    "unknown ROS argument '{other}' (forcemap nodes take -p, --params-file, -r, --log-level)"
                ),
            }
        }
        Ok(out)
    }
}

/// A node's identity and parameters, resolved from its command line.
#[derive(Debug, Clone)]
pub struct NodeSetup {
    pub name: String,
    /// Absolute namespace, e.g. `/rig` (`/` for the root).
    pub namespace: String,
    pub params: Params,
    pub remaps: BTreeMap<String, String>,
}

impl NodeSetup {
    /// Resolves the node's name, namespace and parameters (files in order, then `-p`
    /// overrides), with `default_name` when no `__node` remap is given.
    pub fn from_args(default_name: &str, args: &RosArgs) -> anyhow::Result<NodeSetup> {
        let name = args
            .node_name
            .clone()
            .unwrap_or_else(|| default_name.to_string());
        let namespace = match args.namespace.as_deref() {
            None | Some("") | Some("/") => "/".to_string(),
            Some(ns) if ns.starts_with('/') => ns.trim_end_matches('/').to_string(),
            Some(ns) => format!("/{}", ns.trim_end_matches('/')),
        };
        NodeName::new(&namespace, &name)
            .map_err(|e| anyhow::anyhow!("node name '{name}' in namespace '{namespace}': {e:?}"))?;
        let fq = if namespace == "/" {
            format!("/{name}")
        } else {
            format!("{namespace}/{name}")
        };
        let mut params = Params::new();
        for f in &args.params_files {
            let file = match read_params(f, Some(&fq)) {
                Ok(p) => p,
                // A shared file without an entry for this node is fine (ros2 does the same).
                Err(forcemap_io::params::ParamsError::NoMatchingNode { .. }) => continue,
                Err(e) => return Err(e.into()),
            };
            for (k, v) in file.iter() {
                params.set_with_origin(k, v.clone(), &f.display().to_string());
            }
        }
        for o in &args.overrides {
            params.set_from_override(o)?;
        }
        Ok(NodeSetup {
            name,
            namespace,
            params,
            remaps: args.remaps.clone(),
        })
    }

    pub fn fully_qualified_name(&self) -> String {
        if self.namespace == "/" {
            format!("/{}", self.name)
        } else {
            format!("{}/{}", self.namespace, self.name)
        }
    }

    /// The name of a topic after remapping (relative names stay relative to the namespace).
    pub fn topic_name(&self, name: &str) -> String {
        self.remaps
            .get(name)
            .cloned()
            .unwrap_or_else(|| name.to_string())
    }

    /// The absolute name of a topic, as it appears on the wire and in bags.
    pub fn absolute_topic(&self, name: &str) -> String {
        let n = self.topic_name(name);
        if n.starts_with('/') {
            n
        } else if self.namespace == "/" {
            format!("/{n}")
        } else {
            format!("{}/{n}", self.namespace)
        }
    }
}

/// The wall-clock time, as message stamps carry it.
pub fn now_time() -> forcemap_msgs::builtin_interfaces::Time {
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or_default();
    forcemap_msgs::builtin_interfaces::Time::from_nanos(now.as_nanos() as i64)
}

/// The rig's mass from its constants on the `parameters` topic, if it is there and usable.
pub fn rig_mass_kg(status: &forcemap_msgs::diagnostic_msgs::DiagnosticStatus) -> Option<f64> {
    status
        .values
        .iter()
        .find(|kv| kv.key == "mass_kg")
        .and_then(|kv| kv.value.parse::<f64>().ok())
        .filter(|m| *m > 0.0 && m.is_finite())
}

/// The DDS domain from `ROS_DOMAIN_ID` (0 when unset), checked as ROS does.
pub fn domain_id() -> anyhow::Result<u16> {
    match std::env::var("ROS_DOMAIN_ID") {
        Err(_) => Ok(0),
        Ok(s) if s.trim().is_empty() => Ok(0),
        Ok(s) => match s.trim().parse::<u16>() {
            Ok(d) if d <= 232 => Ok(d),
            _ => bail!("ROS_DOMAIN_ID='{s}': expected a whole number from 0 to 232"),
        },
    }
}

/// A running ROS 2 node: its context, node handle and setup.
pub struct RosNode {
    pub setup: NodeSetup,
    pub node: Node,
    _context: Context,
}

impl RosNode {
    /// Creates the node on `ROS_DOMAIN_ID` and starts its spinner (inside tokio), with the
    /// parameters it was started with served read-only on the parameter services.
    pub fn start(setup: NodeSetup) -> anyhow::Result<RosNode> {
        let table = ParameterTable::read_only(&setup.params);
        Self::start_with_parameters(setup, table, None)
    }

    /// [`RosNode::start`] serving `table` on the parameter services, the sets of its writable
    /// parameters sent into `sets` for the node's loop to apply.
    pub fn start_with_parameters(
        setup: NodeSetup,
        table: ParameterTable,
        sets: Option<mpsc::UnboundedSender<SetRequest>>,
    ) -> anyhow::Result<RosNode> {
        let context = Context::with_options(ContextOptions::new().domain_id(domain_id()?))
            .map_err(|e| anyhow::anyhow!("creating the DDS participant: {e:?}"))?;
        let name = NodeName::new(&setup.namespace, &setup.name)
            .map_err(|e| anyhow::anyhow!("node name: {e:?}"))?;
        // ros2-client's own parameter services are off: forcemap serves them
        // (parameter_services says why).
        let mut node = context
            .new_node(
                name,
                NodeOptions::new()
                    .enable_rosout(true)
                    .start_parameter_services(false),
            )
            .map_err(|e| anyhow::anyhow!("creating node {}: {e:?}", setup.name))?;
        parameter_services::serve(&mut node, &setup.fully_qualified_name(), table, sets)?;
        let spinner = node
            .spinner()
            .map_err(|e| anyhow::anyhow!("starting the node's spinner: {e:?}"))?;
        tokio::spawn(spinner.spin());
        Ok(RosNode {
            setup,
            node,
            _context: context,
        })
    }

    fn ros_name(&self, name: &str) -> anyhow::Result<Name> {
        let n = self.setup.topic_name(name);
        Name::parse(&n).map_err(|e| anyhow::anyhow!("topic name '{n}': {e:?}"))
    }

    pub fn publisher<M: forcemap_msgs::RosMessage + serde::Serialize>(
        &mut self,
        name: &str,
        qos: QosProfile,
    ) -> anyhow::Result<Publisher<M>> {
        let topic = self
            .node
            .create_topic(&self.ros_name(name)?, type_name::<M>(), &qos)
            .map_err(|e| anyhow::anyhow!("topic {name}: {e:?}"))?;
        self.node
            .create_publisher::<M>(&topic, Some(qos))
            .map_err(|e| anyhow::anyhow!("publisher on {name}: {e:?}"))
    }

    pub fn subscription<M: forcemap_msgs::RosMessage + 'static>(
        &mut self,
        name: &str,
        qos: QosProfile,
    ) -> anyhow::Result<Subscription<M>> {
        let topic = self
            .node
            .create_topic(&self.ros_name(name)?, type_name::<M>(), &qos)
            .map_err(|e| anyhow::anyhow!("topic {name}: {e:?}"))?;
        self.node
            .create_subscription::<M>(&topic, Some(qos))
            .map_err(|e| anyhow::anyhow!("subscription to {name}: {e:?}"))
    }
}

/// What a forwarding task ([`forward`]) does when a message cannot be taken (it does not
/// deserialise, or the reader failed).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OnTakeError {
    /// Log `warning: receiving WHAT: ERROR` and go on with the next message.
    Warn(&'static str),
    /// End the task without a word (the subscription goes with it).
    Stop,
}

/// Spawns the task that feeds a node's event loop from a subscription: each message taken is
/// turned into an event by `wrap` (given the message and its info; `None` drops the message)
/// and sent into `tx`. The task ends when the receiver is gone, or at a take error when
/// `on_error` is [`OnTakeError::Stop`]. One helper rather than a loop per topic and node, so
/// that take errors and a closed channel are handled in one place.
pub fn forward<M, E, F>(
    subscription: Subscription<M>,
    tx: mpsc::UnboundedSender<E>,
    on_error: OnTakeError,
    wrap: F,
) -> tokio::task::JoinHandle<()>
where
    M: serde::de::DeserializeOwned + Send + Sync + 'static,
    E: Send + 'static,
    F: FnMut(M, MessageInfo) -> Option<E> + Send + 'static,
{
    forward_shared(std::sync::Arc::new(subscription), tx, on_error, wrap)
}

/// [`forward`] for a subscription the node still asks about (its matched publishers).
pub fn forward_shared<M, E, F>(
    subscription: std::sync::Arc<Subscription<M>>,
    tx: mpsc::UnboundedSender<E>,
    on_error: OnTakeError,
    mut wrap: F,
) -> tokio::task::JoinHandle<()>
where
    M: serde::de::DeserializeOwned + Send + Sync + 'static,
    E: Send + 'static,
    F: FnMut(M, MessageInfo) -> Option<E> + Send + 'static,
{
    tokio::spawn(async move {
        loop {
            match subscription.async_take().await {
                Ok((m, info)) => {
                    if let Some(event) = wrap(m, info)
                        && tx.send(event).is_err()
                    {
                        break;
                    }
                }
                Err(e) => match on_error {
                    OnTakeError::Warn(what) => {
                        crate::log_line!("warning: receiving {what}: {e:?}");
                    }
                    OnTakeError::Stop => break,
                },
            }
        }
    })
}

/// Waits until `publisher` has `min` matched subscribers, logging what it waits for. `Ok(false)`
/// when SIGINT/SIGTERM came first; an error naming the topic and `parameter` (the node's
/// parameter that set `min`) once `deadline` has passed. Publishers that end quickly (a sensor
/// flooding the graph, then gone) wait this way for every node that must see the whole run.
pub async fn wait_for_subscribers<M: serde::Serialize>(
    node: &Node,
    publisher: &Publisher<M>,
    min: usize,
    topic: &str,
    parameter: &str,
    deadline: std::time::Instant,
    startup_timeout_s: f64,
) -> anyhow::Result<bool> {
    crate::log_line!("waiting for {min} subscriber(s) on {topic}");
    loop {
        let n = publisher.get_subscription_count(node);
        if n >= min {
            return Ok(true);
        }
        if shutdown_requested() {
            crate::log_line!("stopped while waiting for subscribers");
            return Ok(false);
        }
        if std::time::Instant::now() > deadline {
            anyhow::bail!(
                "{n} subscriber(s) on {topic} after {startup_timeout_s} s, {min} expected ({parameter}): are the nodes that listen running on the same ROS_DOMAIN_ID?"
            );
        }
        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
    }
}

/// Publishes reliably, retrying while the send window is full (flow control: a publisher
/// slows down to what the subscribers acknowledge rather than losing messages). Gives up
/// after a minute of failures.
pub async fn publish_blocking<M: serde::Serialize + Clone>(
    publisher: &ros2_client::Publisher<M>,
    message: M,
) -> anyhow::Result<()> {
    let mut tries = 0;
    loop {
        match publisher.async_publish(message.clone()).await {
            Ok(()) => return Ok(()),
            Err(e) => {
                tries += 1;
                if tries > 600 {
                    bail!("publishing failed for a minute: {e}");
                }
                tokio::time::sleep(Duration::from_millis(100)).await;
            }
        }
    }
}

/// `pkg/msg/Type` as ros2-client wants it.
pub fn type_name<M: forcemap_msgs::RosMessage>() -> MessageTypeName {
    let mut parts = M::TYPE_NAME.split('/');
    let pkg = parts.next().unwrap_or("");
    let ty = parts.next_back().unwrap_or("");
    MessageTypeName::new(pkg, ty)
}

/// The process's shutdown flag: set once SIGINT or SIGTERM has arrived.
static SHUTDOWN: std::sync::OnceLock<tokio::sync::watch::Sender<bool>> = std::sync::OnceLock::new();

/// Installs the SIGINT/SIGTERM listener once per process (inside a tokio runtime) and returns
/// the flag it sets. One listener for the process's life, rather than one per wait: tokio
/// delivers a signal only to the receivers that exist when it arrives, so a handler created
/// per loop iteration lost a SIGTERM that came while the node was busy between two waits
/// (a harmonic node then ignored the launcher's SIGTERM and never stopped).
fn shutdown_flag() -> &'static tokio::sync::watch::Sender<bool> {
    SHUTDOWN.get_or_init(|| {
        use tokio::signal::unix::{SignalKind, signal};
        let (tx, _) = tokio::sync::watch::channel(false);
        // Registered here, synchronously, so that from now on a signal is not lost.
        let term = signal(SignalKind::terminate());
        let int = signal(SignalKind::interrupt());
        match (term, int) {
            (Ok(mut term), Ok(mut int)) => {
                let tx = tx.clone();
                tokio::spawn(async move {
                    tokio::select! {
                        _ = term.recv() => {}
                        _ = int.recv() => {}
                    }
                    tx.send_replace(true);
                });
            }
            (Err(e), _) | (_, Err(e)) => {
                eprintln!(
                    "warning: cannot listen for SIGINT/SIGTERM ({e}); stop the node with SIGKILL"
                );
            }
        }
        tx
    })
}

/// Whether SIGINT or SIGTERM has arrived, for loops that poll rather than wait.
pub fn shutdown_requested() -> bool {
    *shutdown_flag().borrow()
}

/// How long a node has after SIGINT/SIGTERM to stop by itself (a recorder finishing its bag)
/// before [`run_node`] ends it; below the launcher's 10 s before SIGKILL.
const SHUTDOWN_GRACE: std::time::Duration = std::time::Duration::from_secs(5);

/// Resolves once SIGINT or SIGTERM has arrived (at once if one already has).
pub async fn shutdown_signal() {
    let mut flag = shutdown_flag().subscribe();
    // The sender lives in a static, so the channel never closes.
    let _ = flag.wait_for(|stopped| *stopped).await;
}

/// Runs a node's main future on a tokio runtime, stopping it cleanly on SIGINT/SIGTERM.
pub fn run_node<F, Fut>(main: F) -> anyhow::Result<()>
where
    F: FnOnce() -> Fut,
    Fut: std::future::Future<Output = anyhow::Result<()>>,
{
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
    rt.block_on(async {
        // Listen from the start, before the node's main future runs.
        shutdown_flag();
        let main = main();
        tokio::pin!(main);
        tokio::select! {
            result = &mut main => result,
            () = async {
                shutdown_signal().await;
                tokio::time::sleep(SHUTDOWN_GRACE).await;
            } => Err(anyhow::anyhow!(
                "did not stop within {} s of SIGINT/SIGTERM; ended",
                SHUTDOWN_GRACE.as_secs()
            )),
        }
    })
}

/// Prints a line of the node's log to stdout at once (the launcher prefixes it with the node
/// name; stdout of a child process is a pipe, so flush every line).
#[macro_export]
macro_rules! log_line {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let mut out = std::io::stdout().lock();
        let _ = writeln!(out, $($arg)*);
        let _ = out.flush();
    }};
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(s: &str) -> Vec<String> {
        s.split_whitespace().map(str::to_string).collect()
    }

    #[test]
    fn ros_args_give_name_namespace_params_and_remaps() {
        let a = RosArgs::parse(&args(
            "--ros-args -r __node:=ident -r __ns:=/bench -p model:=coulomb -p mass_kg:=36 -r theta:=/ctrl/theta",
        ))
        .unwrap();
        let s = NodeSetup::from_args("identifier", &a).unwrap();
        assert_eq!(s.fully_qualified_name(), "/bench/ident");
        assert_eq!(s.params.get_str("model").unwrap(), "coulomb");
        assert_eq!(s.params.get_f64("mass_kg").unwrap(), 36.0);
        assert_eq!(s.absolute_topic("theta"), "/ctrl/theta");
        assert_eq!(s.absolute_topic("samples"), "/bench/samples");
        assert_eq!(s.absolute_topic("/diagnostics"), "/diagnostics");
    }

    #[test]
    fn bad_arguments_are_named() {
        let e = RosArgs::parse(&args("--model coulomb")).unwrap_err();
        assert!(e.to_string().contains("'--model'"), "{e}");
        let e = RosArgs::parse(&args("--ros-args -p")).unwrap_err();
        assert!(e.to_string().contains("-p needs a value"), "{e}");
        let e = RosArgs::parse(&args("--ros-args -r samples")).unwrap_err();
        assert!(e.to_string().contains("from:=to"), "{e}");
        let a = RosArgs::parse(&args("--ros-args -p mass_kg")).unwrap();
        let e = NodeSetup::from_args("x", &a).unwrap_err();
        assert!(e.to_string().contains("mass_kg"), "{e}");
    }
}
