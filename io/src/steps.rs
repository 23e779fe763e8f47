//! Rig samples back into records, one per excitation step: what reading a bag and the harmonic
//! node both do, in one place, so that a step replayed through the node graph becomes exactly
//! the record `forcemap identify` reads from the same bag.

use forcemap_math::record::{Channel, Excitation, Record};
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::msg::{ExcitationState, RigSample};

/// Why a step's samples do not make a record.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("step {step}: {problem}")]
pub struct StepError {
    pub step: usize,
    pub problem: String,
    /// The step only ended early (fewer samples than planned, nothing else wrong): what the
    /// last step of an interrupted recording looks like.
    pub truncated: bool,
}

/// What the assembler knows of a step from its excitation state.
#[derive(Debug, Clone, PartialEq)]
pub struct StepPlan {
    pub excitation: Excitation,
    /// Samples the step lasts; 0 when not known (the step ends when the next one starts).
    pub sample_count: usize,
}

impl StepPlan {
    /// The plan of a step from its state; `None` for IDLE (no step).
    pub fn from_state(state: &ExcitationState) -> Result<Option<StepPlan>, StepError> {
        if state.is_idle() {
            return Ok(None);
        }
        let excitation = state.excitation().map_err(|e| StepError {
            step: state.step as usize,
            problem: e.to_string(),
            truncated: false,
        })?;
        Ok(Some(StepPlan {
            excitation,
            sample_count: state.sample_count as usize,
        }))
    }
}

struct Building {
    record: Record,
    /// Sample times [s] from the run start.
    stamps: Vec<f64>,
    expected: usize,
    /// The first problem met; the step is dropped when it completes.
    problem: Option<String>,
}

/// Groups samples into records. Samples of a step must be contiguous; a step completes when
/// its planned sample count is reached, when a sample of another step arrives, or on
/// [`StepAssembler::finish`].
pub struct StepAssembler {
    origin: Option<Time>,
    building: Option<Building>,
    /// The last completed (or dropped) step, so that a step cannot come back.
    last_step: Option<usize>,
}

impl Default for StepAssembler {
    fn default() -> Self {
        Self::new()
    }
}

impl StepAssembler {
    pub fn new() -> StepAssembler {
        StepAssembler {
            origin: None,
            building: None,
            last_step: None,
        }
    }

    /// Sets the time of t = 0 of the run (record start times count from it). Without it the
    /// first sample's stamp is taken.
    pub fn set_origin(&mut self, t: Time) {
        if self.origin.is_none() {
            self.origin = Some(t);
        }
    }

    pub fn origin(&self) -> Option<Time> {
        self.origin
    }

    /// The step being assembled and how many samples it has.
    pub fn in_progress(&self) -> Option<(usize, usize)> {
        self.building
            .as_ref()
            .map(|b| (b.record.step, b.stamps.len()))
    }

    /// Adds one sample. `plan` is the plan of the sample's step (`None`: no excitation state
    /// was seen for it). Returns the steps this sample completed: the previous one when the
    /// step changes, and this one when it reaches its planned count.
    pub fn push(
        &mut self,
        sample: &RigSample,
        plan: Option<&StepPlan>,
    ) -> Vec<Result<Record, StepError>> {
        let mut done = Vec::new();
        let step = sample.step as usize;
        let origin = *self.origin.get_or_insert(sample.header.stamp);
        let t = sample.header.stamp.secs_since(origin);
        if self
            .building
            .as_ref()
            .is_some_and(|b| b.record.step != step)
        {
            done.extend(self.finish());
        }
        if self.building.is_none() {
            let problem = if self.last_step.is_some_and(|l| l >= step) {
                Some(format!(
                    "its samples are not contiguous in time (step {} came before)",
                    self.last_step.unwrap_or(0)
                ))
            } else if plan.is_none() {
                Some("no ExcitationState for this step".to_string())
            } else {
                None
            };
            let present = sample.present();
            self.building = Some(Building {
                record: Record {
                    step,
                    excitation: plan.map_or(
                        Excitation::Random {
                            band_hz: None,
                            rms: f64::NAN,
                        },
                        |p| p.excitation.clone(),
                    ),
                    sample_rate_hz: 0.0,
                    start_time_s: t,
                    channels: present.iter().map(|c| (*c, Vec::new())).collect(),
                },
                stamps: Vec::new(),
                expected: plan.map_or(0, |p| p.sample_count),
                problem,
            });
        }
        let b = self.building.as_mut().expect("started above");
        let index = b.stamps.len();
        if b.problem.is_none() {
            let present = sample.present();
            let expected: Vec<Channel> = b.record.channels.iter().map(|(c, _)| *c).collect();
            if expected != present {
                b.problem = Some(format!(
                    "sample {index}: the set of present channels changed within the step"
                ));
            } else if let Some(c) = present
                .iter()
                .find(|c| !sample.channel(**c).is_some_and(f64::is_finite))
            {
                b.problem = Some(format!(
                    "sample {index}: channel {} is flagged present but not finite",
                    c.name()
                ));
            }
        }
        if b.problem.is_none() {
            for (c, v) in b.record.channels.iter_mut() {
                v.push(sample.channel(*c).expect("checked present"));
            }
        }
        b.stamps.push(t);
        if b.expected > 0 && b.stamps.len() >= b.expected {
            done.extend(self.finish());
        }
        done
    }

    /// Completes the step in progress, if any.
    pub fn finish(&mut self) -> Option<Result<Record, StepError>> {
        let b = self.building.take()?;
        let step = b.record.step;
        self.last_step = Some(self.last_step.map_or(step, |l| l.max(step)));
        Some(complete(b))
    }

    /// Drops the step in progress (e.g. when its excitation state says it was replaced).
    pub fn abandon(&mut self, why: &str) -> Option<StepError> {
        let b = self.building.take()?;
        self.last_step = Some(b.record.step);
        Some(StepError {
            step: b.record.step,
            problem: format!("{why} after {} samples", b.stamps.len()),
            truncated: false,
        })
    }
}

fn complete(b: Building) -> Result<Record, StepError> {
    let Building {
        mut record,
        stamps,
        expected,
        problem,
    } = b;
    let err = |problem: String| StepError {
        step: record.step,
        problem,
        truncated: false,
    };
    if let Some(p) = problem {
        return Err(err(p));
    }
    if expected > 0 && stamps.len() != expected {
        return Err(StepError {
            truncated: stamps.len() < expected,
            ..err(format!(
                "{} of its {expected} samples arrived (samples were lost or the recording stopped)",
                stamps.len()
            ))
        });
    }
    if stamps.len() < 3 {
        return Err(err(format!(
            "{} samples; a step needs at least 3",
            stamps.len()
        )));
    }
    let dt = (stamps[stamps.len() - 1] - stamps[0]) / (stamps.len() - 1) as f64;
    if let Some(k) =
        (1..stamps.len()).find(|&k| ((stamps[k] - stamps[k - 1]) / dt - 1.0).abs() > 1e-3)
    {
        return Err(err(format!(
            "samples are not uniform: sample {k} follows the previous after {:.6} s where {:.6} s is the step's mean interval (a gap or a duplicate)",
            stamps[k] - stamps[k - 1],
            dt
        )));
    }
    // Stamps are whole nanoseconds: snap a rate within that rounding of a whole number of Hz to
    // it, as the CSV reader does, so both forms of the same data give the same rate.
    let rate = 1.0 / dt;
    let snapped = rate.round();
    record.sample_rate_hz = if (rate - snapped).abs() < 1e-6 * rate {
        snapped
    } else {
        rate
    };
    Ok(record)
}

#[cfg(test)]
mod tests {
    use super::*;
    use forcemap_msgs::std_msgs::Header;

    fn sample(step: u32, t_ms: i64, x: f64) -> RigSample {
        let stamp = Time::from_nanos(1_000_000_000 + t_ms * 1_000_000);
        RigSample::new(Header::new(stamp, "rig"), step)
            .with(Channel::BaseDisplacementM, x)
            .with(Channel::MassAccelerationMps2, 2.0 * x)
    }

    fn plan(n: usize) -> StepPlan {
        StepPlan {
            excitation: Excitation::Sine {
                frequency_hz: 2.0,
                amplitude: 1e-3,
            },
            sample_count: n,
        }
    }

    #[test]
    fn a_step_completes_at_its_planned_count_with_its_rate_and_values() {
        let mut a = StepAssembler::new();
        a.set_origin(Time::from_nanos(1_000_000_000));
        let p = plan(5);
        let mut out = Vec::new();
        for k in 0..5 {
            out.extend(a.push(&sample(0, 10 * k, k as f64), Some(&p)));
        }
        assert_eq!(out.len(), 1);
        let r = out.pop().unwrap().unwrap();
        assert_eq!(r.sample_rate_hz, 100.0);
        assert_eq!(r.start_time_s, 0.0);
        assert_eq!(
            r.channel(Channel::MassAccelerationMps2).unwrap(),
            &[0.0, 2.0, 4.0, 6.0, 8.0]
        );
        assert!(a.in_progress().is_none());
    }

    #[test]
    fn a_gap_or_a_lost_tail_drops_the_step_with_the_reason() {
        let mut a = StepAssembler::new();
        let p = plan(0);
        for k in [0, 1, 2, 4, 5] {
            assert!(a.push(&sample(0, 10 * k, 0.0), Some(&p)).is_empty());
        }
        let e = a.finish().unwrap().unwrap_err();
        assert_eq!(e.step, 0);
        assert!(e.problem.contains("not uniform"), "{e}");
        assert!(!e.truncated, "a gap is not a truncation");

        let p = plan(6);
        let mut out = Vec::new();
        for k in 0..4 {
            out.extend(a.push(&sample(1, 100 + 10 * k, 0.0), Some(&p)));
        }
        // The next step begins: step 1 is complete with 4 of its 6 samples.
        out.extend(a.push(&sample(2, 200, 0.0), Some(&p)));
        let e = out.pop().unwrap().unwrap_err();
        assert_eq!(e.step, 1);
        assert!(e.problem.contains("4 of its 6 samples"), "{e}");
        assert!(e.truncated, "a short step is only truncated");
    }

    #[test]
    fn non_finite_values_and_unknown_steps_are_refused() {
        let mut a = StepAssembler::new();
        let p = plan(3);
        let mut out = a.push(&sample(0, 0, 0.0), Some(&p));
        out.extend(a.push(&sample(0, 10, f64::NAN), Some(&p)));
        out.extend(a.push(&sample(0, 20, 0.0), Some(&p)));
        let e = out.pop().unwrap().unwrap_err();
        assert!(e.problem.contains("sample 1: channel"), "{e}");
        let mut out = Vec::new();
        for k in 0..3 {
            out.extend(a.push(&sample(1, 100 + 10 * k, 0.0), None));
        }
        let e = a.finish().unwrap().unwrap_err();
        assert!(e.problem.contains("no ExcitationState"), "{e}");
        // a step cannot come back after a later one
        out.extend(a.push(&sample(0, 300, 0.0), Some(&p)));
        let e = a.finish().unwrap().unwrap_err();
        assert!(e.problem.contains("not contiguous"), "{e}");
    }
}
