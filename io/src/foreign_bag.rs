//! A bag recorded by a bench's own tools, read through a [`ChannelMap`]: each mapped topic is
//! decoded from its definition (the bag's schema, a `.msg` file named by the map, or a
//! built-in standard message), and the messages go in log-time order (a log time is when the
//! recorder received the message) through [`ForeignTopics`], the reader the live `foreign`
//! node feeds as messages arrive: the same alignment by stamps (a message without a header by
//! its receive time less the reference's delay, to the nearest sample; [`crate::stamp_align`]),
//! the same labels (`step`, `frequency_hz`: from the sample nearest their time until the next
//! message; samples before the first label are left out). The samples are then assembled into
//! steps by the same [`StepAssembler`] as forcemap's own bags (its timing rule: a pause or lost
//! samples end a record, jittered stamps are read as uniform).
//!
//! The data topics must have one sample rate (no resampling: a lost message, a clock offset or
//! a different rate is an error that says which). A map with neither label gives the run as
//! records cut where its driven channel changes ([`split_parts`], as an unlabelled CSV export
//! is cut, each part between pauses apart, and as the harmonic node's `find_steps` cuts the
//! same samples live).

use std::collections::BTreeMap;
use std::path::Path;

use forcemap_math::recipe::SetupKind;
use forcemap_math::record::Record;
use forcemap_math::segment::SegmentOptions;
use forcemap_msgs::builtin_interfaces::Time;

use crate::bag::{BagError, BagReader};
use crate::channel_map::{ChannelMap, FREQUENCY_LABEL, STEP_LABEL, Source};
use crate::foreign_topics::{ForeignTopics, LiveTopic, Output, SampleLabels, step_of_labels};
use crate::rig_bag::RigBag;
use crate::ros_msg::{Registry, builtin_registry, parse_msg};
use crate::stamp_align::median_interval_ns;
use crate::steps::timing::TimingReport;
use crate::steps::unlabelled::split_parts;
use crate::steps::{
    AssembledStep, StepAssembler, StepError, StepPlan, StepRules, StepSample, estimated_excitation,
    rms_about_mean,
};

pub use crate::stamp_align::{ALIGN_TOLERANCE, RATE_TOLERANCE};

#[derive(Debug, thiserror::Error)]
pub enum ForeignBagError {
    #[error(transparent)]
    Bag(#[from] BagError),
    #[error("{path}: topic {topic} (for {entry}) is not in the bag; its topics: {available}")]
    MissingTopic {
        path: String,
        topic: String,
        entry: String,
        available: String,
    },
    #[error(
        "{path}: topic {topic}: unknown message type {type_name}: the bag has no schema for it and it is neither built in nor in the map's definitions"
    )]
    UnknownType {
        path: String,
        topic: String,
        type_name: String,
    },
    #[error("{path}: topic {topic}: definition of {type_name}: {problem}")]
    Definition {
        path: String,
        topic: String,
        type_name: String,
        problem: String,
    },
    #[error("{path}: topic {topic}, field {field} (for {entry}): {problem}")]
    Field {
        path: String,
        topic: String,
        field: String,
        entry: String,
        problem: String,
    },
    #[error("{path}: topic {topic}, message {index}: {problem}")]
    Message {
        path: String,
        topic: String,
        index: usize,
        problem: String,
    },
    #[error("{path}: cannot align the channels: {problem}")]
    Align { path: String, problem: String },
    #[error(
        "{path}: the channel map gives no {missing} (map both step and frequency_hz to the topic and field that carry them, or neither, to find the steps in the driven channel)"
    )]
    Unlabelled { path: String, missing: String },
    #[error("{path}: finding the steps in the driven channel: {problem}")]
    Segment { path: String, problem: String },
    #[error("{path}: step {step}: {problem}")]
    Step {
        path: String,
        step: usize,
        problem: String,
    },
    #[error("{path}: no labelled samples on {topics}")]
    Empty { path: String, topics: String },
}

/// The definitions `type_name` is decoded with: the bag's schema, else the map's `.msg` files,
/// completed by the built-in ones.
pub fn registry_for(
    map: &ChannelMap,
    type_name: &str,
    schema: &str,
) -> Result<Registry, (bool, String)> {
    let mut reg = if schema.trim().is_empty() {
        let mut reg = Registry::new();
        for (name, file) in &map.definitions {
            let text = std::fs::read_to_string(file)
                .map_err(|e| (false, format!("{}: {e}", file.display())))?;
            reg.insert(parse_msg(name, &text).map_err(|e| (false, e.to_string()))?);
        }
        reg
    } else {
        Registry::parse_schema(type_name, schema).map_err(|e| (false, e.to_string()))?
    };
    reg.extend_missing(&builtin_registry());
    if !reg.contains(type_name) {
        return Err((true, String::new()));
    }
    reg.check(type_name).map_err(|e| (false, e.to_string()))?;
    Ok(reg)
}

/// Reads the records of a bag recorded by a bench's own tools, through `map`.
pub fn read_foreign_bag(path: &Path, map: &ChannelMap) -> Result<RigBag, ForeignBagError> {
    let p = path.display().to_string();
    let reader = BagReader::open(path)?;
    let sources: Vec<(&str, &Source)> = map.sources().collect();

    // The map against the bag: topics, types, fields.
    let mut topics: Vec<LiveTopic> = Vec::new();
    for (entry, s) in &sources {
        let info = reader
            .topic(&s.topic)
            .map_err(|_| ForeignBagError::MissingTopic {
                path: p.clone(),
                topic: s.topic.clone(),
                entry: entry.to_string(),
                available: reader
                    .topics()
                    .map(|t| t.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
            })?;
        if let Some(named) = &s.type_name
            && *named != info.type_name
        {
            return Err(ForeignBagError::Definition {
                path: p.clone(),
                topic: s.topic.clone(),
                type_name: info.type_name.clone(),
                problem: format!(
                    "the channel map names the type {named} (for {entry}), the bag records {}",
                    info.type_name
                ),
            });
        }
        if !topics.iter().any(|t| t.name == s.topic) {
            let registry = registry_for(map, &info.type_name, &info.schema_text).map_err(
                |(unknown, problem)| {
                    if unknown {
                        ForeignBagError::UnknownType {
                            path: p.clone(),
                            topic: s.topic.clone(),
                            type_name: info.type_name.clone(),
                        }
                    } else {
                        ForeignBagError::Definition {
                            path: p.clone(),
                            topic: s.topic.clone(),
                            type_name: info.type_name.clone(),
                            problem,
                        }
                    }
                },
            )?;
            topics.push(LiveTopic::new(&s.topic, &info.type_name, registry));
        }
        let t = topics
            .iter()
            .find(|t| t.name == s.topic)
            .expect("added above");
        s.field
            .check(t.registry(), &t.type_name)
            .map_err(|e| ForeignBagError::Field {
                path: p.clone(),
                topic: s.topic.clone(),
                field: s.field.text.clone(),
                entry: entry.to_string(),
                problem: e.to_string(),
            })?;
    }
    let labelled = map.step.is_some() || map.frequency_hz.is_some();
    if labelled && (map.step.is_none() || map.frequency_hz.is_none()) {
        let missing: Vec<&str> = [
            (map.step.is_none(), STEP_LABEL),
            (map.frequency_hz.is_none(), FREQUENCY_LABEL),
        ]
        .into_iter()
        .filter_map(|(m, n)| m.then_some(n))
        .collect();
        return Err(ForeignBagError::Unlabelled {
            path: p,
            missing: missing.join(" and "),
        });
    }

    let samples = read_samples(&p, &reader, map, topics)?;
    let driven = setup_kind(&p, map)?.driven_channel();
    if labelled {
        return assemble(&p, map, &samples, driven, TimingReport::default()).map(|a| a.bag);
    }
    // No labels: the run as one random step (cut at pauses or lost samples), each part then
    // cut where the drive changes.
    let unlabelled: Vec<Sample> = samples
        .iter()
        .map(|(t, v, _)| (*t, v.clone(), Some([Some(0.0), Some(0.0)])))
        .collect();
    let mut bag = assemble(&p, map, &unlabelled, driven, TimingReport::of_run())?;
    let t0 = samples.first().map_or(0, |s| s.0);
    let times_s: Vec<f64> = samples
        .iter()
        .map(|s| Time::from_nanos(s.0).secs_since(Time::from_nanos(t0)))
        .collect();
    let parts: Vec<(&Record, &[f64])> = bag
        .bag
        .records
        .iter()
        .zip(&bag.first_samples)
        .map(|(r, &first)| (r, &times_s[first..first + r.len()]))
        .collect();
    let records = split_parts(&parts, driven, &SegmentOptions::default())
        .map_err(|e| ForeignBagError::Segment {
            path: p.clone(),
            problem: e.to_string(),
        })?
        .into_iter()
        .map(|(mut r, frequency)| {
            let level = r.channel(driven).map_or(f64::NAN, rms_about_mean);
            r.excitation = estimated_excitation(frequency, level);
            r
        })
        .collect();
    bag.bag.records = records;
    Ok(bag.bag)
}

/// An aligned sample: its time [ns], the channels' values in the map's order, its labels.
type Sample = (i64, Vec<f64>, Option<SampleLabels>);

/// Every mapped topic's messages, in log-time order, through the reader of foreign topics: the
/// aligned (and labelled) samples; a message that breaks the rules is the error.
fn read_samples(
    p: &str,
    reader: &BagReader,
    map: &ChannelMap,
    topics: Vec<LiveTopic>,
) -> Result<Vec<Sample>, ForeignBagError> {
    let mut live = ForeignTopics::of_topics(map, topics).recording_times();
    let names: Vec<String> = live.topics().iter().map(|t| t.name.clone()).collect();
    let refs: Vec<&str> = names.iter().map(String::as_str).collect();
    // Each channel's place in a sample: the reader gives them in its data topics' order.
    let places: Vec<usize> = map
        .channels
        .iter()
        .map(|(c, _)| live.channels().iter().position(|d| d == c).unwrap_or(0))
        .collect();
    let mut counts = vec![0usize; names.len()];
    let mut samples = Vec::new();
    let mut misaligned = None;
    let mut out = Vec::new();
    let mut take = |out: &mut Vec<Output>,
                    samples: &mut Vec<Sample>,
                    counts: &[usize]|
     -> Result<(), ForeignBagError> {
        for o in out.drain(..) {
            match o {
                Output::Sample {
                    t_ns,
                    values,
                    labels,
                } => samples.push((t_ns, places.iter().map(|&i| values[i].1).collect(), labels)),
                Output::Malformed { topic, problem } => {
                    let k = names.iter().position(|n| *n == topic).unwrap_or(0);
                    return Err(ForeignBagError::Message {
                        path: p.to_string(),
                        topic,
                        index: counts[k].saturating_sub(1),
                        problem,
                    });
                }
                Output::Misaligned(problem) => {
                    misaligned.get_or_insert(problem);
                }
            }
        }
        Ok(())
    };
    for m in reader.messages_on(&refs)? {
        let m = m?;
        let k = names.iter().position(|n| *n == m.topic.name).unwrap_or(0);
        counts[k] += 1;
        let log_ns = i64::try_from(m.log_time).map_err(|_| ForeignBagError::Message {
            path: p.to_string(),
            topic: m.topic.name.clone(),
            index: counts[k] - 1,
            problem: "log time out of range".into(),
        })?;
        live.push(k, &m.data, log_ns, &mut out);
        take(&mut out, &mut samples, &counts)?;
    }
    live.flush(&mut out);
    take(&mut out, &mut samples, &counts)?;
    check_rates(p, &live)?;
    if let Some(problem) = misaligned {
        return Err(ForeignBagError::Align {
            path: p.to_string(),
            problem,
        });
    }
    Ok(samples)
}

/// The data topics' rates against the reference's: what a misalignment may come from, said
/// first.
fn check_rates(p: &str, live: &ForeignTopics) -> Result<(), ForeignBagError> {
    let err = |problem: String| ForeignBagError::Align {
        path: p.to_string(),
        problem,
    };
    let Some(times) = live.times() else {
        return Ok(());
    };
    let name = |k: usize| live.topics()[k].name.as_str();
    let reference = &times[0];
    if reference.len() < 2 {
        return Err(err(format!(
            "{} has {} messages: too few for a sample rate",
            name(0),
            reference.len()
        )));
    }
    let interval = median_interval_ns(reference.iter().copied());
    if interval <= 0.0 {
        return Err(err(format!(
            "{}: most messages share one stamp (a median interval of 0 ns)",
            name(0)
        )));
    }
    for (k, t) in times.iter().enumerate().skip(1) {
        if t.len() < 2 {
            return Err(err(format!(
                "{} has {} messages where {} has {}",
                name(k),
                t.len(),
                name(0),
                reference.len()
            )));
        }
        let other = median_interval_ns(t.iter().copied());
        if (other / interval - 1.0).abs() > RATE_TOLERANCE {
            return Err(err(format!(
                "{} has a sample rate of {:.6} Hz where {} has {:.6} Hz: channels from different topics must share one rate (forcemap does not resample)",
                name(k),
                1e9 / other,
                name(0),
                1e9 / interval
            )));
        }
    }
    Ok(())
}

/// The setup the map's channels make.
fn setup_kind(p: &str, map: &ChannelMap) -> Result<SetupKind, ForeignBagError> {
    SetupKind::of_channels(|c| map.channels.iter().any(|(m, _)| *m == c)).map_err(|e| {
        ForeignBagError::Align {
            path: p.to_string(),
            problem: e.to_string(),
        }
    })
}

/// The data topics in the map's channel order, the reference (whose times the samples take)
/// first: the first with a header stamp, else the first. The live source orders them the same.
pub fn data_topic_order(map: &ChannelMap, stamped: impl Fn(&str) -> bool) -> Vec<&str> {
    let mut order: Vec<&str> = Vec::new();
    for (_, s) in &map.channels {
        if !order.contains(&s.topic.as_str()) {
            order.push(&s.topic);
        }
    }
    let first_stamped = order.iter().position(|n| stamped(n)).unwrap_or(0);
    order.swap(0, first_stamped);
    order
}

/// A bag's records and where each starts among the samples of its step.
struct Assembled {
    bag: RigBag,
    first_samples: Vec<usize>,
}

/// The labelled samples through the step assembler, then each step's excitation level
/// estimated from its driven channel (a bench's messages carry no amplitude).
fn assemble(
    p: &str,
    map: &ChannelMap,
    samples: &[Sample],
    driven: forcemap_math::record::Channel,
    mut timing: TimingReport,
) -> Result<Assembled, ForeignBagError> {
    let step_src = map.step.as_ref().map_or("", |s| s.topic.as_str());
    let freq_src = map.frequency_hz.as_ref().map_or("", |s| s.topic.as_str());
    let label_err =
        |topic: &str, entry: &str, k: usize, problem: String| ForeignBagError::Message {
            path: p.to_string(),
            topic: topic.to_string(),
            index: k,
            problem: format!("{entry} at sample {k}: {problem}"),
        };
    let step_err = |e: StepError| ForeignBagError::Step {
        path: p.to_string(),
        step: e.step,
        problem: e.problem,
    };
    let mut assembler = StepAssembler::with_rules(StepRules::MESSAGES);
    let mut origin: Option<Time> = None;
    let mut plans: BTreeMap<usize, (Option<f64>, StepPlan)> = BTreeMap::new();
    let mut assembled: Vec<AssembledStep> = Vec::new();
    let mut left_before = 0usize;
    for (k, (t, values, labels)) in samples.iter().enumerate() {
        let Some([Some(step), Some(freq)]) = labels else {
            left_before += 1;
            continue;
        };
        let (step, frequency) = step_of_labels(*step, *freq).map_err(|(entry, problem)| {
            let topic = if entry == STEP_LABEL {
                step_src
            } else {
                freq_src
            };
            label_err(topic, entry, k, problem)
        })?;
        let (f0, plan) = plans.entry(step).or_insert_with(|| {
            // The level is not known until the step is complete (estimated then).
            let excitation = estimated_excitation(frequency, f64::NAN);
            (
                frequency,
                StepPlan {
                    excitation,
                    sample_count: 0,
                    driven: None,
                    multisine_band_hz: None,
                },
            )
        });
        if *f0 != frequency {
            return Err(label_err(
                freq_src,
                FREQUENCY_LABEL,
                k,
                format!("step {step} changes frequency from {f0:?} Hz to {frequency:?} Hz"),
            ));
        }
        let time = Time::from_nanos(*t);
        let origin = *origin.get_or_insert(time);
        let sample = StepSample {
            t_s: time.secs_since(origin),
            t_resolution_s: 0.0,
            step,
            values: map
                .channels
                .iter()
                .map(|(c, _)| *c)
                .zip(values.iter().copied())
                .collect(),
        };
        let plan = plan.clone();
        for done in assembler.push_sample(&sample, Some(&plan)) {
            assembled.push(done.map_err(step_err)?);
        }
    }
    for done in assembler.finish_step() {
        assembled.push(done.map_err(step_err)?);
    }
    if assembled.is_empty() {
        let topics: Vec<&str> = map.channels.iter().map(|(_, s)| s.topic.as_str()).collect();
        return Err(ForeignBagError::Empty {
            path: p.to_string(),
            topics: topics.join(", "),
        });
    }
    let mut first_samples = Vec::new();
    let records = assembled
        .into_iter()
        .map(|a| {
            timing.add(&a);
            first_samples.push(a.first_sample);
            let mut r = a.record;
            let level = r.channel(driven).map_or(f64::NAN, rms_about_mean);
            r.excitation = estimated_excitation(r.excitation.frequency_hz(), level);
            r
        })
        .collect();
    Ok(Assembled {
        bag: RigBag {
            records,
            parameters: BTreeMap::new(),
            left_out: (left_before > 0)
                .then(|| format!("{left_before} samples before the first step label left out")),
            warnings: Vec::new(),
            notices: timing.notices(),
        },
        first_samples,
    })
}
