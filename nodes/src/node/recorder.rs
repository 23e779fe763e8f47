//! The recorder node: records topics into a rosbag2 MCAP bag.
//!
//! Chunks are closed at least once a second (and on every idle second), so a recorder killed
//! without warning loses at most the last second; `forcemap bag recover` rebuilds such a bag.
//! On SIGINT/SIGTERM the bag is finished (summary, footer, metadata.yaml) and moved into place.
//!
//! Parameters: `bag` (the bag directory to write; required), `topics` (names relative to the
//! namespace or absolute; default: samples, excitation, parameters, phasors, theta,
//! /diagnostics). The type of each topic is known from its last name component (forcemap's
//! topics) or given as `name:pkg/msg/Type`. `overwrite` (false): replace an existing bag there.
//! `log_flushes` (false): log the message count each time a chunk is closed (what a crash
//! would keep).

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use forcemap_msgs::RosMessage;
use forcemap_msgs::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus};
use forcemap_msgs::msg::{
    ExcitationState, GapDiagnosis, HarmonicPhasors, IdentifiedParameters, RigSample,
};
use ros2_client::QosProfile;
use tokio::sync::mpsc;

use crate::log_line;
use crate::ros::{NodeSetup, OnTakeError, RosNode, qos};
use forcemap_io::bag::{BagWriter, QosProfile as BagQos, TopicId, TopicSpec};
use forcemap_io::topics;

const DEFAULT_TOPICS: [&str; 6] = [
    topics::SAMPLES,
    topics::EXCITATION,
    topics::PARAMETERS,
    topics::PHASORS,
    topics::THETA,
    topics::DIAGNOSTICS,
];

/// One received message for the writer.
struct Received {
    topic: usize,
    log_time: u64,
    publish_time: u64,
    cdr: Vec<u8>,
}

/// The type and QoS of one of forcemap's topics, by its last name component or an explicit
/// `pkg/msg/Type`.
fn known_type(name: &str, explicit: Option<&str>) -> anyhow::Result<(&'static str, QosProfile)> {
    let by_type = |t: &str| -> Option<(&'static str, QosProfile)> {
        Some(match t {
            RigSample::TYPE_NAME => (RigSample::TYPE_NAME, qos::samples()),
            ExcitationState::TYPE_NAME => (ExcitationState::TYPE_NAME, qos::excitation()),
            DiagnosticStatus::TYPE_NAME => (DiagnosticStatus::TYPE_NAME, qos::parameters()),
            HarmonicPhasors::TYPE_NAME => (HarmonicPhasors::TYPE_NAME, qos::phasors()),
            IdentifiedParameters::TYPE_NAME => (IdentifiedParameters::TYPE_NAME, qos::theta()),
            DiagnosticArray::TYPE_NAME => (DiagnosticArray::TYPE_NAME, qos::diagnostics()),
            GapDiagnosis::TYPE_NAME => (GapDiagnosis::TYPE_NAME, qos::theta()),
            _ => return None,
        })
    };
    if let Some(t) = explicit {
        return by_type(t).with_context(|| {
            format!("topic {name}: type {t} is not one the recorder knows (forcemap_msgs and diagnostic_msgs types)")
        });
    }
    let base = name.rsplit('/').next().unwrap_or(name);
    let t = match base {
        topics::SAMPLES => RigSample::TYPE_NAME,
        topics::EXCITATION => ExcitationState::TYPE_NAME,
        topics::PARAMETERS => DiagnosticStatus::TYPE_NAME,
        topics::PHASORS => HarmonicPhasors::TYPE_NAME,
        topics::THETA => IdentifiedParameters::TYPE_NAME,
        "diagnostics" => DiagnosticArray::TYPE_NAME,
        topics::DIAGNOSIS => GapDiagnosis::TYPE_NAME,
        _ => bail!(
            "topic {name}: unknown type; write it as {name}:pkg/msg/Type (e.g. forcemap_msgs/msg/RigSample)"
        ),
    };
    Ok(by_type(t).expect("known above"))
}

fn bag_qos(q: &QosProfile) -> BagQos {
    use ros2_client::qos::{Durability, History, Reliability};
    BagQos {
        depth: match q.history {
            History::KeepLast { depth } => depth as u32,
            History::KeepAll => 0,
        },
        reliable: matches!(q.reliability, Reliability::Reliable { .. }),
        transient_local: matches!(q.durability, Durability::TransientLocal),
    }
}

/// Subscribes to `name` with type `M` and forwards every message as CDR.
fn forward<M>(
    ros: &mut RosNode,
    name: &str,
    q: QosProfile,
    index: usize,
    tx: mpsc::UnboundedSender<Received>,
) -> anyhow::Result<()>
where
    M: RosMessage + serde::de::DeserializeOwned + Send + Sync + 'static,
{
    let sub = ros.subscription::<M>(name, q)?;
    crate::ros::forward(sub, tx, OnTakeError::Warn("a message"), move |m, info| {
        let log_time = crate::ros::now_time().as_nanos().max(0) as u64;
        let publish_time = info
            .source_timestamp()
            .map_or(log_time, |t| t.to_nanos().max(0) as u64);
        Some(Received {
            topic: index,
            log_time,
            publish_time,
            cdr: m.to_cdr(),
        })
    });
    Ok(())
}

pub async fn run(setup: NodeSetup) -> anyhow::Result<()> {
    let p = setup.params.clone();
    let bag = PathBuf::from(
        p.opt_str("bag")?
            .context("the recorder needs the parameter bag (the bag directory to write)")?,
    );
    let wanted: Vec<String> = p
        .opt_str_array("topics")?
        .unwrap_or_else(|| DEFAULT_TOPICS.iter().map(|s| s.to_string()).collect());
    if wanted.is_empty() {
        bail!("topics is empty: nothing to record");
    }
    let mut plan = Vec::new();
    for w in &wanted {
        let (name, explicit) = match w.split_once(':') {
            Some((n, t)) => (n.to_string(), Some(t)),
            None => (w.clone(), None),
        };
        let (type_name, q) = known_type(&name, explicit)?;
        plan.push((name, type_name, q));
    }

    if p.opt_bool("overwrite")?.unwrap_or(false) && bag.exists() {
        // Only ever remove a bag (a directory holding metadata.yaml or an .mcap).
        let is_bag = bag.join("metadata.yaml").exists()
            || std::fs::read_dir(&bag).is_ok_and(|d| {
                d.flatten()
                    .any(|e| e.path().extension().is_some_and(|x| x == "mcap"))
            });
        if !is_bag {
            bail!(
                "{} exists and is not a bag; overwrite only replaces bags",
                bag.display()
            );
        }
        std::fs::remove_dir_all(&bag)
            .with_context(|| format!("removing the previous bag {}", bag.display()))?;
    }
    if let Some(parent) = bag.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating {}", parent.display()))?;
    }
    // Create the bag first: a bad path fails before anything is subscribed.
    let mut writer = BagWriter::create(&bag)?;
    let mut ids: Vec<TopicId> = Vec::new();
    let mut ros = RosNode::start(setup.clone())?;
    let (tx, mut rx) = mpsc::unbounded_channel::<Received>();
    for (i, (name, type_name, q)) in plan.iter().enumerate() {
        let absolute = setup.absolute_topic(name);
        let schema = match *type_name {
            RigSample::TYPE_NAME => RigSample::schema(),
            ExcitationState::TYPE_NAME => ExcitationState::schema(),
            DiagnosticStatus::TYPE_NAME => DiagnosticStatus::schema(),
            HarmonicPhasors::TYPE_NAME => HarmonicPhasors::schema(),
            IdentifiedParameters::TYPE_NAME => IdentifiedParameters::schema(),
            GapDiagnosis::TYPE_NAME => GapDiagnosis::schema(),
            _ => DiagnosticArray::schema(),
        };
        let mut spec = TopicSpec::new(&absolute, type_name, &schema);
        spec.offered_qos_profiles = bag_qos(q).to_yaml_string();
        ids.push(writer.add_topic(&spec)?);
        let tx = tx.clone();
        let q = q.clone();
        match *type_name {
            RigSample::TYPE_NAME => forward::<RigSample>(&mut ros, name, q, i, tx)?,
            ExcitationState::TYPE_NAME => forward::<ExcitationState>(&mut ros, name, q, i, tx)?,
            DiagnosticStatus::TYPE_NAME => forward::<DiagnosticStatus>(&mut ros, name, q, i, tx)?,
            HarmonicPhasors::TYPE_NAME => forward::<HarmonicPhasors>(&mut ros, name, q, i, tx)?,
            IdentifiedParameters::TYPE_NAME => {
                forward::<IdentifiedParameters>(&mut ros, name, q, i, tx)?
            }
            GapDiagnosis::TYPE_NAME => forward::<GapDiagnosis>(&mut ros, name, q, i, tx)?,
            _ => forward::<DiagnosticArray>(&mut ros, name, q, i, tx)?,
        }
    }
    drop(tx);
    log_line!("recording {} topics into {}", plan.len(), bag.display());
    let mut tick = tokio::time::interval(Duration::from_millis(250));
    let mut last_flush = Instant::now();
    let mut count = 0u64;
    let log_flushes = p.opt_bool("log_flushes")?.unwrap_or(false);
    loop {
        tokio::select! {
            m = rx.recv() => {
                let Some(m) = m else { break };
                writer.write(ids[m.topic], m.log_time, m.publish_time, &m.cdr)?;
                count += 1;
            }
            _ = tick.tick() => {
                // Close the chunk every second even when nothing else arrives.
                if last_flush.elapsed() >= Duration::from_secs(1) {
                    writer.flush_chunk()?;
                    last_flush = Instant::now();
                    if log_flushes {
                        log_line!("on disk: {count} messages");
                    }
                }
            }
            _ = crate::ros::shutdown_signal() => break,
        }
    }
    // Take what already arrived, then finish.
    while let Ok(m) = rx.try_recv() {
        writer.write(ids[m.topic], m.log_time, m.publish_time, &m.cdr)?;
        count += 1;
    }
    let path = writer.finish()?;
    log_line!("recorded {count} messages into {}", path.display());
    Ok(())
}
