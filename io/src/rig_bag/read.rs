//! Reading a rig run from a bag: one reader of the rig topics ([`RigBagReader`]) that the
//! analysis ([`read_rig_bag`]: records) and the sensor's playback ([`read_rig_messages`]:
//! messages in log-time order) share, so both find the topics by the same rule and decode them
//! with the same errors.
//!
//! The rule: a rig topic holds forcemap's type for its kind, under forcemap's name as the last
//! component of its name, in any namespace (`/rig/samples`, `/bench2/rig/samples`). A bag with
//! two topics of one kind (two rigs) is refused as ambiguous, naming them.

use std::collections::BTreeMap;
use std::path::Path;

use forcemap_math::record::{Channel, Record};
use forcemap_msgs::RosMessage;
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::DiagnosticStatus;
use forcemap_msgs::msg::{ExcitationState, RigSample};
use forcemap_msgs::std_msgs::Header;

use super::{RigBagError, check_topic};
use crate::bag::BagReader;
use crate::rig_messages::RigMessage;
use crate::steps::timing::TimingReport;
use crate::steps::{AssembledStep, StepAssembler, StepError, StepPlan};
use crate::topics;

/// The kinds of rig topic.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RigTopic {
    Samples,
    Excitation,
    Parameters,
}

impl RigTopic {
    const ALL: [RigTopic; 3] = [
        RigTopic::Samples,
        RigTopic::Excitation,
        RigTopic::Parameters,
    ];

    /// The last component of the topic's name.
    pub fn name(self) -> &'static str {
        match self {
            RigTopic::Samples => topics::SAMPLES,
            RigTopic::Excitation => topics::EXCITATION,
            RigTopic::Parameters => topics::PARAMETERS,
        }
    }

    /// The name under forcemap's own namespace (what an error names when the topic is missing).
    fn default_name(self) -> &'static str {
        match self {
            RigTopic::Samples => topics::RIG_SAMPLES,
            RigTopic::Excitation => topics::RIG_EXCITATION,
            RigTopic::Parameters => topics::RIG_PARAMETERS,
        }
    }

    pub fn type_name(self) -> &'static str {
        match self {
            RigTopic::Samples => RigSample::TYPE_NAME,
            RigTopic::Excitation => ExcitationState::TYPE_NAME,
            RigTopic::Parameters => DiagnosticStatus::TYPE_NAME,
        }
    }

    fn check(self, reader: &BagReader, path: &str, topic: &str) -> Result<(), RigBagError> {
        match self {
            RigTopic::Samples => check_topic::<RigSample>(reader, path, topic),
            RigTopic::Excitation => check_topic::<ExcitationState>(reader, path, topic),
            RigTopic::Parameters => check_topic::<DiagnosticStatus>(reader, path, topic),
        }
    }

    fn decode(self, data: &[u8]) -> Result<RigMessage, String> {
        let e = |e: &dyn std::fmt::Display| e.to_string();
        Ok(match self {
            RigTopic::Samples => RigMessage::Sample(RigSample::from_cdr(data).map_err(|x| e(&x))?),
            RigTopic::Excitation => {
                RigMessage::Excitation(ExcitationState::from_cdr(data).map_err(|x| e(&x))?)
            }
            RigTopic::Parameters => {
                RigMessage::Parameters(DiagnosticStatus::from_cdr(data).map_err(|x| e(&x))?)
            }
        })
    }
}

/// A bag opened for its rig topics.
pub struct RigBagReader {
    reader: BagReader,
    path: String,
    /// The topic of each kind of [`RigTopic::ALL`], when the bag has one.
    topics: [Option<String>; 3],
}

impl RigBagReader {
    pub fn open(path: &Path) -> Result<RigBagReader, RigBagError> {
        RigBagReader::new(BagReader::open(path)?, path)
    }

    /// The rig topics of an opened bag, checked against forcemap's definitions.
    pub fn new(reader: BagReader, path: &Path) -> Result<RigBagReader, RigBagError> {
        let path = path.display().to_string();
        let mut found: [Option<String>; 3] = Default::default();
        for (slot, kind) in found.iter_mut().zip(RigTopic::ALL) {
            let names: Vec<String> = reader
                .topics()
                .filter(|t| {
                    t.type_name == kind.type_name()
                        && t.name.rsplit('/').next() == Some(kind.name())
                })
                .map(|t| t.name.clone())
                .collect();
            match names.as_slice() {
                [] => {
                    // A topic with forcemap's name but another type is an error, not absence.
                    if reader.topic(kind.default_name()).is_ok() {
                        kind.check(&reader, &path, kind.default_name())?;
                    }
                }
                [one] => {
                    kind.check(&reader, &path, one)?;
                    *slot = Some(one.clone());
                }
                more => {
                    return Err(RigBagError::Ambiguous {
                        path,
                        kind: kind.name().into(),
                        topics: more.join(", "),
                    });
                }
            }
        }
        Ok(RigBagReader {
            reader,
            path,
            topics: found,
        })
    }

    /// The bag's topic of `kind`, if it has one.
    pub fn topic(&self, kind: RigTopic) -> Option<&str> {
        let i = RigTopic::ALL.iter().position(|k| *k == kind)?;
        self.topics[i].as_deref()
    }

    /// The bag's topic of `kind`, or the bag's error naming the missing topic.
    fn required(&self, kind: RigTopic) -> Result<&str, RigBagError> {
        match self.topic(kind) {
            Some(t) => Ok(t),
            None => Err(self
                .reader
                .topic(kind.default_name())
                .map(|_| ())
                .err()
                .map_or_else(
                    || RigBagError::Empty {
                        path: self.path.clone(),
                        topic: kind.default_name().into(),
                    },
                    RigBagError::Bag,
                )),
        }
    }

    /// The messages on the topics of `kinds` the bag has, decoded, in log-time order.
    pub fn messages(
        &self,
        kinds: &[RigTopic],
    ) -> Result<impl Iterator<Item = Result<RigMessage, RigBagError>> + '_, RigBagError> {
        let wanted: Vec<(RigTopic, &str)> = kinds
            .iter()
            .filter_map(|k| self.topic(*k).map(|t| (*k, t)))
            .collect();
        let names: Vec<&str> = wanted.iter().map(|(_, t)| *t).collect();
        let mut counts = [0usize; 3];
        let it = self.reader.messages_on(&names)?;
        Ok(it.map(move |m| {
            let m = m?;
            let (kind, topic) = wanted
                .iter()
                .find(|(_, t)| *t == m.topic.name)
                .copied()
                .ok_or_else(|| RigBagError::Message {
                    path: self.path.clone(),
                    topic: m.topic.name.clone(),
                    index: 0,
                    problem: "not a rig topic".into(),
                })?;
            let slot = RigTopic::ALL.iter().position(|k| *k == kind).unwrap_or(0);
            let index = counts[slot];
            counts[slot] += 1;
            kind.decode(&m.data)
                .map_err(|problem| RigBagError::Message {
                    path: self.path.clone(),
                    topic: topic.into(),
                    index,
                    problem,
                })
        }))
    }
}

/// A rig run read from a bag.
#[derive(Debug, Clone)]
pub struct RigBag {
    pub records: Vec<Record>,
    /// Rig constants found on the parameters topic (numeric values only).
    pub parameters: BTreeMap<String, f64>,
    /// Why a last, unfinished step was left out (a recording stopped in the middle of it).
    pub left_out: Option<String>,
    /// What the steps' data say against their labels, each naming its step
    /// ([`crate::steps::AssembledStep::warnings`]).
    pub warnings: Vec<String>,
    /// What the timing rule did ([`crate::steps::timing`]): a step split at a pause or lost
    /// samples, samples left out, the jitter of the stamps.
    pub notices: Vec<String>,
}

/// Reads the records of a rig run from a bag directory or a bare .mcap.
pub fn read_rig_bag(path: &Path) -> Result<RigBag, RigBagError> {
    RigBagReader::open(path)?.records()
}

impl RigBagReader {
    /// The bag's records: the steps planned on the excitation topic (read first, so that a
    /// state logged after its step's first samples still applies), assembled from the
    /// samples by the one [`StepAssembler`].
    pub fn records(&self) -> Result<RigBag, RigBagError> {
        self.records_reduced(Some)
    }

    /// [`records`](Self::records) with each record handed to `keep` as soon as its step is
    /// complete: what `keep` returns is kept (None: consumed, e.g. analysed into phasors), so
    /// that a long bag is read in memory of one step and what is kept. `records` of the
    /// result holds the kept records.
    pub fn records_reduced(
        &self,
        mut keep: impl FnMut(Record) -> Option<Record>,
    ) -> Result<RigBag, RigBagError> {
        let p = &self.path;
        let samples_topic = self.required(RigTopic::Samples)?.to_string();
        let excitation_topic = self.required(RigTopic::Excitation)?.to_string();
        let mut parameters = BTreeMap::new();
        for m in self.messages(&[RigTopic::Parameters])? {
            if let RigMessage::Parameters(s) = m? {
                for kv in s.values {
                    if let Ok(v) = kv.value.parse::<f64>() {
                        parameters.insert(kv.key, v);
                    }
                }
            }
        }

        let mut plans: BTreeMap<u32, StepPlan> = BTreeMap::new();
        let mut run_start: Option<Time> = None;
        for (i, m) in self.messages(&[RigTopic::Excitation])?.enumerate() {
            let RigMessage::Excitation(s) = m? else {
                continue;
            };
            // IDLE (the run ended) starts no step but its time is not the run's start either.
            let plan = StepPlan::from_state(&s).map_err(|e| RigBagError::Message {
                path: p.clone(),
                topic: excitation_topic.clone(),
                index: i,
                problem: e.to_string(),
            })?;
            if let Some(plan) = plan {
                run_start = Some(run_start.map_or(s.start_time, |t: Time| t.min(s.start_time)));
                plans.insert(s.step, plan);
            }
        }

        // Samples, grouped by step in time order.
        let mut assembler = StepAssembler::new();
        if let Some(t) = run_start {
            assembler.set_origin(t);
        }
        let mut records: Vec<Record> = Vec::new();
        let mut warnings = Vec::new();
        let mut timing = TimingReport::default();
        let mut complete = 0usize;
        let mut take = |a: AssembledStep| {
            complete += 1;
            timing.add(&a);
            warnings.extend(a.warnings);
            records.extend(keep(a.record));
        };
        let step_err = |e: StepError| RigBagError::Step {
            path: p.clone(),
            step: e.step,
            problem: e.problem,
        };
        for m in self.messages(&[RigTopic::Samples])? {
            let RigMessage::Sample(s) = m? else {
                continue;
            };
            for done in assembler.push_rig(&s, plans.get(&s.step)) {
                take(done.map_err(step_err)?);
            }
        }
        let mut truncated = None;
        for done in assembler.finish_step() {
            match done {
                Ok(r) => take(r),
                Err(e) if e.truncated => truncated = Some(e),
                Err(e) => return Err(step_err(e)),
            }
        }
        // The recording stopped in the middle of the last step: keep the complete ones.
        let left_out = match truncated {
            Some(e) if complete > 0 => Some(format!("step {} left out: {}", e.step, e.problem)),
            Some(e) => return Err(step_err(e)),
            None => None,
        };
        if complete == 0 {
            return Err(RigBagError::Empty {
                path: p.clone(),
                topic: samples_topic,
            });
        }
        Ok(RigBag {
            records,
            parameters,
            left_out,
            warnings,
            notices: timing.notices(),
        })
    }

    /// The bag's rig messages in log-time order; an IDLE state is added one sample period
    /// after the last sample when the bag has none (a recording stopped before the exciter went
    /// idle). What the sensor node plays.
    pub fn playback(&self) -> Result<Vec<RigMessage>, RigBagError> {
        let mut out = Vec::new();
        self.stream_playback(|m| {
            out.push(m);
            true
        })?;
        Ok(out)
    }

    /// [`playback`](Self::playback) one message at a time, in constant memory: `emit` takes
    /// each message and says whether to go on.
    pub fn stream_playback(
        &self,
        mut emit: impl FnMut(RigMessage) -> bool,
    ) -> Result<(), RigBagError> {
        self.required(RigTopic::Samples)?;
        let mut last: Option<(u32, Time, String)> = None;
        let mut saw_idle = false;
        let mut period = 0.0f64;
        for m in self.messages(&RigTopic::ALL)? {
            let m = m?;
            match &m {
                RigMessage::Sample(s) => {
                    if let Some((_, t, _)) = &last {
                        let dt = s.header.stamp.secs_since(*t);
                        if dt > 0.0 {
                            period = dt;
                        }
                    }
                    last = Some((s.step, s.header.stamp, s.header.frame_id.clone()));
                }
                RigMessage::Excitation(s) => saw_idle |= s.is_idle(),
                RigMessage::Parameters(_) => {}
            }
            if !emit(m) {
                return Ok(());
            }
        }
        let Some((step, t, frame)) = last else {
            return Err(RigBagError::Empty {
                path: self.path.clone(),
                topic: self.required(RigTopic::Samples)?.into(),
            });
        };
        if !saw_idle {
            let end = t.add_secs_f64(period);
            emit(RigMessage::Excitation(ExcitationState::idle(
                Header::new(end, &frame),
                step as usize + 1,
                end,
                Channel::BaseDisplacementM,
            )));
        }
        Ok(())
    }

    /// How many messages the bag holds on its topic of `kind` (from its summary; 0 without
    /// the topic).
    pub fn message_count(&self, kind: RigTopic) -> u64 {
        self.topic(kind)
            .and_then(|t| self.reader.topic(t).ok())
            .map_or(0, |info| info.message_count)
    }
}

/// The rig messages of a bag, as [`RigBagReader::playback`].
pub fn read_rig_messages(path: &Path) -> Result<Vec<RigMessage>, RigBagError> {
    RigBagReader::open(path)?.playback()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Records handed out as they complete are today's records, in order; those kept are kept.
    #[test]
    fn reduced_records_are_the_records_one_at_a_time() {
        let bag = Path::new(env!("CARGO_MANIFEST_DIR")).join("../bags/rig_40db");
        let reader = RigBagReader::open(&bag).unwrap();
        let whole = reader.records().unwrap();
        let mut seen = Vec::new();
        let kept = reader
            .records_reduced(|r| {
                seen.push(r.clone());
                (r.step % 2 == 1).then_some(r)
            })
            .unwrap();
        assert_eq!(whole.records.len(), 12);
        assert!(format!("{seen:?}") == format!("{:?}", whole.records));
        let odd: Vec<&Record> = whole.records.iter().filter(|r| r.step % 2 == 1).collect();
        assert!(format!("{:?}", kept.records.iter().collect::<Vec<_>>()) == format!("{odd:?}"));
        assert_eq!(kept.parameters, whole.parameters);
    }
}
