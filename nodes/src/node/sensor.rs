//! The sensor node: publishes rig samples, the excitation state of each step and the rig
//! constants. Sources: the built-in simulated rig (default) or the playback of a bag.
//!
//! Parameters:
//! - `source`: `sim` (default) or `bag`;
//! - `bag`: the bag to play (source `bag`);
//! - `rate_factor`: 1.0 plays in real time, 10.0 ten times faster, 0 as fast as the graph
//!   keeps up (reliable publishing that waits for the subscribers' acknowledgements);
//! - `min_subscribers`: wait until this many subscribers listen to the samples (default 1);
//! - `startup_timeout_s`: how long to wait for them (default 20);
//! - sim only: `system` (`rig` or `three_dof`), `case` (`i`/`ii`, 3-DOF), `sample_rate_hz`
//!   (100), `step_duration_s` (13, the paper's 1300 samples at 100 Hz), `snr_db` (40; negative
//!   or `.nan` for noise-free), `seed` (1), `include_random` (true: the two validation
//!   records after the sine steps), `frequencies_hz` (the paper's 1.6 to 3.4 Hz).
//!
//! Stamps: the simulated run starts at the wall-clock time the node starts publishing; a bag is
//! played with the stamps it holds (as `ros2 bag play` does).

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use forcemap_math::record::{Channel, Excitation, Record};
use forcemap_math::sim::excitation::{
    PAPER_RIG_RANDOM_BANDS_HZ, PAPER_RIG_RANDOM_RMS_M, PAPER_RIG_SINE_AMPLITUDE_M, StepSpec,
    paper_rig_random_step,
};
use forcemap_math::sim::{self, RigRun, SimSpec, ThreeDofRun, TruthElement};
use forcemap_msgs::RosMessage;
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::DiagnosticStatus;
use forcemap_msgs::msg::{ExcitationState, RigSample};
use forcemap_msgs::std_msgs::Header;

use crate::log_line;
use crate::ros::{NodeSetup, RosNode, qos};
use forcemap_io::bag::BagReader;
use forcemap_io::topics;

/// One message the sensor publishes, in time order.
pub enum Out {
    Excitation(ExcitationState),
    Sample(RigSample),
    Parameters(DiagnosticStatus),
}

impl Out {
    fn stamp(&self) -> Option<Time> {
        match self {
            Out::Excitation(m) => Some(m.start_time),
            Out::Sample(m) => Some(m.header.stamp),
            Out::Parameters(_) => None,
        }
    }
}

/// The run the simulated rig plays, and its rig constants (with the truth, for summaries).
pub fn simulated_run(
    setup: &NodeSetup,
) -> anyhow::Result<(Vec<Record>, Channel, DiagnosticStatus)> {
    let p = &setup.params;
    let system = p.opt_str("system")?.unwrap_or("rig").to_string();
    let snr_db = p.opt_f64("snr_db")?.unwrap_or(40.0);
    let snr_db = (snr_db.is_finite() && snr_db >= 0.0).then_some(snr_db);
    let seed = p.opt_i64("seed")?.unwrap_or(1);
    if seed < 0 {
        bail!("seed = {seed}: must be a whole number >= 0");
    }
    let seed = seed as u64;
    let mut constants = DiagnosticStatus::new(
        DiagnosticStatus::OK,
        forcemap_io::rig_bag::PARAMETERS_NAME,
        "rig constants (simulated rig; truth.* are the simulator's true element values)",
        setup.fully_qualified_name(),
    );
    let truth_keys = |s: DiagnosticStatus, e: &TruthElement| {
        let mut s = s
            .with_value("truth.k", e.stiffness_n_per_m)
            .with_value("truth.c", e.damping_n_s_per_m);
        if let Some(f) = &e.friction {
            s = s.with_value("truth.fd", f.kinetic_n);
        }
        if e.cubic_stiffness_n_per_m3 != 0.0 {
            s = s.with_value("truth.s", e.cubic_stiffness_n_per_m3);
        }
        s
    };
    match system.as_str() {
        "rig" => {
            let rate = p.opt_f64("sample_rate_hz")?.unwrap_or(100.0);
            let duration = p.opt_f64("step_duration_s")?.unwrap_or(13.0);
            if !(rate.is_finite() && rate > 0.0 && rate <= 1e6) {
                bail!("sample_rate_hz = {rate}: expected a positive rate up to 1 MHz");
            }
            if !(duration.is_finite() && duration > 0.0) {
                bail!("step_duration_s = {duration}: expected a positive duration");
            }
            let samples = (duration * rate).round() as usize;
            let mut run = RigRun {
                snr_db,
                seed,
                sample_rate_hz: rate,
                samples_per_record: samples,
                ..RigRun::paper_sine(TruthElement::rig_coulomb())
            };
            if let Some(f) = p.opt_f64_array("frequencies_hz")? {
                if f.is_empty() || f.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
                    bail!("frequencies_hz: expected a non-empty list of positive frequencies");
                }
                run.steps = f
                    .iter()
                    .map(|&frequency_hz| StepSpec::Sine {
                        frequency_hz,
                        amplitude: PAPER_RIG_SINE_AMPLITUDE_M,
                    })
                    .collect();
            }
            if p.opt_bool("include_random")?.unwrap_or(true) {
                for band in PAPER_RIG_RANDOM_BANDS_HZ {
                    run.steps
                        .push(paper_rig_random_step(band, PAPER_RIG_RANDOM_RMS_M));
                }
            }
            constants = truth_keys(
                constants.with_value("mass_kg", run.nominal_mass_kg),
                &run.element,
            );
            let records = sim::simulate(&SimSpec::Rig(run)).context("simulating the rig")?;
            Ok((records, Channel::BaseDisplacementM, constants))
        }
        "three_dof" => {
            let run = match p.opt_str("case")?.unwrap_or("i") {
                "i" | "I" => ThreeDofRun::case_i(),
                "ii" | "II" => ThreeDofRun::case_ii(),
                other => bail!("case = '{other}': expected i or ii"),
            };
            let run = ThreeDofRun {
                snr_db,
                seed,
                ..run
            };
            constants = truth_keys(constants, &run.element);
            let records =
                sim::simulate(&SimSpec::ThreeDof(run)).context("simulating the 3-DOF example")?;
            Ok((records, Channel::ForceN, constants))
        }
        other => bail!("system = '{other}': expected rig or three_dof"),
    }
}

/// The messages of a simulated run starting at `run_start`, ending with IDLE.
pub fn messages_of(
    records: &[Record],
    driven: Channel,
    constants: DiagnosticStatus,
    run_start: Time,
    frame: &str,
) -> Vec<Out> {
    let mut out = vec![Out::Parameters(constants)];
    let mut end = run_start;
    for r in records {
        let start = run_start.add_secs_f64(r.start_time_s);
        out.push(Out::Excitation(ExcitationState::from_excitation(
            Header::new(start, frame),
            r.step,
            start,
            &r.excitation,
            driven,
            r.len(),
        )));
        for i in 0..r.len() {
            let stamp = run_start.add_secs_f64(r.time_s(i));
            out.push(Out::Sample(RigSample::from_record(
                r,
                i,
                Header::new(stamp, frame),
            )));
        }
        end = run_start.add_secs_f64(r.start_time_s + r.len() as f64 / r.sample_rate_hz);
    }
    let last = records.last().map_or(0, |r| r.step + 1);
    out.push(Out::Excitation(ExcitationState::idle(
        Header::new(end, frame),
        last,
        end,
        driven,
    )));
    out
}

/// The messages of a bag (its samples, excitation and rig-constants topics, recognised by
/// their last name component), in log-time order, ending with IDLE if the bag has none.
fn messages_of_bag(path: &PathBuf) -> anyhow::Result<Vec<Out>> {
    let reader = BagReader::open(path)?;
    let base = |name: &str| name.rsplit('/').next().unwrap_or("").to_string();
    let mut out = Vec::new();
    let mut last: Option<(u32, Time, String)> = None;
    let mut saw_idle = false;
    let mut period = 0.0f64;
    for (i, m) in reader.messages()?.enumerate() {
        let m = m?;
        let topic = &m.topic.name;
        let bad = |e: &dyn std::fmt::Display| {
            anyhow::anyhow!("{}: {topic}, message {i}: {e}", path.display())
        };
        match (base(topic).as_str(), m.topic.type_name.as_str()) {
            (topics::SAMPLES, RigSample::TYPE_NAME) => {
                let s = RigSample::from_cdr(&m.data).map_err(|e| bad(&e))?;
                if let Some((_, t, _)) = &last {
                    let dt = s.header.stamp.secs_since(*t);
                    if dt > 0.0 {
                        period = dt;
                    }
                }
                last = Some((s.step, s.header.stamp, s.header.frame_id.clone()));
                out.push(Out::Sample(s));
            }
            (topics::EXCITATION, ExcitationState::TYPE_NAME) => {
                let s = ExcitationState::from_cdr(&m.data).map_err(|e| bad(&e))?;
                saw_idle |= s.is_idle();
                out.push(Out::Excitation(s));
            }
            (topics::PARAMETERS, DiagnosticStatus::TYPE_NAME) => {
                out.push(Out::Parameters(
                    DiagnosticStatus::from_cdr(&m.data).map_err(|e| bad(&e))?,
                ));
            }
            _ => {}
        }
    }
    let Some((step, t, frame)) = last else {
        bail!(
            "{}: no forcemap_msgs/msg/RigSample messages on a '.../{}' topic",
            path.display(),
            topics::SAMPLES
        );
    };
    if !saw_idle {
        let end = t.add_secs_f64(period);
        out.push(Out::Excitation(ExcitationState::idle(
            Header::new(end, &frame),
            step as usize + 1,
            end,
            Channel::BaseDisplacementM,
        )));
    }
    Ok(out)
}

pub async fn run(setup: NodeSetup) -> anyhow::Result<()> {
    let p = &setup.params;
    let rate_factor = p.opt_f64("rate_factor")?.unwrap_or(1.0);
    if !(rate_factor.is_finite() && rate_factor >= 0.0) {
        bail!(
            "rate_factor = {rate_factor}: expected 0 (as fast as the graph keeps up) or a positive factor"
        );
    }
    let min_subscribers = p.opt_usize("min_subscribers")?.unwrap_or(1);
    let startup_timeout = p.opt_f64("startup_timeout_s")?.unwrap_or(20.0);
    let source = p.opt_str("source")?.unwrap_or("sim").to_string();
    let frame = p.opt_str("frame_id")?.unwrap_or("rig").to_string();

    // Prepare everything before touching the network, so bad input fails fast.
    let prepared = match source.as_str() {
        "sim" => {
            let t0 = Instant::now();
            let (records, driven, constants) = simulated_run(&setup)?;
            log_line!(
                "simulated {} steps ({} samples) in {:.2} s",
                records.len(),
                records.iter().map(Record::len).sum::<usize>(),
                t0.elapsed().as_secs_f64()
            );
            Some((records, driven, constants))
        }
        "bag" => None,
        other => bail!("source = '{other}': expected sim or bag"),
    };
    let bag_messages = if prepared.is_none() {
        let path = PathBuf::from(
            p.opt_str("bag")?
                .context("source = bag needs the parameter bag (the bag to play)")?,
        );
        Some(messages_of_bag(&path)?)
    } else {
        None
    };

    let mut ros = RosNode::start(setup.clone())?;
    let samples_pub = ros.publisher::<RigSample>(topics::SAMPLES, qos::samples())?;
    let excitation_pub = ros.publisher::<ExcitationState>(topics::EXCITATION, qos::excitation())?;
    let parameters_pub =
        ros.publisher::<DiagnosticStatus>(topics::PARAMETERS, qos::parameters())?;

    // Wait for the subscribers that must not miss a sample (the harmonic node, a recorder).
    let deadline = Instant::now() + Duration::from_secs_f64(startup_timeout);
    loop {
        let n = samples_pub.get_subscription_count(&ros.node);
        if n >= min_subscribers {
            break;
        }
        if Instant::now() > deadline {
            bail!(
                "{} subscriber(s) on {} after {startup_timeout} s, {min_subscribers} expected (min_subscribers): is the harmonic node running on the same ROS_DOMAIN_ID?",
                n,
                setup.absolute_topic(topics::SAMPLES)
            );
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    // Discovery of the subscriber's reader completes a little after the count changes.
    tokio::time::sleep(Duration::from_millis(300)).await;

    let messages = match prepared {
        Some((records, driven, constants)) => {
            let run_start = crate::ros::now_time();
            messages_of(&records, driven, constants, run_start, &frame)
        }
        None => bag_messages.unwrap_or_default(),
    };
    let total_samples = messages
        .iter()
        .filter(|m| matches!(m, Out::Sample(_)))
        .count();
    log_line!(
        "publishing {total_samples} samples on {} ({})",
        setup.absolute_topic(topics::SAMPLES),
        if rate_factor == 0.0 {
            "as fast as the graph keeps up".to_string()
        } else {
            format!("{rate_factor}x real time")
        }
    );

    // Stop between two messages on SIGINT/SIGTERM.
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let stop_w = stop.clone();
    tokio::spawn(async move {
        crate::ros::shutdown_signal().await;
        stop_w.store(true, std::sync::atomic::Ordering::SeqCst);
    });
    let first_stamp = messages.iter().find_map(Out::stamp);
    let wall0 = Instant::now();
    let mut published = 0usize;
    let mut last_report = Instant::now();
    for m in messages {
        if stop.load(std::sync::atomic::Ordering::SeqCst) {
            log_line!("stopped after {published} of {total_samples} samples");
            return Ok(());
        }
        if rate_factor > 0.0
            && let (Some(t0), Some(t)) = (first_stamp, m.stamp())
        {
            let due = wall0 + Duration::from_secs_f64((t.secs_since(t0) / rate_factor).max(0.0));
            let now = Instant::now();
            if due > now {
                tokio::time::sleep(due - now).await;
            }
        }
        match m {
            Out::Sample(s) => {
                publish_blocking(&samples_pub, s).await?;
                published += 1;
            }
            Out::Excitation(e) => {
                if e.is_idle() {
                    log_line!(
                        "run complete: exciter idle after step {}",
                        e.step.saturating_sub(1)
                    );
                } else {
                    log_line!("step {}: {}", e.step, describe(&e));
                }
                publish_blocking(&excitation_pub, e).await?;
            }
            Out::Parameters(s) => publish_blocking(&parameters_pub, s).await?,
        }
        if last_report.elapsed() > Duration::from_secs(5) {
            log_line!("{published} of {total_samples} samples published");
            last_report = Instant::now();
        }
    }
    log_line!(
        "published {published} samples in {:.2} s",
        wall0.elapsed().as_secs_f64()
    );
    // Keep the latched topics alive a moment for late joiners, unless told to stay.
    let linger = p.opt_f64("linger_s")?.unwrap_or(2.0);
    let t_end = Instant::now() + Duration::from_secs_f64(linger.max(0.0));
    while Instant::now() < t_end && !stop.load(std::sync::atomic::Ordering::SeqCst) {
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    Ok(())
}

/// Publishes reliably, retrying while the send window is full (flow control: the sensor
/// slows down to what the subscribers acknowledge rather than losing samples).
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

fn describe(e: &ExcitationState) -> String {
    match e.excitation() {
        Ok(Excitation::Sine {
            frequency_hz,
            amplitude,
        }) => format!(
            "sine {frequency_hz:.2} Hz, amplitude {amplitude:.4} ({}), {} samples",
            e.driven_channel, e.sample_count
        ),
        Ok(Excitation::Random { band_hz, rms }) => format!(
            "band random{}, RMS {rms:.4} ({}), {} samples",
            band_hz.map_or(String::new(), |b| format!(" {:.1}-{:.1} Hz", b[0], b[1])),
            e.driven_channel,
            e.sample_count
        ),
        Err(err) => err.to_string(),
    }
}
