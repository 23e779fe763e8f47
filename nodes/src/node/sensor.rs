//! The sensor node: publishes rig samples, the excitation state of each step and the rig
//! constants. Sources: the built-in simulated rig (default) or the playback of a bag.
//!
//! Parameters:
//! - `source`: `sim` (default) or `bag`;
//! - `bag`: the bag to play (source `bag`);
//! - `rate_factor`: 1.0 plays in real time, 10.0 ten times faster, 0 as fast as the graph
//!   keeps up (reliable publishing that waits for the subscribers' acknowledgements);
//! - `min_subscribers`: wait until this many subscribers listen to the samples (default 1);
//! - `min_excitation_subscribers`: and until this many listen to the excitation state
//!   (default 1; a launch file with a monitor or diagnoser counts them, as the run's end is
//!   the idle state they must not miss);
//! - `startup_timeout_s`: how long to wait for them all (default 20);
//! - sim only: `system` (`rig` or `three_dof`), `case` (`i`/`ii`, 3-DOF), `sample_rate_hz`
//!   (100), `step_duration_s` (13, the paper's 1300 samples at 100 Hz), `snr_db` (40; negative
//!   or `.nan` for noise-free), `seed` (1), `include_random` (true: the two validation
//!   records after the sine steps), `frequencies_hz` (the paper's 1.6 to 3.4 Hz).
//!
//! Stamps: the simulated run starts at the wall-clock time the node starts publishing; a bag is
//! played with the stamps it holds (as `ros2 bag play` does).

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use forcemap_math::record::{Channel, Excitation, Record};
use forcemap_math::sim::excitation::{
    PAPER_RIG_SINE_AMPLITUDE_M, paper_rig_random_steps, sine_steps,
};
use forcemap_math::sim::{RunSpec, ThreeDofCase};
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::DiagnosticStatus;
use forcemap_msgs::msg::{ExcitationState, RigSample};

use crate::log_line;
use crate::ros::{NodeSetup, RosNode, publish_blocking, qos};
use forcemap_io::params::Params;
use forcemap_io::rig_bag::{RigBagReader, RigTopic};
use forcemap_io::rig_messages::{
    RigMessage, SIMULATED_CONSTANTS_MESSAGE, constants_status, idle_after, record_sample,
    record_state,
};
use forcemap_io::topics;

/// The run the simulated rig plays, from the node's parameters.
fn run_spec(p: &Params) -> anyhow::Result<RunSpec> {
    let system = p.opt_str("system")?.unwrap_or("rig").to_string();
    let snr_db = p.opt_f64("snr_db")?.unwrap_or(40.0);
    let snr_db = (snr_db.is_finite() && snr_db >= 0.0).then_some(snr_db);
    let seed = p.opt_i64("seed")?.unwrap_or(1);
    if seed < 0 {
        bail!("seed = {seed}: must be a whole number >= 0");
    }
    let seed = seed as u64;
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
            let mut spec = RunSpec {
                sample_rate_hz: rate,
                samples_per_record: (duration * rate).round() as usize,
                ..RunSpec::paper_rig_sine(snr_db, seed)
            };
            if let Some(f) = p.opt_f64_array("frequencies_hz")? {
                if f.is_empty() || f.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
                    bail!("frequencies_hz: expected a non-empty list of positive frequencies");
                }
                spec.steps = sine_steps(&f, PAPER_RIG_SINE_AMPLITUDE_M);
            }
            if p.opt_bool("include_random")?.unwrap_or(true) {
                spec.steps.extend(paper_rig_random_steps());
            }
            Ok(spec)
        }
        "three_dof" => {
            let case = match p.opt_str("case")?.unwrap_or("i") {
                "i" | "I" => ThreeDofCase::I,
                "ii" | "II" => ThreeDofCase::Ii,
                other => bail!("case = '{other}': expected i or ii"),
            };
            Ok(RunSpec::three_dof(case, snr_db, seed))
        }
        other => bail!("system = '{other}': expected rig or three_dof"),
    }
}

/// The messages of a bag (its samples, excitation and rig-constants topics, recognised by
/// their last name component), in log-time order, ending with IDLE if the bag has none.
/// Where the sensor's messages come from: the simulated rig or a bag (foreign topics arrive
/// through the `foreign` node instead, which does not pace them). A source is prepared before the node touches the network, so bad
/// input fails fast; its messages are taken once the subscribers listen.
pub trait SampleSource: Send {
    /// How many samples the run publishes (for progress).
    fn sample_count(&self) -> usize;

    /// The messages in publishing order, for a run that starts now at `run_start` (a bag keeps
    /// the stamps it holds, as `ros2 bag play` does); an error ends the run.
    fn messages(
        self: Box<Self>,
        run_start: Time,
    ) -> Box<dyn Iterator<Item = anyhow::Result<RigMessage>> + Send>;
}

/// The simulated run of a [`RunSpec`], stamped from the moment it is published, simulated
/// record by record while it is published (a simulator thread a bounded queue of records
/// ahead of the publisher), so that memory stays flat however long the run: the records of the
/// whole-run simulation bit for bit ([`RunSpec::simulate_streamed`]).
pub struct SimulatedRun {
    spec: RunSpec,
    samples: usize,
    driven: Channel,
    constants: DiagnosticStatus,
    frame: String,
}

/// Records the simulator thread may be ahead of the publisher.
const SIMULATION_QUEUE: usize = 1;

impl SimulatedRun {
    /// Checks `spec` (bad input fails here, before the network); the simulation runs while
    /// the messages are taken.
    pub fn new(spec: &RunSpec, node_name: &str, frame: &str) -> anyhow::Result<SimulatedRun> {
        if spec.samples_per_record == 0 || spec.steps.is_empty() {
            bail!("{} needs steps and samples", spec.system.description());
        }
        Ok(SimulatedRun {
            spec: spec.clone(),
            samples: spec.program().total_samples(),
            driven: spec.driven_channel(),
            constants: constants_status(SIMULATED_CONSTANTS_MESSAGE, node_name, &spec.constants()),
            frame: frame.to_string(),
        })
    }
}

impl SampleSource for SimulatedRun {
    fn sample_count(&self) -> usize {
        self.samples
    }

    fn messages(
        self: Box<Self>,
        run_start: Time,
    ) -> Box<dyn Iterator<Item = anyhow::Result<RigMessage>> + Send> {
        let SimulatedRun {
            spec,
            driven,
            constants,
            frame,
            ..
        } = *self;
        let (tx, rx) = std::sync::mpsc::sync_channel(SIMULATION_QUEUE);
        std::thread::spawn(move || {
            let t0 = Instant::now();
            let result = spec.simulate_streamed(|r| tx.send(Ok(r)).is_ok());
            match result {
                Ok(()) => log_line!(
                    "simulated {} ({} steps) in {:.2} s",
                    spec.system.description(),
                    spec.steps.len(),
                    t0.elapsed().as_secs_f64()
                ),
                // The publisher stops at the error and exits with it.
                Err(e) => {
                    let _ = tx.send(Err(anyhow::Error::new(e)
                        .context(format!("simulating {}", spec.system.description()))));
                }
            }
        });
        // Each record's state then its samples, the IDLE state after the last record.
        let mut records = rx.into_iter();
        let mut current: Option<(Record, usize)> = None;
        let mut last: Option<Record> = None;
        let mut done = false;
        let stream = std::iter::from_fn(move || {
            if let Some((r, i)) = &mut current {
                if *i < r.len() {
                    *i += 1;
                    return Some(Ok(record_sample(r, *i - 1, run_start, &frame)));
                }
                last = current.take().map(|(r, _)| r);
            }
            if done {
                return None;
            }
            match records.next() {
                Some(Ok(r)) => {
                    let state = record_state(&r, driven, run_start, &frame);
                    current = Some((r, 0));
                    Some(Ok(state))
                }
                Some(Err(e)) => {
                    done = true;
                    Some(Err(e))
                }
                None => {
                    done = true;
                    Some(Ok(idle_after(last.as_ref(), driven, run_start, &frame)))
                }
            }
        });
        Box::new(std::iter::once(Ok(RigMessage::Parameters(constants))).chain(stream))
    }
}

/// The rig messages of a bag, played with their own stamps, streamed from the file (a reader
/// thread a bounded queue ahead of the publisher), so that memory stays flat however long the
/// bag.
pub struct BagPlayback {
    path: PathBuf,
    samples: usize,
}

/// Messages the reader thread may be ahead of the publisher.
const PLAYBACK_QUEUE: usize = 4096;

impl BagPlayback {
    /// Opens the bag and checks its rig topics (bad input fails here, before the network).
    pub fn open(path: &Path) -> anyhow::Result<BagPlayback> {
        let reader = RigBagReader::open(path)?;
        Ok(BagPlayback {
            path: path.to_path_buf(),
            samples: reader.message_count(RigTopic::Samples) as usize,
        })
    }
}

impl SampleSource for BagPlayback {
    fn sample_count(&self) -> usize {
        self.samples
    }

    fn messages(
        self: Box<Self>,
        _run_start: Time,
    ) -> Box<dyn Iterator<Item = anyhow::Result<RigMessage>> + Send> {
        let (tx, rx) = std::sync::mpsc::sync_channel(PLAYBACK_QUEUE);
        let path = self.path;
        std::thread::spawn(move || {
            let result = RigBagReader::open(&path)
                .and_then(|r| r.stream_playback(|m| tx.send(Ok(m)).is_ok()));
            if let Err(e) = result {
                // The publisher stops at the error and exits with it.
                let _ = tx.send(Err(anyhow::Error::new(e)));
            }
        });
        Box::new(rx.into_iter())
    }
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
    let min_excitation_subscribers = p.opt_usize("min_excitation_subscribers")?.unwrap_or(1);
    let startup_timeout = p.opt_f64("startup_timeout_s")?.unwrap_or(20.0);
    let source = p.opt_str("source")?.unwrap_or("sim").to_string();
    let frame = p.opt_str("frame_id")?.unwrap_or("rig").to_string();

    // Prepare everything before touching the network, so bad input fails fast.
    let source: Box<dyn SampleSource> = match source.as_str() {
        "sim" => Box::new(SimulatedRun::new(
            &run_spec(p)?,
            &setup.fully_qualified_name(),
            &frame,
        )?),
        "bag" => Box::new(BagPlayback::open(Path::new(
            p.opt_str("bag")?
                .context("source = bag needs the parameter bag (the bag to play)")?,
        ))?),
        other => bail!("source = '{other}': expected sim or bag"),
    };

    let mut ros = RosNode::start(setup.clone())?;
    let samples_pub = ros.publisher::<RigSample>(topics::SAMPLES, qos::samples())?;
    let excitation_pub = ros.publisher::<ExcitationState>(topics::EXCITATION, qos::excitation())?;
    let parameters_pub =
        ros.publisher::<DiagnosticStatus>(topics::PARAMETERS, qos::parameters())?;

    // Wait for the subscribers that must not miss a sample (the harmonic node, a recorder),
    // then for those that must see every excitation state (a monitor, a diagnoser): a run
    // published as fast as the graph keeps up is over in a second, and a node that has not
    // matched the excitation writer by the time the sensor is gone never sees the run end.
    let deadline = Instant::now() + Duration::from_secs_f64(startup_timeout);
    if !crate::ros::wait_for_subscribers(
        &ros.node,
        &samples_pub,
        min_subscribers,
        &setup.absolute_topic(topics::SAMPLES),
        "min_subscribers",
        deadline,
        startup_timeout,
    )
    .await?
        || !crate::ros::wait_for_subscribers(
            &ros.node,
            &excitation_pub,
            min_excitation_subscribers,
            &setup.absolute_topic(topics::EXCITATION),
            "min_excitation_subscribers",
            deadline,
            startup_timeout,
        )
        .await?
    {
        return Ok(());
    }
    // Discovery of the subscriber's reader completes a little after the count changes.
    tokio::time::sleep(Duration::from_millis(300)).await;

    let total_samples = source.sample_count();
    let messages = source.messages(crate::ros::now_time());
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
    // The run's time origin: the first stamped message, due at once (the constants before it
    // are not timed).
    let mut first_stamp: Option<Time> = None;
    let wall0 = Instant::now();
    let mut published = 0usize;
    let mut last_report = Instant::now();
    for m in messages {
        let m = m?;
        if first_stamp.is_none() {
            first_stamp = m.stamp();
        }
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
            RigMessage::Sample(s) => {
                publish_blocking(&samples_pub, s).await?;
                published += 1;
            }
            RigMessage::Excitation(e) => {
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
            RigMessage::Parameters(s) => publish_blocking(&parameters_pub, s).await?,
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
        // The state carries the band, not the lines (its subscribers find them in the data).
        Ok(Excitation::Multisine {
            base_frequency_hz,
            rms,
            ..
        }) => format!(
            "periodic multisine, lines of {base_frequency_hz} Hz over {}-{} Hz, RMS {rms:.4} ({}), {} samples",
            e.band_low_hz, e.band_high_hz, e.driven_channel, e.sample_count
        ),
        Ok(Excitation::Sweep { law }) => format!(
            "{:?} sweep {}-{} Hz, amplitude {:.4} ({}), {} samples",
            law.kind,
            law.start_frequency_hz,
            law.end_frequency_hz,
            law.amplitude,
            e.driven_channel,
            e.sample_count
        ),
        Err(err) => err.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use forcemap_io::params::ParamValue;

    #[test]
    fn the_default_simulated_run_is_the_paper_rig_run() {
        let spec = run_spec(&Params::new()).unwrap();
        assert_eq!(spec, RunSpec::paper_rig(Some(40.0), 1));
    }

    #[test]
    fn parameters_shape_the_run() {
        let mut p = Params::new();
        p.set("sample_rate_hz", ParamValue::Double(200.0));
        p.set("step_duration_s", ParamValue::Double(2.0));
        p.set("snr_db", ParamValue::Double(f64::NAN));
        p.set("seed", ParamValue::Integer(4));
        p.set("include_random", ParamValue::Bool(false));
        p.set("frequencies_hz", ParamValue::DoubleArray(vec![2.0, 3.0]));
        let spec = run_spec(&p).unwrap();
        assert_eq!(
            spec,
            RunSpec {
                sample_rate_hz: 200.0,
                samples_per_record: 400,
                steps: sine_steps(&[2.0, 3.0], PAPER_RIG_SINE_AMPLITUDE_M),
                ..RunSpec::paper_rig_sine(None, 4)
            }
        );
        let mut p = Params::new();
        p.set("system", ParamValue::String("three_dof".into()));
        p.set("case", ParamValue::String("ii".into()));
        let spec = run_spec(&p).unwrap();
        assert_eq!(spec, RunSpec::three_dof(ThreeDofCase::Ii, Some(40.0), 1));
        assert_eq!(spec.driven_channel(), Channel::ForceN);
    }

    /// The sensor's messages of the default run (simulated while published) are those of the
    /// whole-run simulation, and its samples those of the committed bag of the same run
    /// (`bags/rig_40db`, written by the simulator before it streamed) bit for bit.
    #[test]
    fn the_streamed_simulated_run_is_the_whole_run_and_the_committed_bag() {
        use forcemap_io::rig_bag::{DEFAULT_RUN_START, read_rig_messages};
        use forcemap_io::rig_messages::rig_messages;
        use forcemap_msgs::RosMessage as _;
        let spec = run_spec(&Params::new()).unwrap();
        let run = SimulatedRun::new(&spec, "/rig/sensor", "rig").unwrap();
        assert_eq!(run.sample_count(), 12 * 1300);
        let constants = run.constants.clone();
        let streamed: Vec<RigMessage> = Box::new(run)
            .messages(DEFAULT_RUN_START)
            .map(Result::unwrap)
            .collect();
        let whole = spec.simulate().unwrap();
        let expected: Vec<RigMessage> = rig_messages(
            &whole,
            spec.driven_channel(),
            Some(constants),
            DEFAULT_RUN_START,
            "rig",
        )
        .collect();
        // Compared as their CDR bytes (a channel the rig lacks is NaN, which is not == NaN).
        let cdr = |m: &[RigMessage]| -> Vec<Vec<u8>> {
            m.iter()
                .map(|m| match m {
                    RigMessage::Sample(s) => s.to_cdr(),
                    RigMessage::Excitation(e) => e.to_cdr(),
                    RigMessage::Parameters(p) => p.to_cdr(),
                })
                .collect()
        };
        assert!(cdr(&streamed) == cdr(&expected), "streamed messages differ");

        let bag = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../bags/rig_40db");
        let samples = |m: &[RigMessage]| -> Vec<Vec<u8>> {
            m.iter()
                .filter_map(|m| match m {
                    RigMessage::Sample(s) => Some(s.to_cdr()),
                    _ => None,
                })
                .collect()
        };
        let committed = samples(&read_rig_messages(&bag).unwrap());
        assert_eq!(committed.len(), 12 * 1300);
        assert!(
            samples(&streamed) == committed,
            "samples differ from the committed bag"
        );
    }

    #[test]
    fn bad_parameters_are_refused() {
        for (name, value) in [
            ("system", ParamValue::String("car".into())),
            ("seed", ParamValue::Integer(-1)),
            ("sample_rate_hz", ParamValue::Double(0.0)),
            ("step_duration_s", ParamValue::Double(-1.0)),
            ("frequencies_hz", ParamValue::DoubleArray(vec![])),
        ] {
            let mut p = Params::new();
            p.set(name, value);
            assert!(run_spec(&p).is_err(), "{name}");
        }
    }
}
