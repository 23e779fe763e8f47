//! A bag recorded by a bench's own tools, read through a [`ChannelMap`]: each mapped topic is
//! decoded from its definition (the bag's schema, a `.msg` file named by the map, or a
//! built-in standard message), the channels of different topics are aligned by their header
//! stamps (the log time for a message without a header), and the samples are assembled into
//! steps by the same [`StepAssembler`] as forcemap's own bags.
//!
//! Alignment: the samples take the times of a reference topic (the first channel's topic whose
//! type has a header, else the first channel's). The data topics must have one sample rate;
//! over the time span they all cover, each reference message takes the message of every other
//! data topic stamped within [`ALIGN_TOLERANCE`] sample intervals of it, once each (no
//! resampling: a lost message, a clock offset or a different rate is an error that says
//! which). The rule is [`crate::stamp_align`]'s, which the live `foreign` node applies too. The labels (`step`, `frequency_hz`) hold from their message's stamp (less
//! the tolerance) until the next one, so a state topic published once per step works as well as
//! one published with every sample; samples before the first label are left out. A map with
//! neither label gives the run as one record cut where its driven channel changes
//! ([`split_run`], as an unlabelled CSV export is cut, and as the harmonic node's `find_steps`
//! cuts the same samples live).

use std::collections::BTreeMap;
use std::path::Path;

use forcemap_math::recipe::SetupKind;
use forcemap_math::record::Record;
use forcemap_msgs::builtin_interfaces::Time;

use crate::bag::{BagError, BagReader};
use crate::channel_map::{ChannelMap, FREQUENCY_LABEL, STEP_LABEL, Source};
use crate::rig_bag::RigBag;
use crate::ros_msg::{Registry, builtin_registry, decode, has_header, header_stamp_ns, parse_msg};
use crate::stamp_align::{
    Aligned as AlignedMessage, StampAligner, median_interval_ns, tolerance_ns,
};
use crate::steps::unlabelled::split_run;
use crate::steps::{
    StepAssembler, StepError, StepPlan, StepRules, StepSample, estimated_excitation, rms_about_mean,
};
use forcemap_math::segment::SegmentOptions;

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

/// A mapped topic: its type's definitions and messages' times and values.
struct Topic {
    type_name: String,
    registry: Registry,
    /// Times are header stamps (else log times).
    stamped: bool,
    /// The map's entries read from this topic, in the order of each row's values.
    entries: Vec<String>,
    /// (time [ns], one value per entry), in time order.
    rows: Vec<(i64, Vec<f64>)>,
}

impl Topic {
    /// Where the value of `entry` is in a row.
    fn column(&self, entry: &str) -> usize {
        self.entries
            .iter()
            .position(|e| e == entry)
            .unwrap_or_default()
    }
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
    let mut topics: BTreeMap<&str, Topic> = BTreeMap::new();
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
        if !topics.contains_key(s.topic.as_str()) {
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
            topics.insert(
                &s.topic,
                Topic {
                    type_name: info.type_name.clone(),
                    stamped: has_header(&registry, &info.type_name),
                    registry,
                    entries: Vec::new(),
                    rows: Vec::new(),
                },
            );
        }
        let t = &topics[s.topic.as_str()];
        s.field
            .check(&t.registry, &t.type_name)
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

    // Every mapped topic's messages: time and values.
    for (name, topic) in &mut topics {
        let on_topic: Vec<(&str, &Source)> = sources
            .iter()
            .filter(|(_, s)| s.topic == *name)
            .copied()
            .collect();
        topic.entries = on_topic.iter().map(|(e, _)| e.to_string()).collect();
        let stamped = topic.stamped;
        for (index, m) in reader.messages_on(&[*name])?.enumerate() {
            let m = m?;
            let bad = |problem: String| ForeignBagError::Message {
                path: p.clone(),
                topic: name.to_string(),
                index,
                problem,
            };
            let value = decode(&topic.registry, &topic.type_name, &m.data)
                .map_err(|e| bad(format!("{} does not decode: {e}", topic.type_name)))?;
            let t = if stamped {
                let ns = header_stamp_ns(&value).ok_or_else(|| bad("no header stamp".into()))?;
                i64::try_from(ns).map_err(|_| bad(format!("stamp {ns} ns out of range")))?
            } else {
                i64::try_from(m.log_time).map_err(|_| bad("log time out of range".into()))?
            };
            let values = on_topic
                .iter()
                .map(|(_, s)| {
                    s.field
                        .get(&value)
                        .map(|raw| s.apply(raw))
                        .map_err(|e| bad(format!("field {}: {e}", s.field.text)))
                })
                .collect::<Result<Vec<f64>, _>>()?;
            topic.rows.push((t, values));
        }
        topic.rows.sort_by_key(|(t, _)| *t);
    }

    let samples = align(&p, map, &topics)?;
    let (Some(step_src), Some(freq_src)) = (&map.step, &map.frequency_hz) else {
        // No labels: the run as one random step, then cut where the drive changes.
        let one = vec![Some(0.0); samples.times.len()];
        let mut bag = assemble(&p, map, &samples, &one, &one)?;
        let run = bag.records.remove(0);
        let t0 = samples.times.first().copied().unwrap_or(0);
        let times_s: Vec<f64> = samples
            .times
            .iter()
            .map(|&t| Time::from_nanos(t).secs_since(Time::from_nanos(t0)))
            .collect();
        let driven = setup_kind(&p, map)?.driven_channel();
        bag.records = split_run(&run, driven, &times_s, &SegmentOptions::default())
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
        return Ok(bag);
    };
    let steps = label(&topics, STEP_LABEL, step_src, &samples);
    let freqs = label(&topics, FREQUENCY_LABEL, freq_src, &samples);
    assemble(&p, map, &samples, &steps, &freqs)
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

/// The aligned data: one time per sample (the reference topic's) and the channel values.
struct Aligned {
    times: Vec<i64>,
    /// Per sample, the channels' values in the map's order.
    values: Vec<Vec<f64>>,
    /// How far stamps of one instant may differ [ns].
    tolerance_ns: f64,
}

/// The median interval [ns] of a topic's times (0 with fewer than two).
fn median_interval(rows: &[(i64, Vec<f64>)]) -> f64 {
    median_interval_ns(rows.iter().map(|r| r.0))
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

fn align(
    p: &str,
    map: &ChannelMap,
    topics: &BTreeMap<&str, Topic>,
) -> Result<Aligned, ForeignBagError> {
    let err = |problem: String| ForeignBagError::Align {
        path: p.to_string(),
        problem,
    };
    let order = data_topic_order(map, |n| topics[n].stamped);
    let reference = order[0];
    let ref_rows = &topics[reference].rows;
    if ref_rows.len() < 2 {
        return Err(err(format!(
            "{reference} has {} messages: too few for a sample rate",
            ref_rows.len()
        )));
    }
    let interval = median_interval(ref_rows);
    if interval <= 0.0 {
        return Err(err(format!(
            "{reference}: most messages share one stamp (a median interval of 0 ns)"
        )));
    }
    let tol = tolerance_ns(interval);
    for name in &order[1..] {
        let rows = &topics[name].rows;
        if rows.len() < 2 {
            return Err(err(format!(
                "{name} has {} messages where {reference} has {}",
                rows.len(),
                ref_rows.len()
            )));
        }
        let other = median_interval(rows);
        if (other / interval - 1.0).abs() > RATE_TOLERANCE {
            return Err(err(format!(
                "{name} has a sample rate of {:.6} Hz where {reference} has {:.6} Hz: channels from different topics must share one rate (forcemap does not resample)",
                1e9 / other,
                1e9 / interval
            )));
        }
    }
    // Every topic's messages through the aligner, topic after topic; the first message that
    // breaks the rule is the error.
    let mut aligner = StampAligner::new(order.len(), tol, usize::MAX);
    let mut out = Vec::new();
    let mut times = Vec::new();
    let mut rows: Vec<Vec<f64>> = Vec::new();
    for (k, name) in order.iter().enumerate() {
        for (t, v) in &topics[name].rows {
            aligner.push(k, *t, v.clone(), &mut out);
            for a in out.drain(..) {
                match a {
                    AlignedMessage::Sample { t_ns, values } => {
                        times.push(t_ns);
                        rows.push(values);
                    }
                    AlignedMessage::Misaligned(m) => return Err(err(m.describe(&order, tol))),
                }
            }
        }
    }
    // Each channel's place in a row: the topics' values are concatenated in `order`.
    let mut offset = 0usize;
    let mut starts = BTreeMap::new();
    for name in &order {
        starts.insert(*name, offset);
        offset += topics[name].entries.len();
    }
    let places: Vec<usize> = map
        .channels
        .iter()
        .map(|(c, s)| starts[s.topic.as_str()] + topics[s.topic.as_str()].column(c.name()))
        .collect();
    let values = rows
        .iter()
        .map(|row| places.iter().map(|&i| row[i]).collect())
        .collect();
    Ok(Aligned {
        times,
        values,
        tolerance_ns: tol,
    })
}

/// The value of label `entry` at each sample time: that of its last message stamped at or
/// before it, within the alignment tolerance (`None` before the first).
fn label(
    topics: &BTreeMap<&str, Topic>,
    entry: &str,
    src: &Source,
    samples: &Aligned,
) -> Vec<Option<f64>> {
    let times = &samples.times;
    let t = &topics[src.topic.as_str()];
    let pos = t.column(entry);
    let mut out = Vec::with_capacity(times.len());
    let mut j = 0usize;
    let mut current = None;
    for &time in times {
        while j < t.rows.len() && t.rows[j].0 as f64 <= time as f64 + samples.tolerance_ns {
            current = Some(t.rows[j].1[pos]);
            j += 1;
        }
        out.push(current);
    }
    out
}

/// The aligned, labelled samples through the step assembler, then each step's excitation
/// level estimated from its driven channel (a bench's messages carry no amplitude).
fn assemble(
    p: &str,
    map: &ChannelMap,
    samples: &Aligned,
    steps: &[Option<f64>],
    freqs: &[Option<f64>],
) -> Result<RigBag, ForeignBagError> {
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
    let mut assembled: Vec<(Option<f64>, Record)> = Vec::new();
    let mut left_before = 0usize;
    for (k, (&t, values)) in samples.times.iter().zip(&samples.values).enumerate() {
        let (Some(step), Some(freq)) = (steps[k], freqs[k]) else {
            left_before += 1;
            continue;
        };
        if !(step.is_finite() && step >= 0.0 && step.fract() == 0.0 && step <= u32::MAX as f64) {
            return Err(label_err(
                step_src,
                STEP_LABEL,
                k,
                format!("{step} is not a whole number from 0"),
            ));
        }
        if !(freq.is_finite() && freq >= 0.0) {
            return Err(label_err(
                freq_src,
                FREQUENCY_LABEL,
                k,
                format!("{freq} Hz is not a frequency (0 for random excitation)"),
            ));
        }
        let step = step as usize;
        let frequency = (freq > 0.0).then_some(freq);
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
        let time = Time::from_nanos(t);
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
            let a = done.map_err(step_err)?;
            assembled.push((frequency_of(&a.record), a.record));
        }
    }
    for done in assembler.finish_step() {
        let a = done.map_err(step_err)?;
        assembled.push((frequency_of(&a.record), a.record));
    }
    if assembled.is_empty() {
        let topics: Vec<&str> = map.channels.iter().map(|(_, s)| s.topic.as_str()).collect();
        return Err(ForeignBagError::Empty {
            path: p.to_string(),
            topics: topics.join(", "),
        });
    }
    let driven = setup_kind(p, map)?.driven_channel();
    let records = assembled
        .into_iter()
        .map(|(frequency, mut r)| {
            let level = r.channel(driven).map_or(f64::NAN, rms_about_mean);
            r.excitation = estimated_excitation(frequency, level);
            r
        })
        .collect();
    Ok(RigBag {
        records,
        parameters: BTreeMap::new(),
        left_out: (left_before > 0)
            .then(|| format!("{left_before} samples before the first step label left out")),
        warnings: Vec::new(),
        notices: Vec::new(),
    })
}

fn frequency_of(r: &Record) -> Option<f64> {
    r.excitation.frequency_hz()
}
