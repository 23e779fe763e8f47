//! Records as the sensor's message stream: the rig constants, then per step its
//! `ExcitationState` and its `RigSample`s, then the exciter's IDLE. The simulated sensor node
//! publishes it, `forcemap bench graph` plays it, and a rig bag is written from it (and read
//! back by `rig_bag::read_rig_messages`). Plain
//! message structs: no ROS runtime needed.

use forcemap_math::record::{Channel, Record};
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::DiagnosticStatus;
use forcemap_msgs::msg::{ExcitationState, RigSample};
use forcemap_msgs::std_msgs::Header;

use crate::rig_bag::PARAMETERS_NAME;

/// One message of a rig run, in publishing order.
#[derive(Debug, Clone, PartialEq)]
pub enum RigMessage {
    /// The rig constants (`/rig/parameters`).
    Parameters(DiagnosticStatus),
    /// The start of a step, or the exciter's IDLE after the last one (`/rig/excitation`).
    Excitation(ExcitationState),
    /// One sample (`/rig/samples`).
    Sample(RigSample),
}

impl RigMessage {
    /// When the message is due: a step's start time, a sample's stamp; None for the
    /// constants (published before anything else).
    pub fn stamp(&self) -> Option<Time> {
        match self {
            RigMessage::Excitation(m) => Some(m.start_time),
            RigMessage::Sample(m) => Some(m.header.stamp),
            RigMessage::Parameters(_) => None,
        }
    }
}

/// The `message` of the constants of a simulated run (see [`constants_status`]).
pub const SIMULATED_CONSTANTS_MESSAGE: &str =
    "rig constants (simulated rig; truth.* are the simulator's true element values)";

/// The rig constants as the `/rig/parameters` status: named [`PARAMETERS_NAME`], with
/// `message` and `hardware_id`, one key/value pair per constant, in order.
pub fn constants_status<K: AsRef<str>>(
    message: &str,
    hardware_id: &str,
    constants: &[(K, f64)],
) -> DiagnosticStatus {
    constants.iter().fold(
        DiagnosticStatus::new(DiagnosticStatus::OK, PARAMETERS_NAME, message, hardware_id),
        |s, (k, v)| s.with_value(k.as_ref(), v),
    )
}

/// The messages of `records` run from `run_start`, in time order: `parameters` (if any),
/// then per record its `ExcitationState` (stamped at the record's start) followed by its
/// samples (stamped at their times), then the IDLE `ExcitationState` at the end of the last
/// record (the step after the last one). `driven` is the channel whose amplitude the
/// excitation gives; every header carries `frame`.
pub fn rig_messages<'a>(
    records: &'a [Record],
    driven: Channel,
    parameters: Option<DiagnosticStatus>,
    run_start: Time,
    frame: &'a str,
) -> impl Iterator<Item = RigMessage> + 'a {
    let steps = records
        .iter()
        .flat_map(move |r| record_messages(r, driven, run_start, frame));
    parameters
        .map(RigMessage::Parameters)
        .into_iter()
        .chain(steps)
        .chain(std::iter::once(idle_after(
            records.last(),
            driven,
            run_start,
            frame,
        )))
}

/// The messages of one record of a run from `run_start`: its `ExcitationState` (stamped at the
/// record's start), then its samples (for a run published record by record).
pub fn record_messages<'a>(
    r: &'a Record,
    driven: Channel,
    run_start: Time,
    frame: &'a str,
) -> impl Iterator<Item = RigMessage> + 'a {
    std::iter::once(record_state(r, driven, run_start, frame))
        .chain((0..r.len()).map(move |i| record_sample(r, i, run_start, frame)))
}

/// The `ExcitationState` of a record, stamped at its start.
pub fn record_state(r: &Record, driven: Channel, run_start: Time, frame: &str) -> RigMessage {
    let start = run_start.add_secs_f64(r.start_time_s);
    RigMessage::Excitation(ExcitationState::from_excitation(
        Header::new(start, frame),
        r.step,
        start,
        &r.excitation,
        driven,
        r.len(),
    ))
}

/// Sample `i` of a record, stamped at its time.
pub fn record_sample(r: &Record, i: usize, run_start: Time, frame: &str) -> RigMessage {
    let stamp = run_start.add_secs_f64(r.time_s(i));
    RigMessage::Sample(RigSample::from_record(r, i, Header::new(stamp, frame)))
}

/// The IDLE state at the end of a run's `last` record (the step after it).
pub fn idle_after(
    last: Option<&Record>,
    driven: Channel,
    run_start: Time,
    frame: &str,
) -> RigMessage {
    let end = last.map_or(run_start, |r| {
        run_start.add_secs_f64(r.start_time_s + r.len() as f64 / r.sample_rate_hz)
    });
    let idle_step = last.map_or(0, |r| r.step + 1);
    RigMessage::Excitation(ExcitationState::idle(
        Header::new(end, frame),
        idle_step,
        end,
        driven,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use forcemap_math::record::Excitation;

    fn record(step: usize, start_time_s: f64, n: usize) -> Record {
        Record {
            step,
            excitation: Excitation::Sine {
                frequency_hz: 2.0,
                amplitude: 0.006,
            },
            sample_rate_hz: 100.0,
            start_time_s,
            channels: vec![
                (
                    Channel::BaseDisplacementM,
                    (0..n).map(|i| i as f64).collect(),
                ),
                (
                    Channel::MassAccelerationMps2,
                    (0..n).map(|i| -(i as f64)).collect(),
                ),
            ],
        }
    }

    const START: Time = Time {
        sec: 1_000,
        nanosec: 0,
    };

    #[test]
    fn parameters_then_each_step_then_idle() {
        let records = [record(0, 0.0, 3), record(1, 0.03, 2)];
        let params = constants_status("rig constants", "rig", &[("mass_kg", 36.0)]);
        let m: Vec<RigMessage> = rig_messages(
            &records,
            Channel::BaseDisplacementM,
            Some(params.clone()),
            START,
            "rig",
        )
        .collect();
        // 1 parameters + (1 + 3) + (1 + 2) + 1 idle.
        assert_eq!(m.len(), 9);
        assert_eq!(m[0], RigMessage::Parameters(params));
        let kinds: String = m
            .iter()
            .map(|m| match m {
                RigMessage::Parameters(_) => 'P',
                RigMessage::Excitation(e) if e.is_idle() => 'I',
                RigMessage::Excitation(_) => 'E',
                RigMessage::Sample(_) => 's',
            })
            .collect();
        assert_eq!(kinds, "PEsssEssI");
        let RigMessage::Excitation(e) = &m[5] else {
            unreachable!()
        };
        assert_eq!((e.step, e.sample_count), (1, 2));
        assert_eq!(e.start_time, START.add_secs_f64(0.03));
        let RigMessage::Excitation(idle) = &m[8] else {
            unreachable!()
        };
        assert_eq!(idle.step, 2);
        assert_eq!(idle.start_time, START.add_secs_f64(0.05));
        assert_eq!(idle.header.frame_id, "rig");
    }

    #[test]
    fn stamps_are_the_sample_times_and_never_go_back() {
        let records = [record(0, 0.0, 3), record(1, 0.03, 2)];
        let m: Vec<RigMessage> =
            rig_messages(&records, Channel::BaseDisplacementM, None, START, "f").collect();
        assert_eq!(m.len(), 8, "no parameters message without parameters");
        let stamps: Vec<Time> = m.iter().filter_map(RigMessage::stamp).collect();
        assert_eq!(stamps.len(), m.len());
        assert!(stamps.windows(2).all(|w| w[1].secs_since(w[0]) >= 0.0));
        let samples: Vec<&RigSample> = m
            .iter()
            .filter_map(|m| match m {
                RigMessage::Sample(s) => Some(s),
                _ => None,
            })
            .collect();
        assert_eq!(samples.len(), 5);
        for (s, t) in samples.iter().zip([0.0, 0.01, 0.02, 0.03, 0.04]) {
            assert_eq!(s.header.stamp, START.add_secs_f64(t));
            assert_eq!(s.header.frame_id, "f");
        }
        assert_eq!(samples[4].step, 1);
        // The excitation message of a step shares the stamp of its first sample.
        assert_eq!(m[0].stamp(), m[1].stamp());
    }

    #[test]
    fn no_records_give_the_idle_at_the_start() {
        let m: Vec<RigMessage> = rig_messages(&[], Channel::ForceN, None, START, "rig").collect();
        assert_eq!(m.len(), 1);
        let RigMessage::Excitation(e) = &m[0] else {
            unreachable!()
        };
        assert!(e.is_idle());
        assert_eq!((e.step, e.start_time), (0, START));
    }

    #[test]
    fn constants_keep_their_order() {
        let s = constants_status("m", "hw", &[("b", 2.0), ("a", 1.5)]);
        assert_eq!(s.name, PARAMETERS_NAME);
        assert_eq!((s.message.as_str(), s.hardware_id.as_str()), ("m", "hw"));
        let kv: Vec<(&str, &str)> = s
            .values
            .iter()
            .map(|k| (k.key.as_str(), k.value.as_str()))
            .collect();
        assert_eq!(kv, [("b", "2"), ("a", "1.5")]);
    }
}
