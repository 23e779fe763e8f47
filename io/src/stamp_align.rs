//! Aligning the messages of several topics into samples by their stamps: the one rule both the
//! offline foreign bag ([`crate::foreign_bag`]) and the live source of foreign topics (the
//! `foreign` node) apply, message by message, so that a bag and a live graph fed the same
//! messages give the same samples.
//!
//! The rule: the samples take the times of a reference topic (topic 0). Each reference message
//! takes the first message of every other topic stamped within the tolerance of it (at most
//! one can be, the topics sharing one rate and the tolerance being 1 % of the interval), once
//! each; no values are interpolated. Messages before the span every topic covers (before the
//! latest first message, less the tolerance) are left out without a word, as are those after it
//! (still waiting when the stream ends). Within the span, a reference message that no message
//! of another topic matches is lost (the report names the nearest), and a message of another
//! topic that no reference message takes is extra; both are reported as [`Misalignment`]s, and
//! the sample is not made.

use std::collections::VecDeque;

/// How far (in sample intervals) the stamps of one sample on different topics may differ.
/// Values are not interpolated: 1 % of an interval is a phase error of 0.036 degrees at a
/// tenth of the sample rate.
pub const ALIGN_TOLERANCE: f64 = 0.01;
/// How far (relative) the sample rates of the data topics may differ.
pub const RATE_TOLERANCE: f64 = 1e-3;

/// The tolerance [ns] for topics sampled every `interval_ns`.
pub fn tolerance_ns(interval_ns: f64) -> f64 {
    (ALIGN_TOLERANCE * interval_ns).max(1.0)
}

/// The median interval [ns] of times in order (0 with fewer than two).
pub fn median_interval_ns(times: impl IntoIterator<Item = i64>) -> f64 {
    let times: Vec<i64> = times.into_iter().collect();
    let mut d: Vec<i64> = times.windows(2).map(|w| w[1] - w[0]).collect();
    if d.is_empty() {
        return 0.0;
    }
    d.sort_unstable();
    d[d.len() / 2] as f64
}

/// A message that breaks the rule, within the span all topics cover.
#[derive(Debug, Clone, PartialEq)]
pub enum Misalignment {
    /// Reference message number `sample` (counted from the span's start), at `t_ns`, has no
    /// message of `topic` within the tolerance; the nearest is `nearest_offset_ns` away.
    Lost {
        sample: usize,
        t_ns: i64,
        topic: usize,
        nearest_offset_ns: Option<i64>,
    },
    /// The message of `topic` at `t_ns` matches no reference message.
    Extra { topic: usize, t_ns: i64 },
    /// The message of `topic` at `t_ns` is stamped before the one before it (`after_ns`).
    OutOfOrder {
        topic: usize,
        t_ns: i64,
        after_ns: i64,
    },
}

impl Misalignment {
    /// What went wrong, with the topics' names (`names[0]` is the reference).
    pub fn describe(&self, names: &[&str], tolerance_ns: f64) -> String {
        match *self {
            Misalignment::Lost {
                sample,
                t_ns,
                topic,
                nearest_offset_ns,
            } => {
                let nearest = match nearest_offset_ns {
                    Some(d) => format!(
                        "the nearest {} message is {:.9} s away",
                        names[topic],
                        d as f64 * 1e-9
                    ),
                    None => format!("no {} message came", names[topic]),
                };
                format!(
                    "sample {sample} ({} at {t_ns} ns): {nearest}; stamps must agree within {:.3e} s (a lost message, or clocks that differ)",
                    names[0],
                    tolerance_ns * 1e-9
                )
            }
            Misalignment::Extra { topic, t_ns } => format!(
                "the {} message at {t_ns} ns matches no {} message (duplicated or extra messages)",
                names[topic], names[0]
            ),
            Misalignment::OutOfOrder {
                topic,
                t_ns,
                after_ns,
            } => format!(
                "the {} message at {t_ns} ns comes after one at {after_ns} ns (stamps out of order)",
                names[topic]
            ),
        }
    }
}

/// What the aligner gives: a sample, or a message that breaks the rule.
#[derive(Debug, Clone, PartialEq)]
pub enum Aligned {
    /// The reference time and every topic's values, concatenated in topic order.
    Sample {
        t_ns: i64,
        values: Vec<f64>,
    },
    Misaligned(Misalignment),
}

/// The streaming aligner: messages go in per topic, in stamp order, samples come out as soon
/// as every topic has a message for them.
#[derive(Debug, Clone)]
pub struct StampAligner {
    tolerance_ns: f64,
    queues: Vec<VecDeque<(i64, Vec<f64>)>>,
    first_ns: Vec<Option<i64>>,
    last_pushed_ns: Vec<Option<i64>>,
    last_taken_ns: Vec<Option<i64>>,
    /// Reference messages judged within the span so far.
    judged: usize,
    /// Reference messages that may wait for the other topics before they count as lost.
    max_pending: usize,
}

impl StampAligner {
    /// An aligner of `topics` topics (0 the reference) with `tolerance_ns` (see
    /// [`tolerance_ns`]); at most `max_pending` reference messages wait for another topic.
    pub fn new(topics: usize, tolerance_ns: f64, max_pending: usize) -> StampAligner {
        StampAligner {
            tolerance_ns,
            queues: vec![VecDeque::new(); topics],
            first_ns: vec![None; topics],
            last_pushed_ns: vec![None; topics],
            last_taken_ns: vec![None; topics],
            judged: 0,
            max_pending: max_pending.max(1),
        }
    }

    pub fn tolerance_ns(&self) -> f64 {
        self.tolerance_ns
    }

    /// The span's start, once every topic has had a message.
    fn span_start(&self) -> Option<f64> {
        let mut start = i64::MIN;
        for f in &self.first_ns {
            start = start.max((*f)?);
        }
        Some(start as f64 - self.tolerance_ns)
    }

    /// Adds a message of `topic` and appends what it completes to `out`.
    pub fn push(&mut self, topic: usize, t_ns: i64, values: Vec<f64>, out: &mut Vec<Aligned>) {
        if let Some(after_ns) = self.last_pushed_ns[topic]
            && t_ns <= after_ns
        {
            out.push(Aligned::Misaligned(Misalignment::OutOfOrder {
                topic,
                t_ns,
                after_ns,
            }));
            return;
        }
        self.last_pushed_ns[topic] = Some(t_ns);
        self.first_ns[topic].get_or_insert(t_ns);
        self.queues[topic].push_back((t_ns, values));
        self.process(out);
    }

    fn process(&mut self, out: &mut Vec<Aligned>) {
        let Some(span_start) = self.span_start() else {
            return;
        };
        let tol = self.tolerance_ns;
        'reference: while let Some(&(t, _)) = self.queues[0].front() {
            let in_span = t as f64 >= span_start;
            // Per other topic: how many messages are too old for t, and whether the next one
            // matches (Some(true)), lies beyond (Some(false)) or has not come (None).
            let mut skips = vec![0usize; self.queues.len()];
            let mut lost: Option<(usize, Option<i64>)> = None;
            let mut waiting = false;
            for (j, (q, skip)) in self.queues.iter().zip(skips.iter_mut()).enumerate().skip(1) {
                let skipped = q
                    .iter()
                    .take_while(|(u, _)| (*u as f64) < t as f64 - tol)
                    .count();
                *skip = skipped;
                match q.get(skipped) {
                    None => waiting = true,
                    Some(&(u, _)) if (u as f64) <= t as f64 + tol => {}
                    Some(&(u, _)) => {
                        if lost.is_none() {
                            let before = skipped
                                .checked_sub(1)
                                .map(|k| q[k].0)
                                .or(self.last_taken_ns[j]);
                            let nearest = [before, Some(u)]
                                .into_iter()
                                .flatten()
                                .min_by_key(|v| (v - t).abs())
                                .map(|v| v - t);
                            lost = Some((j, nearest));
                        }
                    }
                }
            }
            if lost.is_none() && waiting {
                if self.queues[0].len() <= self.max_pending {
                    return;
                }
                // A topic went quiet: the oldest reference message cannot wait any longer.
                let j = (1..self.queues.len())
                    .find(|&j| self.queues[j].len() <= skips[j])
                    .unwrap_or(1);
                lost = Some((j, None));
            }
            if let Some((topic, nearest_offset_ns)) = lost {
                self.queues[0].pop_front();
                if in_span {
                    out.push(Aligned::Misaligned(Misalignment::Lost {
                        sample: self.judged,
                        t_ns: t,
                        topic,
                        nearest_offset_ns,
                    }));
                    self.judged += 1;
                }
                continue 'reference;
            }
            // Every topic matches: the sample, after the extra messages before it.
            let Some((_, mut values)) = self.queues[0].pop_front() else {
                return;
            };
            for (j, &skipped) in skips.iter().enumerate().skip(1) {
                for _ in 0..skipped {
                    if let Some((u, _)) = self.queues[j].pop_front()
                        && (u as f64) >= span_start
                    {
                        out.push(Aligned::Misaligned(Misalignment::Extra {
                            topic: j,
                            t_ns: u,
                        }));
                    }
                }
                if let Some((u, v)) = self.queues[j].pop_front() {
                    self.last_taken_ns[j] = Some(u);
                    values.extend(v);
                }
            }
            if in_span {
                self.judged += 1;
            }
            out.push(Aligned::Sample { t_ns: t, values });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: i64 = 1_000_000;

    fn run(pushes: &[(usize, i64)]) -> Vec<Aligned> {
        let mut a = StampAligner::new(2, tolerance_ns(10.0 * MS as f64), 1000);
        let mut out = Vec::new();
        for &(topic, t) in pushes {
            a.push(topic, t, vec![t as f64 + topic as f64], &mut out);
        }
        out
    }

    fn samples(out: &[Aligned]) -> Vec<i64> {
        out.iter()
            .filter_map(|a| match a {
                Aligned::Sample { t_ns, .. } => Some(*t_ns),
                Aligned::Misaligned(_) => None,
            })
            .collect()
    }

    #[test]
    fn interleaved_and_batched_pushes_give_the_same_samples() {
        let t: Vec<i64> = (0..20).map(|i| i * 10 * MS).collect();
        let interleaved: Vec<(usize, i64)> =
            t.iter().flat_map(|&t| [(0, t), (1, t + 50_000)]).collect();
        let batched: Vec<(usize, i64)> = t
            .iter()
            .map(|&t| (0, t))
            .chain(t.iter().map(|&t| (1, t + 50_000)))
            .collect();
        let a = run(&interleaved);
        assert_eq!(a, run(&batched));
        assert_eq!(samples(&a), t);
        assert_eq!(
            a[3],
            Aligned::Sample {
                t_ns: 30 * MS,
                values: vec![30.0 * MS as f64, 30.0 * MS as f64 + 50_000.0 + 1.0]
            }
        );
    }

    #[test]
    fn messages_outside_the_common_span_are_left_out_quietly() {
        // Topic 1 starts 3 samples late and ends 2 early.
        let mut p: Vec<(usize, i64)> = (0..10).map(|i| (0, i * 10 * MS)).collect();
        p.extend((3..8).map(|i| (1, i * 10 * MS)));
        let out = run(&p);
        assert!(
            out.iter().all(|a| matches!(a, Aligned::Sample { .. })),
            "{out:?}"
        );
        assert_eq!(
            samples(&out),
            (3..8).map(|i| i * 10 * MS).collect::<Vec<_>>()
        );
    }

    #[test]
    fn a_lost_message_and_an_extra_one_are_reported_with_the_nearest() {
        let mut p: Vec<(usize, i64)> = (0..10).map(|i| (0, i * 10 * MS)).collect();
        p.extend((0..10).filter(|&i| i != 4).map(|i| (1, i * 10 * MS)));
        p.push((1, 95 * MS));
        p.sort_by_key(|&(topic, t)| (t, topic));
        let out = run(&p);
        assert_eq!(samples(&out).len(), 9);
        assert!(out.contains(&Aligned::Misaligned(Misalignment::Lost {
            sample: 4,
            t_ns: 40 * MS,
            topic: 1,
            nearest_offset_ns: Some(-10 * MS),
        })));
        // The extra one at 95 ms is reported once a later reference message passes it: none
        // does, so it is after the span's end and left out.
        let mut p2 = p.clone();
        p2.push((0, 100 * MS));
        p2.push((1, 100 * MS));
        let out = run(&p2);
        assert!(out.contains(&Aligned::Misaligned(Misalignment::Extra {
            topic: 1,
            t_ns: 95 * MS
        })));
    }

    #[test]
    fn a_quiet_topic_loses_the_oldest_reference_messages_beyond_the_limit() {
        let mut a = StampAligner::new(2, 1.0, 3);
        let mut out = Vec::new();
        a.push(1, 0, vec![], &mut out);
        a.push(0, 0, vec![], &mut out);
        for i in 1..6 {
            a.push(0, i * 10, vec![], &mut out);
        }
        let lost: Vec<&Aligned> = out
            .iter()
            .filter(|o| {
                matches!(
                    o,
                    Aligned::Misaligned(Misalignment::Lost {
                        nearest_offset_ns: None,
                        ..
                    })
                )
            })
            .collect();
        assert_eq!((samples(&out), lost.len()), (vec![0], 2), "{out:?}");
    }

    #[test]
    fn stamps_out_of_order_are_refused() {
        let out = run(&[(0, 10), (0, 5)]);
        assert_eq!(
            out,
            vec![Aligned::Misaligned(Misalignment::OutOfOrder {
                topic: 0,
                t_ns: 5,
                after_ns: 10
            })]
        );
    }
}
