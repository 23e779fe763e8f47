//! `forcemap bench graph`: what the node graph sustains, measured on this machine (a benchmark,
//! not a test: figures go in docs/graph.md with the command that produced them).
//!
//! The harmonic node and the identifier run as separate processes, as in a launch; this
//! process plays the sensor (a simulated rig run published as fast as the graph acknowledges,
//! or at a rate factor) and a control node (it subscribes to theta). With `--rigs N` there are
//! N rigs, each in its own namespace with its own two nodes (a four-poster's corners), fed the
//! same run interleaved sample by sample. It reports:
//! - samples per second published with no loss (every step analysed, none dropped);
//! - latency from the last sample of a step (when its publish returned) to the theta that
//!   includes that step (when it arrived here), p50 and p99 over the steps;
//! - CPU (% of one core) and resident memory of each node, sampled from /proc during the run,
//!   with RSS early and late in the run (memory must stay flat);
//! - with `--trace`, that latency stage by stage ([`super::bench_trace`]).

use std::collections::BTreeMap;
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use forcemap_math::record::Record;
use forcemap_math::sim::RunSpec;
use forcemap_math::sim::excitation::{
    PAPER_RIG_FREQUENCIES_HZ, PAPER_RIG_SINE_AMPLITUDE_M, sine_steps,
};
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::DiagnosticStatus;
use forcemap_msgs::msg::{ExcitationState, IdentifiedParameters, RigSample};
use serde_json::json;

use super::bench_trace;
use crate::cli::BenchGraphArgs;
use forcemap_io::params::Params;
use forcemap_io::rig_messages::{
    RigMessage, SIMULATED_CONSTANTS_MESSAGE, constants_status, rig_messages,
};
use forcemap_io::topics;
use forcemap_nodes::latency_trace::TraceMark;
use forcemap_nodes::ros::{NodeSetup, RosNode, publish_blocking, qos};
use ros2_client::Publisher;

/// CPU time (s) and resident memory (bytes) of a process, from /proc.
fn proc_usage(pid: u32) -> Option<(f64, u64)> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // Fields after the command name (which may hold spaces) in parentheses.
    let rest = &stat[stat.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = 100.0; // USER_HZ on Linux
    let cpu = (f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?) / ticks;
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let rss_kb: u64 = status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))?
        .trim()
        .trim_end_matches(" kB")
        .trim()
        .parse()
        .ok()?;
    Some((cpu, rss_kb * 1024))
}

/// (seconds since the start, node, CPU seconds, RSS bytes).
type UsageSample = (f64, String, f64, u64);

pub fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((p / 100.0) * (sorted.len() - 1) as f64).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

struct Spawned {
    /// `namespace/kind`, e.g. `/rig2/harmonic`.
    name: String,
    child: Child,
    lines: Arc<Mutex<Vec<String>>>,
}

fn spawn(
    kind: &str,
    namespace: &str,
    domain: u16,
    params: &[&str],
    trace: bool,
) -> anyhow::Result<Spawned> {
    let exe = std::env::current_exe().context("finding the forcemap executable")?;
    let ns = format!("__ns:={namespace}");
    let mut args = vec!["node", kind, "--ros-args", "-r", &ns];
    for p in params {
        args.push("-p");
        args.push(p);
    }
    let mut command = Command::new(exe);
    if trace {
        command.env(forcemap_nodes::latency_trace::ENV, "1");
    }
    let mut child = command
        .args(&args)
        .env("ROS_DOMAIN_ID", domain.to_string())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .with_context(|| format!("starting the {kind} node"))?;
    let lines = Arc::new(Mutex::new(Vec::new()));
    for out in [
        Box::new(child.stdout.take().expect("piped")) as Box<dyn std::io::Read + Send>,
        Box::new(child.stderr.take().expect("piped")),
    ] {
        let l = lines.clone();
        std::thread::spawn(move || {
            use std::io::BufRead;
            for line in std::io::BufReader::new(out).lines().map_while(Result::ok) {
                l.lock().expect("lines lock").push(line);
            }
        });
    }
    Ok(Spawned {
        name: format!("{namespace}/{kind}"),
        child,
        lines,
    })
}

/// One rig's side of the bench process: its sensor's publishers, its control node's record of
/// when each step's theta arrived, and its rig constants.
struct BenchRig {
    ros: RosNode,
    samples_pub: Publisher<RigSample>,
    excitation_pub: Publisher<ExcitationState>,
    parameters_pub: Publisher<DiagnosticStatus>,
    /// Last step a theta included -> when it arrived [ns].
    theta_arrivals: Arc<Mutex<BTreeMap<u32, i64>>>,
    constants: DiagnosticStatus,
}

fn now_ns() -> i64 {
    forcemap_nodes::ros::now_time().as_nanos()
}

pub fn run_graph(args: &BenchGraphArgs) -> anyhow::Result<()> {
    if args.steps == 0 {
        bail!("--steps must be at least 1");
    }
    let domain = forcemap_nodes::ros::domain_id()?;
    let (rate, duration) = (args.sample_rate_hz, args.step_duration_s);
    if !(rate.is_finite() && rate > 0.0 && rate <= 1e6) {
        bail!("--sample-rate-hz {rate}: expected a positive rate up to 1 MHz");
    }
    if !(duration.is_finite() && duration > 0.0) {
        bail!("--step-duration-s {duration}: expected a positive duration");
    }
    // The run: the paper's rig at 40 dB, its frequencies cycled, no random records.
    let freqs: Vec<f64> = (0..args.steps)
        .map(|k| PAPER_RIG_FREQUENCIES_HZ[k % PAPER_RIG_FREQUENCIES_HZ.len()])
        .collect();
    let spec = RunSpec {
        sample_rate_hz: rate,
        samples_per_record: (duration * rate).round() as usize,
        steps: sine_steps(&freqs, PAPER_RIG_SINE_AMPLITUDE_M),
        ..RunSpec::paper_rig_sine(Some(40.0), 1)
    };
    if args.rigs == 0 {
        bail!("--rigs must be at least 1");
    }
    let namespaces: Vec<String> = if args.rigs == 1 {
        vec!["/rig".to_string()]
    } else {
        (1..=args.rigs).map(|k| format!("/rig{k}")).collect()
    };
    let setups: Vec<NodeSetup> = namespaces
        .iter()
        .map(|ns| NodeSetup {
            name: "bench_sensor".into(),
            namespace: ns.clone(),
            params: Params::new(),
            remaps: BTreeMap::new(),
        })
        .collect();
    eprintln!(
        "simulating {} steps at {} Hz ...",
        args.steps, args.sample_rate_hz
    );
    let records = spec.simulate().context("simulating the rig")?;
    let samples_per_step = records.first().map_or(0, Record::len);

    let mut children = Vec::new();
    for ns in &namespaces {
        children.push(spawn("harmonic", ns, domain, &[], args.trace)?);
        children.push(spawn(
            "identifier",
            ns,
            domain,
            &["model:=coulomb", "mass_kg:=36.0"],
            args.trace,
        )?);
    }

    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
    let result = rt.block_on(async {
        // One sensor and one theta subscriber per rig, as each corner's bench would have.
        let mut rigs = Vec::new();
        for setup in &setups {
            let mut ros = RosNode::start(setup.clone())?;
            let samples_pub = ros.publisher::<RigSample>(topics::SAMPLES, qos::samples())?;
            let excitation_pub =
                ros.publisher::<ExcitationState>(topics::EXCITATION, qos::excitation())?;
            let parameters_pub =
                ros.publisher::<DiagnosticStatus>(topics::PARAMETERS, qos::parameters())?;
            let theta_sub =
                ros.subscription::<IdentifiedParameters>(topics::THETA, qos::theta())?;
            let received: Arc<Mutex<BTreeMap<u32, i64>>> = Arc::new(Mutex::new(BTreeMap::new()));
            let rec = received.clone();
            tokio::spawn(async move {
                while let Ok((t, _)) = theta_sub.async_take().await {
                    let at = now_ns();
                    if let Some(last) = t.steps_used.last() {
                        rec.lock().expect("lock").entry(*last).or_insert(at);
                    }
                }
            });
            let constants = constants_status(
                SIMULATED_CONSTANTS_MESSAGE,
                &setup.fully_qualified_name(),
                &spec.constants(),
            );
            rigs.push(BenchRig {
                ros,
                samples_pub,
                excitation_pub,
                parameters_pub,
                theta_arrivals: received,
                constants,
            });
        }
        let t0 = Instant::now();
        for BenchRig {
            ros, samples_pub, ..
        } in &rigs
        {
            while samples_pub.get_subscription_count(&ros.node) < 1 {
                if t0.elapsed() > Duration::from_secs(30) {
                    bail!(
                        "the harmonic node of {} did not subscribe within 30 s",
                        ros.setup.namespace
                    );
                }
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
        }
        tokio::time::sleep(Duration::from_millis(500)).await;

        let run_start = Time::from_nanos(now_ns());
        // Every rig plays the same run; its messages differ only by the constants' node name.
        // One run for every rig: the messages differ only in the constants' node name, which
        // each rig's own constants supply when they are published.
        let messages: Vec<RigMessage> =
            rig_messages(&records, spec.driven_channel(), None, run_start, "rig").collect();
        let first_stamp = messages.iter().find_map(|m| match m {
            RigMessage::Sample(s) => Some(s.header.stamp),
            _ => None,
        });
        let pids: Vec<(String, u32)> = children
            .iter()
            .map(|c| (c.name.clone(), c.child.id()))
            .collect();
        let usage: Arc<Mutex<Vec<UsageSample>>> = Arc::new(Mutex::new(Vec::new()));
        let us = usage.clone();
        let sampler_start = Instant::now();
        let sampler = tokio::spawn(async move {
            loop {
                for (name, pid) in &pids {
                    if let Some((cpu, rss)) = proc_usage(*pid) {
                        us.lock().expect("lock").push((
                            sampler_start.elapsed().as_secs_f64(),
                            name.clone(),
                            cpu,
                            rss,
                        ));
                    }
                }
                tokio::time::sleep(Duration::from_millis(250)).await;
            }
        });

        let wall0 = Instant::now();
        // (rig, step) -> when the publish of the step's last sample returned.
        let mut last_sample_at: BTreeMap<(usize, u32), i64> = BTreeMap::new();
        let mut rig_published = vec![0usize; rigs.len()];
        let per_rig_samples = messages
            .iter()
            .filter(|m| matches!(m, RigMessage::Sample(_)))
            .count();
        let bar = indicatif::ProgressBar::new((per_rig_samples * rigs.len()) as u64);
        // Each message to every rig in turn (the rigs interleaved sample by sample), paced by
        // the run's stamps; each rig's constants first.
        for r in &rigs {
            publish_blocking(&r.parameters_pub, r.constants.clone()).await?;
        }
        for m in messages {
            if args.rate_factor > 0.0
                && let (Some(t0s), RigMessage::Sample(s)) = (first_stamp, &m)
            {
                let due = wall0
                    + Duration::from_secs_f64(
                        (s.header.stamp.secs_since(t0s) / args.rate_factor).max(0.0),
                    );
                let now = Instant::now();
                if due > now {
                    tokio::time::sleep(due - now).await;
                }
            }
            let mut m = Some(m);
            for (rig, r) in rigs.iter().enumerate() {
                // The last rig takes the message itself; the others a copy.
                let m = if rig + 1 == rigs.len() {
                    m.take().expect("one message per rig")
                } else {
                    m.clone().expect("one message per rig")
                };
                match m {
                    RigMessage::Sample(s) => {
                        let step = s.step;
                        publish_blocking(&r.samples_pub, s).await?;
                        rig_published[rig] += 1;
                        if rig_published[rig].is_multiple_of(samples_per_step.max(1)) {
                            last_sample_at.insert((rig, step), now_ns());
                        }
                    }
                    RigMessage::Excitation(e) => publish_blocking(&r.excitation_pub, e).await?,
                    RigMessage::Parameters(p) => publish_blocking(&r.parameters_pub, p).await?,
                }
            }
            let published: usize = rig_published.iter().sum();
            if published.is_multiple_of(1000) {
                bar.set_position(published as u64);
            }
        }
        let published: usize = rig_published.iter().sum();
        let publish_s = wall0.elapsed().as_secs_f64();
        bar.finish_and_clear();
        // Wait for every rig's last theta.
        let last_step = (args.steps - 1) as u32;
        let t1 = Instant::now();
        while !rigs.iter().all(|r| {
            r.theta_arrivals
                .lock()
                .expect("lock")
                .contains_key(&last_step)
        }) {
            if t1.elapsed() > Duration::from_secs(60) {
                break;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        let total_s = wall0.elapsed().as_secs_f64();
        sampler.abort();
        let received: BTreeMap<(usize, u32), i64> = rigs
            .iter()
            .enumerate()
            .flat_map(|(rig, r)| {
                r.theta_arrivals
                    .lock()
                    .expect("lock")
                    .iter()
                    .map(|(step, at)| ((rig, *step), *at))
                    .collect::<Vec<_>>()
            })
            .collect();
        let usage = usage.lock().expect("lock").clone();
        Ok::<_, anyhow::Error>((
            published,
            publish_s,
            total_s,
            last_sample_at,
            received,
            usage,
        ))
    });
    // Stop the nodes cleanly.
    for c in &children {
        let _ = nix::sys::signal::kill(
            nix::unistd::Pid::from_raw(c.child.id() as i32),
            nix::sys::signal::Signal::SIGINT,
        );
    }
    for c in &mut children {
        let _ = c.child.wait();
    }
    let (published, publish_s, total_s, last_sample_at, received, usage) = result?;

    let dropped: Vec<String> = children
        .iter()
        .flat_map(|c| c.lines.lock().expect("lock").clone())
        .filter(|l| l.contains("DROPPED"))
        .collect();
    let mut latencies_ms: Vec<f64> = last_sample_at
        .iter()
        .filter_map(|(step, t)| received.get(step).map(|r| (r - t) as f64 / 1e6))
        .collect();
    latencies_ms.sort_by(f64::total_cmp);
    let lossless = dropped.is_empty() && received.len() == args.steps * args.rigs;

    // The stages: the nodes' marks (two children per rig, in the rigs' order) and the bench's.
    let stages = args.trace.then(|| {
        let mut marks: Vec<(usize, TraceMark)> = children
            .iter()
            .enumerate()
            .flat_map(|(i, c)| {
                let lines = c.lines.lock().expect("lock").clone();
                lines
                    .iter()
                    .filter_map(|l| TraceMark::parse(l))
                    .map(|m| (i / 2, m))
                    .collect::<Vec<_>>()
            })
            .collect();
        for (name, at) in [
            (bench_trace::LAST_SAMPLE_PUBLISHED, &last_sample_at),
            (bench_trace::THETA_IN, &received),
        ] {
            marks.extend(at.iter().map(|((rig, step), t)| {
                (
                    *rig,
                    TraceMark {
                        stage: name.to_string(),
                        step: *step,
                        wall_ns: *t,
                        cpu_ns: None,
                    },
                )
            }));
        }
        let steps = bench_trace::per_step(&marks);
        (bench_trace::breakdown(&steps), steps)
    });

    let mut per_node = Vec::new();
    for name in children.iter().map(|c| c.name.as_str()) {
        let s: Vec<&UsageSample> = usage.iter().filter(|u| u.1 == name).collect();
        if s.len() < 2 {
            continue;
        }
        let (first, last) = (s[0], s[s.len() - 1]);
        let cpu_percent = 100.0 * (last.2 - first.2) / (last.0 - first.0).max(1e-9);
        // RSS early (after the first 20 % of the run) and at the end.
        let early = s[s.len() / 5].3;
        let max = s.iter().map(|u| u.3).max().unwrap_or(0);
        per_node.push(json!({
            "node": name, "cpu_percent": cpu_percent,
            "rss_early_mib": early as f64 / 1048576.0, "rss_end_mib": last.3 as f64 / 1048576.0,
            "rss_max_mib": max as f64 / 1048576.0,
        }));
    }
    let mut report = json!({
        "sample_rate_hz": args.sample_rate_hz,
        "steps": args.steps,
        "rigs": args.rigs,
        "samples": published,
        "rate_factor": args.rate_factor,
        "publish_s": publish_s,
        "samples_per_s": published as f64 / publish_s,
        "lossless": lossless,
        "theta_updates": received.len(),
        "dropped": dropped,
        "latency_ms_p50": percentile(&latencies_ms, 50.0),
        "latency_ms_p99": percentile(&latencies_ms, 99.0),
        "latency_ms_max": latencies_ms.last().copied().unwrap_or(f64::NAN),
        "total_s": total_s,
        "nodes": per_node,
    });
    if let Some((rows, steps)) = &stages {
        report["trace"] = bench_trace::json(rows, steps);
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "{} samples at {} Hz ({} rig(s), {} steps of {samples_per_step} each) published in {publish_s:.2} s: {:.0} samples/s, {}",
            published,
            args.sample_rate_hz,
            args.rigs,
            args.steps,
            published as f64 / publish_s,
            if lossless {
                "no loss (every step analysed, theta after each)".to_string()
            } else {
                format!(
                    "LOSS: {} theta updates for {} steps, dropped: {:?}",
                    received.len(),
                    args.steps * args.rigs,
                    dropped
                )
            }
        );
        println!(
            "last sample of a step -> theta: p50 {:.2} ms, p99 {:.2} ms, max {:.2} ms over {} steps of every rig",
            percentile(&latencies_ms, 50.0),
            percentile(&latencies_ms, 99.0),
            latencies_ms.last().copied().unwrap_or(f64::NAN),
            latencies_ms.len()
        );
        for n in &per_node {
            println!(
                "{:<18} CPU {:>5.1} % of a core, RSS {:.1} MiB early, {:.1} MiB at the end (max {:.1})",
                n["node"].as_str().unwrap_or(""),
                n["cpu_percent"].as_f64().unwrap_or(f64::NAN),
                n["rss_early_mib"].as_f64().unwrap_or(f64::NAN),
                n["rss_end_mib"].as_f64().unwrap_or(f64::NAN),
                n["rss_max_mib"].as_f64().unwrap_or(f64::NAN),
            );
        }
        if let Some((rows, steps)) = &stages {
            for l in bench_trace::lines(rows, steps.len()) {
                println!("{l}");
            }
        }
    }
    if !lossless {
        bail!("the graph lost data at this rate");
    }
    Ok(())
}
