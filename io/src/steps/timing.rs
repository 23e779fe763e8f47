//! The timing rule of a step's samples, one for CSV exports, bags and the harmonic node: times
//! as benches record them (a DAQ that pauses between steps, a lost sample, PC-clock stamps with
//! jitter) read into uniformly sampled records.
//!
//! - **Exact** stamps (every interval within the source's [`IntervalRule`](super::IntervalRule)
//!   of the step's interval): one record, as they are.
//! - **A break** (an interval more than [`BREAK_MIN_INTERVALS`] times the intervals around it,
//!   the median of up to [`BREAK_CONTEXT_INTERVALS`] on each side) ends a record: the samples
//!   after it are another record of the same step. Under [`PAUSE_MIN_INTERVALS`] it stands for
//!   lost samples (one or two), beyond for a pause. Pieces between two breaks with fewer than
//!   [`MIN_STEP_SAMPLES`](super::MIN_STEP_SAMPLES) samples are left out. Each side's own median
//!   is the reference, so a pause between parts sampled at different rates is found too.
//! - **Jitter**: within a part, stamps within [`JITTER_MAX_INTERVALS`] of an interval of the
//!   uniform grid fitted to them (least squares), plus half the rounding of written times, are
//!   read as uniform (a PC clock); the jitter (RMS and largest distance from the grid) is
//!   reported, and the rate's snapping to a whole number of Hz allows for it. A stamp further
//!   off that is no break (a duplicate, a slip of a fraction of an interval) is refused as not
//!   uniform.

use super::StepFault;

/// Stamps within this fraction of an interval of their fitted uniform grid are uniform sampling
/// with jitter. At most 0.1, so that an interval between two of them (at most 1.2 intervals)
/// is never more than [`BREAK_MIN_INTERVALS`] times the intervals around it (at least 0.8).
pub const JITTER_MAX_INTERVALS: f64 = 0.1;
/// An interval more than this many times the intervals around it is a break: one lost sample
/// gives 2, a jittered uniform interval at most 1.5 (see [`JITTER_MAX_INTERVALS`]).
pub const BREAK_MIN_INTERVALS: f64 = 1.5;
/// A break of at least this many intervals is a pause (no samples for a while); a shorter one
/// stands for one or two lost samples.
pub const PAUSE_MIN_INTERVALS: f64 = 3.5;
/// How many intervals on each side of an interval are its context (their median is what it is
/// compared with).
pub const BREAK_CONTEXT_INTERVALS: usize = 8;
/// Relative tolerance within which a measured sample rate is snapped to a whole number of Hz
/// beyond the uncertainty of its times (their rounding and jitter).
pub const RATE_SNAP_REL_TOL: f64 = 1e-6;

/// A break in a step's samples: sample `sample` (counted in the step) follows the one before
/// after `interval_s` where the intervals around are `reference_s`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Break {
    pub sample: usize,
    pub interval_s: f64,
    pub reference_s: f64,
}

impl Break {
    /// The samples the break stands for when it is short ([`PAUSE_MIN_INTERVALS`]); `None`
    /// for a pause.
    pub fn lost_samples(&self) -> Option<usize> {
        let intervals = self.interval_s / self.reference_s;
        (intervals < PAUSE_MIN_INTERVALS).then(|| (intervals.round() as usize).max(2) - 1)
    }

    /// What the break is: `2 samples lost (an interval of 0.003 s where the samples around are
    /// 0.001 s apart)` or `a pause of 0.501 s`.
    pub fn describe(&self) -> String {
        match self.lost_samples() {
            Some(k) => format!(
                "{k} sample{} lost (an interval of {:.6} s where the samples around are {:.6} s apart)",
                if k == 1 { "" } else { "s" },
                self.interval_s,
                self.reference_s
            ),
            None => format!("a pause of {:.6} s", self.interval_s),
        }
    }
}

/// What the timing rule did to a step, each at a sample counted in the step.
#[derive(Debug, Clone, PartialEq)]
pub enum TimingNote {
    /// The step's samples break before `Break::sample`: a new record starts there.
    Break(Break),
    /// Samples `first..first + count` lie between two breaks (or a break and the step's end),
    /// too few for a record: left out.
    LeftOut { first: usize, count: usize },
}

impl TimingNote {
    /// The note for a source without lines, naming the step (its label; `None`: an unlabelled
    /// run) and samples counted in it: `step 3, sample 1200: 1 sample lost (...): the step goes
    /// on in another record from there`.
    pub fn describe(&self, step: Option<usize>) -> String {
        let what = step.map_or_else(|| "the run".to_string(), |s| format!("step {s}"));
        match self {
            TimingNote::Break(b) => format!(
                "{what}, sample {}: {}: {}",
                b.sample,
                b.describe(),
                match step {
                    Some(_) => "the step goes on in another record from there",
                    None => "the run is cut there, each part searched for steps apart",
                }
            ),
            TimingNote::LeftOut { first, count } => format!(
                "{what}, samples {first}-{}: {count} sample{} between breaks of the sampling, too few for a record: left out",
                first + count - 1,
                if *count == 1 { "" } else { "s" }
            ),
        }
    }
}

/// What the timing rule did to a source's records, for its notices: each note, and one notice
/// of the jitter.
#[derive(Debug, Clone, Default)]
pub struct TimingReport {
    notes: Vec<String>,
    jitter: JitterSummary,
    /// The records are the parts of an unlabelled run (one step of the assembler).
    unlabelled: bool,
}

impl TimingReport {
    /// The report of an unlabelled run's parts.
    pub fn of_run() -> TimingReport {
        TimingReport {
            unlabelled: true,
            ..TimingReport::default()
        }
    }

    pub fn add(&mut self, a: &super::AssembledStep) {
        self.jitter.add(a.timing.jitter.as_ref());
        let step = (!self.unlabelled).then_some(a.label);
        self.notes.extend(a.notes.iter().map(|n| n.describe(step)));
    }

    /// The notices, in order, the jitter's last.
    pub fn notices(self) -> Vec<String> {
        let mut out = self.notes;
        out.extend(self.jitter.notice());
        out
    }
}

/// How far a record's sample times scatter about the uniform grid fitted to them (least
/// squares).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Jitter {
    pub rms_s: f64,
    pub max_s: f64,
    /// The grid's interval [s].
    pub interval_s: f64,
    pub samples: usize,
}

/// The uniform grid fitted to stamps by least squares: `t_k = intercept + slope k`.
struct Grid {
    intercept: f64,
    slope: f64,
}

impl Grid {
    fn of(stamps: &[f64]) -> Grid {
        let n = stamps.len();
        let k_mean = (n - 1) as f64 / 2.0;
        let t_mean = stamps.iter().sum::<f64>() / n as f64;
        let (mut skt, mut skk) = (0.0, 0.0);
        for (k, t) in stamps.iter().enumerate() {
            let dk = k as f64 - k_mean;
            skt += dk * (t - t_mean);
            skk += dk * dk;
        }
        let slope = skt / skk;
        Grid {
            intercept: t_mean - slope * k_mean,
            slope,
        }
    }

    fn residual(&self, k: usize, t: f64) -> f64 {
        t - (self.intercept + self.slope * k as f64)
    }
}

impl Jitter {
    /// The jitter of `stamps` (at least two) about their least-squares grid.
    pub fn of(stamps: &[f64]) -> Jitter {
        let grid = Grid::of(stamps);
        let (mut sum2, mut max) = (0.0f64, 0.0f64);
        for (k, t) in stamps.iter().enumerate() {
            let e = grid.residual(k, *t);
            sum2 += e * e;
            max = max.max(e.abs());
        }
        Jitter {
            rms_s: (sum2 / stamps.len() as f64).sqrt(),
            max_s: max,
            interval_s: grid.slope,
            samples: stamps.len(),
        }
    }
}

/// The jitter of all the records of a file, for its one notice.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct JitterSummary {
    records: usize,
    samples: usize,
    sum2_s2: f64,
    /// Sum of squared jitter relative to each record's interval.
    sum2_rel: f64,
    max_s: f64,
    max_rel: f64,
}

impl JitterSummary {
    pub fn add(&mut self, jitter: Option<&Jitter>) {
        let Some(j) = jitter else {
            return;
        };
        let n = j.samples as f64;
        self.records += 1;
        self.samples += j.samples;
        self.sum2_s2 += n * j.rms_s * j.rms_s;
        self.sum2_rel += n * (j.rms_s / j.interval_s).powi(2);
        self.max_s = self.max_s.max(j.max_s);
        self.max_rel = self.max_rel.max(j.max_s / j.interval_s);
    }

    /// The notice (`None` when no record had jitter): `sample times scatter about a uniform
    /// grid by 0.029 ms RMS, 0.050 ms at most (2.9 % and 5.0 % of an interval) in 12 records:
    /// read as uniformly sampled`.
    pub fn notice(&self) -> Option<String> {
        (self.records > 0).then(|| {
            let n = self.samples as f64;
            format!(
                "sample times scatter about a uniform grid by {:.4} ms RMS, {:.4} ms at most ({:.1} % and {:.1} % of an interval) in {} record{}: read as uniformly sampled",
                1e3 * (self.sum2_s2 / n).sqrt(),
                1e3 * self.max_s,
                100.0 * (self.sum2_rel / n).sqrt(),
                100.0 * self.max_rel,
                self.records,
                if self.records == 1 { "" } else { "s" }
            )
        })
    }
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The breaks among `stamps` (see the module docs).
pub fn find_breaks(stamps: &[f64]) -> Vec<Break> {
    let d: Vec<f64> = stamps.windows(2).map(|w| w[1] - w[0]).collect();
    let mut out = Vec::new();
    let mut side = Vec::with_capacity(BREAK_CONTEXT_INTERVALS);
    for (i, &di) in d.iter().enumerate() {
        let mut reference = f64::INFINITY;
        let mut any = false;
        for range in [
            i.saturating_sub(BREAK_CONTEXT_INTERVALS)..i,
            (i + 1)..(i + 1 + BREAK_CONTEXT_INTERVALS).min(d.len()),
        ] {
            if range.is_empty() {
                continue;
            }
            side.clear();
            side.extend_from_slice(&d[range]);
            let m = median(&mut side);
            any = true;
            // Broken against both sides: the larger side's interval is the reference.
            if di <= BREAK_MIN_INTERVALS * m {
                reference = f64::NAN;
                break;
            }
            reference = if reference.is_finite() {
                reference.max(m)
            } else {
                m
            };
        }
        if any && reference.is_finite() {
            out.push(Break {
                sample: i + 1,
                interval_s: di,
                reference_s: reference,
            });
        }
    }
    out
}

/// The first of `stamps` (at least two) off a uniform grid by more than the jitter allows
/// ([`JITTER_MAX_INTERVALS`]) plus the rounding `rounding_s` of written times: first an interval
/// further than twice that from the mean interval (a duplicate, a slip: found where it is),
/// then a stamp further than that from the least-squares grid (a drift of the rate); `offset`
/// counts the first stamp in the step.
pub fn jitter_fault(stamps: &[f64], rounding_s: f64, offset: usize) -> Option<StepFault> {
    let d: Vec<f64> = stamps.windows(2).map(|w| w[1] - w[0]).collect();
    let reference = (stamps[stamps.len() - 1] - stamps[0]) / d.len() as f64;
    let tol = 2.0 * JITTER_MAX_INTERVALS * reference + rounding_s;
    if let Some(i) = d.iter().position(|d| (d - reference).abs() > tol) {
        return Some(StepFault::NotUniform {
            sample: offset + i + 1,
            interval: d[i],
            reference,
        });
    }
    let grid = Grid::of(stamps);
    let tol = JITTER_MAX_INTERVALS * grid.slope + 0.5 * rounding_s;
    let k = (0..stamps.len()).find(|&k| grid.residual(k, stamps[k]).abs() > tol)?;
    // The interval that brought the sample off (the first's is the one after it).
    let (a, b) = if k == 0 { (0, 1) } else { (k - 1, k) };
    Some(StepFault::NotUniform {
        sample: offset + b,
        interval: stamps[b] - stamps[a],
        reference: grid.slope,
    })
}

/// A sample rate measured as `rate_hz` with relative uncertainty `rel_unc`, snapped to a whole
/// number of Hz when within it (plus [`RATE_SNAP_REL_TOL`]): rigs sample at whole rates, and
/// both forms of the same data (a bag's nanosecond stamps, a CSV's written times) then give the
/// same rate.
pub fn snap_rate(rate_hz: f64, rel_unc: f64) -> f64 {
    let snapped = rate_hz.round();
    if snapped > 0.0 && (rate_hz - snapped).abs() <= (RATE_SNAP_REL_TOL + rel_unc) * rate_hz {
        snapped
    } else {
        rate_hz
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(n: usize, dt: f64) -> Vec<f64> {
        (0..n).map(|k| k as f64 * dt).collect()
    }

    #[test]
    fn a_lost_sample_and_a_pause_are_breaks_against_their_own_sides() {
        let mut t = grid(20, 0.001);
        t.remove(7);
        // A pause, then the samples at a fifth of the rate.
        let end = *t.last().unwrap() + 0.5;
        t.extend((0..20).map(|k| end + k as f64 * 0.005));
        let b = find_breaks(&t);
        assert_eq!(b.len(), 2, "{b:?}");
        assert_eq!(b[0].sample, 7);
        assert_eq!(b[0].lost_samples(), Some(1));
        assert!((b[0].reference_s - 0.001).abs() < 1e-12);
        assert_eq!(b[1].sample, 19);
        assert_eq!(b[1].lost_samples(), None);
        assert!((b[1].reference_s - 0.005).abs() < 1e-12, "{b:?}");
        assert!(
            b[1].describe().starts_with("a pause of 0.5"),
            "{}",
            b[1].describe()
        );
        assert!(
            b[0].describe().starts_with("1 sample lost"),
            "{}",
            b[0].describe()
        );
    }

    #[test]
    fn jitter_within_the_limit_is_no_break_and_no_fault() {
        // Stamps 9 % of an interval off the grid, alternately early and late: intervals of
        // 0.82 and 1.18 intervals, about the most the rule reads as uniform.
        let t: Vec<f64> = (0..40)
            .map(|k| 0.001 * (k as f64 + if k % 2 == 0 { 0.09 } else { -0.09 }))
            .collect();
        assert!(find_breaks(&t).is_empty());
        assert_eq!(jitter_fault(&t, 0.0, 0), None);
        let j = Jitter::of(&t);
        assert!(
            (j.max_s - 9e-5).abs() < 1e-5 && (j.rms_s - 9e-5).abs() < 1e-5,
            "{j:?}"
        );
        assert!((j.interval_s - 0.001).abs() < 1e-6);
        // A sample 0.3 of an interval late: not uniform, at the interval before it.
        let mut t = grid(30, 0.001);
        t[10] += 0.0003;
        assert!(find_breaks(&t).is_empty());
        match jitter_fault(&t, 0.0, 5) {
            Some(StepFault::NotUniform { sample, .. }) => assert_eq!(sample, 15),
            f => panic!("{f:?}"),
        }
    }

    #[test]
    fn one_notice_sums_the_records_jitter() {
        let mut s = JitterSummary::default();
        assert_eq!(s.notice(), None);
        s.add(None);
        let j = Jitter {
            rms_s: 1e-5,
            max_s: 5e-5,
            interval_s: 1e-3,
            samples: 100,
        };
        s.add(Some(&j));
        s.add(Some(&j));
        let n = s.notice().unwrap();
        assert!(
            n.contains(
                "0.0100 ms RMS, 0.0500 ms at most (1.0 % and 5.0 % of an interval) in 2 records"
            ),
            "{n}"
        );
    }

    #[test]
    fn rates_snap_within_their_uncertainty() {
        assert_eq!(snap_rate(1000.0000005, 0.0), 1000.0);
        assert_eq!(snap_rate(1000.02, 0.0), 1000.02);
        assert_eq!(snap_rate(1000.02, 3e-5), 1000.0);
    }
}
