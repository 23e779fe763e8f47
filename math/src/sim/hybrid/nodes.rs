//! When a run is integrated: its nodes (samples and input breakpoints, in time order) and the
//! RK4 sub-steps of an interval between two nodes.

/// RK4 sub-steps of an interval of length `d` with sub-steps of at most `max_s`: `ceil(d /
/// max_s)`, but one for an interval as long as `max_s` but for the rounding of the sample times
/// (`(i + 1) / fs - i / fs` exceeds `1 / fs` in its last bits for about half the intervals: at
/// 10 kHz with 0.1 ms sub-steps `ceil` alone would split them in two, 1.3 to 1.6 sub-steps per
/// sample).
pub(super) fn substeps(d: f64, max_s: f64) -> usize {
    if d <= max_s * (1.0 + 1e-9) {
        return 1;
    }
    // `ceil` without the libm call (x86-64 baseline has no rounding instruction); d / max_s
    // is above 1 here.
    let x = d / max_s;
    let n = x as usize;
    if (n as f64) < x { n + 1 } else { n }
}

/// The integration nodes of a run, (time, sample index, is input breakpoint), in time order:
/// the samples `i / sample_rate_hz`, a breakpoint within 1e-12 (relative) of a sample marking
/// it, the others merged in (after a sample of the same time, in their given order when
/// equal). Generated one at a time, so a run of any length needs memory only for its
/// breakpoints.
pub(super) struct Nodes {
    samples: usize,
    sample_rate_hz: f64,
    /// Samples that are breakpoints, ascending.
    marked: Vec<usize>,
    /// Breakpoints between samples, ascending (stable).
    between: Vec<f64>,
    next_sample: usize,
    next_marked: usize,
    next_between: usize,
}

impl Nodes {
    pub(super) fn new(samples: usize, sample_rate_hz: f64, breaks: &[f64]) -> Nodes {
        let t_end = (samples.max(1) - 1) as f64 / sample_rate_hz;
        let mut marked = Vec::new();
        let mut between = Vec::new();
        for &b in breaks {
            if b <= 0.0 || b > t_end {
                continue;
            }
            let i = (b * sample_rate_hz).round() as usize;
            if i < samples && (i as f64 / sample_rate_hz - b).abs() <= 1e-12 * b.max(1.0) {
                marked.push(i);
            } else {
                between.push(b);
            }
        }
        marked.sort_unstable();
        marked.dedup();
        between.sort_by(f64::total_cmp);
        Nodes {
            samples,
            sample_rate_hz,
            marked,
            between,
            next_sample: 0,
            next_marked: 0,
            next_between: 0,
        }
    }
}

impl Iterator for Nodes {
    type Item = (f64, Option<usize>, bool);

    fn next(&mut self) -> Option<Self::Item> {
        let sample = (self.next_sample < self.samples)
            .then(|| self.next_sample as f64 / self.sample_rate_hz);
        let between = self.between.get(self.next_between).copied();
        match (sample, between) {
            (Some(ts), Some(tb)) if tb.total_cmp(&ts).is_lt() => {
                self.next_between += 1;
                Some((tb, None, true))
            }
            (Some(ts), _) => self.take_sample(ts),
            (None, Some(tb)) => {
                self.next_between += 1;
                Some((tb, None, true))
            }
            (None, None) => None,
        }
    }
}

impl Nodes {
    /// After sample `k` was taken: the samples from `k` on that are plain nodes followed by the
    /// next sample, as far as marks and the run's end say (`k..end`, each not a breakpoint and
    /// not the last sample), and the next breakpoint between samples (infinity if none): an
    /// interval `[t_s, t_s+1]` of that range is a node interval only while that breakpoint is
    /// not before `t_s+1`.
    pub(super) fn plain_after(&self, k: usize) -> (usize, f64) {
        let last = self.samples.saturating_sub(1);
        let end = self
            .marked
            .get(self.next_marked)
            .map_or(last, |&m| m.min(last));
        let between = self.between.get(self.next_between).copied();
        (end.max(k), between.unwrap_or(f64::INFINITY))
    }

    /// Goes on from sample `i` (after samples up to `i - 1` were taken outside the iterator,
    /// none of them a breakpoint and no breakpoint between them).
    pub(super) fn resume_at(&mut self, i: usize) {
        self.next_sample = i;
    }

    pub(super) fn take_sample(&mut self, t: f64) -> Option<(f64, Option<usize>, bool)> {
        let i = self.next_sample;
        self.next_sample += 1;
        let marked = self.marked.get(self.next_marked) == Some(&i);
        if marked {
            self.next_marked += 1;
        }
        Some((t, Some(i), marked))
    }
}

#[cfg(test)]
mod tests {
    use super::substeps;

    /// A 10 kHz sample interval is one 0.1 ms sub-step whatever the rounding of its sample
    /// times (`ceil` gave two for about half of them); longer intervals are cut as `ceil` cuts
    /// them, so the 100 Hz runs keep their sub-steps.
    #[test]
    fn a_sample_interval_as_long_as_a_substep_is_one() {
        let max_s = 1e-4;
        let (mut rounded_up, mut checked) = (0, 0);
        for i in (0..1_600_000_u32).step_by(7) {
            let d = f64::from(i + 1) / 10_000.0 - f64::from(i) / 10_000.0;
            rounded_up += usize::from(d > max_s);
            assert_eq!(substeps(d, max_s), 1, "sample {i}: {d:e}");
            checked += 1;
        }
        assert!(rounded_up > checked / 4, "{rounded_up} of {checked}");
        for i in 0..16_000_u32 {
            let d = f64::from(i + 1) / 100.0 - f64::from(i) / 100.0;
            assert_eq!(substeps(d, max_s), (d / max_s).ceil() as usize, "{d:e}");
        }
        assert_eq!(substeps(2.5e-4, max_s), 3);
        assert_eq!(substeps(1e-9, max_s), 1);
    }
}
