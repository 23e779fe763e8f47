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
//!
//! **Messages without a header** are timed by when they were received. Beside a stamped
//! reference, receive times lag the stamps by the network's and the scheduler's delay
//! (milliseconds, with jitter), far more than the 1 % tolerance: such a message is timed by its
//! receive time less the reference's own delay ([`ReceiveTiming`]: the median of receive time
//! less stamp over the reference's first [`LEARN_MESSAGES`] messages) and taken by the nearest
//! reference message within half an interval ([`ReceiveTiming::window_ns`]), i.e. rounded to the
//! nearest sample. This assumes the headerless topic is published at the instants of the
//! reference and travels alike: a message whose delay differs from the reference's by more than
//! half an interval lands on a neighbouring sample. When the reference's delays spread over
//! half an interval or more (interquartile range) no consistent offset exists. With an
//! unstamped reference every topic is timed by its receive times as they are, and the other
//! topics are taken within half an interval too.
//!
//! **Labels** (a step's index, its frequency) hold from the sample nearest their message's time
//! (its stamp, or its receive time less the reference's delay), within half an interval, until
//! the next message ([`LabelTrack`]): a label published at a step's first sample and received a
//! few milliseconds later still starts the step there.

use std::collections::VecDeque;

/// How far (in sample intervals) the stamps of one sample on different topics may differ.
/// Values are not interpolated: 1 % of an interval is a phase error of 0.036 degrees at a
/// tenth of the sample rate.
pub const ALIGN_TOLERANCE: f64 = 0.01;
/// How far (relative) the sample rates of the data topics may differ.
pub const RATE_TOLERANCE: f64 = 1e-3;

/// Reference messages that measure the sample interval and the receive delay before the first
/// sample is made.
pub const LEARN_MESSAGES: usize = 16;

/// The tolerance [ns] for topics sampled every `interval_ns`.
pub fn tolerance_ns(interval_ns: f64) -> f64 {
    (ALIGN_TOLERANCE * interval_ns).max(1.0)
}

/// How messages timed by their receive time are put on the reference's samples (see the
/// module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReceiveTiming {
    /// The reference's delay: the median of receive time less stamp [ns] (0 for an unstamped
    /// reference, timed by its receive times itself).
    pub delay_ns: i64,
    /// The interquartile range of those delays [ns].
    pub spread_ns: i64,
    /// The reference's sample interval [ns].
    pub interval_ns: f64,
}

impl ReceiveTiming {
    /// The timing from the reference's delays (receive time less stamp, at least one) and
    /// interval.
    pub fn learn(mut delays_ns: Vec<i64>, interval_ns: f64) -> ReceiveTiming {
        delays_ns.sort_unstable();
        let n = delays_ns.len();
        let (delay_ns, spread_ns) = match n {
            0 => (0, 0),
            _ => (delays_ns[n / 2], delays_ns[(3 * n) / 4] - delays_ns[n / 4]),
        };
        ReceiveTiming {
            delay_ns,
            spread_ns,
            interval_ns,
        }
    }

    /// The timing of an unstamped reference: receive times as they are.
    pub fn unstamped(interval_ns: f64) -> ReceiveTiming {
        ReceiveTiming::learn(Vec::new(), interval_ns)
    }

    /// Whether the delays agree well enough (spread under half an interval) to time messages
    /// without a header by them.
    pub fn consistent(&self) -> bool {
        (self.spread_ns as f64) < 0.5 * self.interval_ns
    }

    /// The time a message received at `receive_ns` stands for: less the reference's delay.
    pub fn time_ns(&self, receive_ns: i64) -> i64 {
        receive_ns - self.delay_ns
    }

    /// How far from a sample a message timed by its receive time, or a label, may be and be
    /// that sample's: half an interval (the nearest sample's).
    pub fn window_ns(&self) -> f64 {
        0.5 * self.interval_ns
    }

    /// Why the topics `headerless` cannot be timed (when not [`consistent`](Self::consistent)).
    pub fn inconsistency(&self, reference: &str, headerless: &[&str]) -> String {
        format!(
            "{reference}: its receive times lag its stamps by amounts that spread over {:.6} s (interquartile range of its first {LEARN_MESSAGES} messages), half a sample interval ({:.6} s) or more: no consistent offset to time the topics without a header ({}) by (publish a type with a header, stamped with the reference's clock)",
            self.spread_ns as f64 * 1e-9,
            0.5 * self.interval_ns * 1e-9,
            headerless.join(", ")
        )
    }
}

/// A label over the samples: each message's value holds from the sample nearest its time
/// (within half an interval: the first sample at or after its time less the window) until the
/// next message's (see the module docs).
#[derive(Debug, Clone, Default)]
pub struct LabelTrack {
    queue: VecDeque<(i64, f64)>,
    current: Option<f64>,
    newest_ns: Option<i64>,
}

impl LabelTrack {
    /// Adds a message at `t_ns`; one before the newest so far is refused (`Err` with it).
    pub fn push(&mut self, t_ns: i64, value: f64) -> Result<(), i64> {
        if let Some(newest) = self.newest_ns
            && t_ns < newest
        {
            return Err(newest);
        }
        self.newest_ns = Some(t_ns);
        self.queue.push_back((t_ns, value));
        Ok(())
    }

    /// Whether the value at the sample at `t_ns` is known: a message past its window came.
    pub fn settled_at(&self, t_ns: i64, window_ns: f64) -> bool {
        self.newest_ns
            .is_some_and(|n| n as f64 > t_ns as f64 + window_ns)
    }

    /// The value at the sample at `t_ns` (`None` before the first message); samples are asked
    /// in time order.
    pub fn at(&mut self, t_ns: i64, window_ns: f64) -> Option<f64> {
        while let Some(&(u, v)) = self.queue.front() {
            if u as f64 > t_ns as f64 + window_ns {
                break;
            }
            self.current = Some(v);
            self.queue.pop_front();
        }
        self.current
    }
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
    /// What went wrong, with the topics' names (`names[0]` is the reference) and the tolerance
    /// of the topic concerned; `received` when that topic is timed by its receive times.
    pub fn describe(&self, names: &[&str], tolerance_ns: f64, received: bool) -> String {
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
                if received {
                    format!(
                        "sample {sample} ({} at {t_ns} ns): {nearest} (timed by its receive time less the reference's delay); it must be within half an interval ({:.3e} s) of a sample (a lost message, or a delay unlike the reference's)",
                        names[0],
                        tolerance_ns * 1e-9
                    )
                } else {
                    format!(
                        "sample {sample} ({} at {t_ns} ns): {nearest}; stamps must agree within {:.3e} s (a lost message, or clocks that differ)",
                        names[0],
                        tolerance_ns * 1e-9
                    )
                }
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
    /// Per topic: how far from a reference message its messages may be.
    tolerances_ns: Vec<f64>,
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
            tolerances_ns: vec![tolerance_ns; topics],
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

    /// The same aligner taking `topic`'s messages within `window_ns` of a reference message (a
    /// topic timed by its receive times: [`ReceiveTiming::window_ns`]).
    pub fn with_window(mut self, topic: usize, window_ns: f64) -> StampAligner {
        self.tolerances_ns[topic] = window_ns;
        self
    }

    /// A misalignment in words, with the topics' names (`names[0]` is the reference) and the
    /// tolerance of the topic concerned.
    pub fn describe(&self, m: &Misalignment, names: &[&str]) -> String {
        let topic = match *m {
            Misalignment::Lost { topic, .. }
            | Misalignment::Extra { topic, .. }
            | Misalignment::OutOfOrder { topic, .. } => topic,
        };
        let tol = self.tolerances_ns[topic];
        m.describe(names, tol, tol > self.tolerance_ns)
    }

    /// The span's start, once every topic has had a message.
    fn span_start(&self) -> Option<f64> {
        let mut start = f64::NEG_INFINITY;
        for (f, tol) in self.first_ns.iter().zip(&self.tolerances_ns) {
            start = start.max((*f)? as f64 - tol);
        }
        Some(start)
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
        'reference: while let Some(&(t, _)) = self.queues[0].front() {
            let in_span = t as f64 >= span_start;
            // Per other topic: how many messages are too old for t, and whether the next one
            // matches (Some(true)), lies beyond (Some(false)) or has not come (None).
            let mut skips = vec![0usize; self.queues.len()];
            let mut lost: Option<(usize, Option<i64>)> = None;
            let mut waiting = false;
            for (j, (q, skip)) in self.queues.iter().zip(skips.iter_mut()).enumerate().skip(1) {
                let tol = self.tolerances_ns[j];
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
