//! The node loop of a run: the samples and input breakpoints in time order, each node interval
//! integrated (one exact step, one linear sub-step, or sub-steps with event location), and
//! stretches of plain samples without the per-node bookkeeping.

use super::nodes::{Nodes, substeps};
use super::{Hybrid, Integrator, Mode, RunStats};
use crate::sim::SimError;

/// What the loop over plain samples knows of an interval's inputs without asking the system.
#[derive(Debug, Clone, Copy)]
struct Known {
    /// [`Hybrid::forcing_affine`] at the interval's `t_ref`.
    affine: bool,
    /// The last sub-step's inputs came from the same pieces.
    same_piece: bool,
}

impl<H: Hybrid> Integrator<'_, H> {
    /// Integrates a whole run sampled at `i / sample_rate_hz`, `i = 0..samples`, with input
    /// breakpoints `breaks` (jump conditions applied there). `y` holds the state at t = 0.
    /// `on_sample(i, t, t_ref, y, mode)` is called at every sample (right limit).
    pub fn run(
        &mut self,
        y: &mut [f64],
        samples: usize,
        sample_rate_hz: f64,
        breaks: &[f64],
        mut on_sample: impl FnMut(usize, f64, f64, &[f64], Mode),
    ) -> Result<RunStats, SimError> {
        let mut stats = RunStats {
            stick_time_s: vec![0.0; samples],
            events: vec![0; samples],
        };
        self.run_streamed(
            y,
            samples,
            sample_rate_hz,
            breaks,
            |i, t, t_ref, y, mode| {
                on_sample(i, t, t_ref, y, mode);
                true
            },
            |i, stuck_s, events| {
                stats.stick_time_s[i] += stuck_s;
                stats.events[i] += events;
            },
        )?;
        Ok(stats)
    }

    /// [`run`](Self::run) in memory independent of the run's length: the nodes are generated
    /// as the integration reaches them, each sub-step's stuck time and events go to
    /// `on_substep(sample interval, stuck_s, events)`, and `on_sample` returning false stops
    /// the run there (Ok).
    pub fn run_streamed(
        &mut self,
        y: &mut [f64],
        samples: usize,
        sample_rate_hz: f64,
        breaks: &[f64],
        mut on_sample: impl FnMut(usize, f64, f64, &[f64], Mode) -> bool,
        mut on_substep: impl FnMut(usize, f64, usize),
    ) -> Result<(), SimError> {
        let mut nodes = Nodes::new(samples, sample_rate_hz, breaks);
        let mut mode = Mode::Free;
        let mut current = 0usize;
        let mut first = true;
        let mut node = nodes.next();
        while let Some((t, sample, is_break)) = node {
            if !first
                && !is_break
                && let Some(k) = sample
            {
                let reached = self.plain_samples(
                    k,
                    &nodes,
                    y,
                    &mut mode,
                    sample_rate_hz,
                    &mut on_sample,
                    &mut on_substep,
                )?;
                match reached {
                    None => return Ok(()),
                    Some(r) if r > k => {
                        nodes.resume_at(r);
                        node = nodes.next();
                        continue;
                    }
                    Some(_) => {}
                }
            }
            let next = nodes.next();
            let t_next = next.map(|n| n.0);
            let t_ref = t_next.map_or(t, |tn| 0.5 * (t + tn));
            if is_break && !first {
                self.sys.jump(t, y);
            }
            if first || is_break {
                mode = self.consistent(t, t_ref, y, mode);
            }
            first = false;
            if let Some(i) = sample {
                current = i;
                if !on_sample(i, t, t_ref, y, mode) {
                    return Ok(());
                }
            }
            node = next;
            let Some(tn) = t_next else { break };
            self.interval(t, tn, t_ref, y, &mut mode, current, &mut on_substep, None)?;
        }
        Ok(())
    }

    /// The plain samples from `k` on (sample `k` just taken from `nodes`): each not a
    /// breakpoint and followed by the next sample, sampled and integrated to the next as the
    /// node loop of [`Integrator::run_streamed`] does it (the same calls in the same order, so
    /// the same state to the bit) without its per-node bookkeeping: at 10 kHz that loop was a
    /// quarter of a run. Returns the sample it stopped before (`k` when none was plain), or
    /// `None` when `on_sample` stopped the run.
    #[allow(
        clippy::too_many_arguments,
        reason = "the node loop's state, passed through"
    )]
    fn plain_samples(
        &mut self,
        k: usize,
        nodes: &Nodes,
        y: &mut [f64],
        mode: &mut Mode,
        sample_rate_hz: f64,
        on_sample: &mut impl FnMut(usize, f64, f64, &[f64], Mode) -> bool,
        on_substep: &mut impl FnMut(usize, f64, usize),
    ) -> Result<Option<usize>, SimError> {
        let (end, next_break) = nodes.plain_after(k);
        let mut t = k as f64 / sample_rate_hz;
        // No breakpoint inside the stretch: the inputs come from the same pieces throughout,
        // so whether they are affine is asked once, and after its first interval every
        // sub-step's inputs are those of the one before.
        let mut affine = None;
        for s in k..end {
            let tn = (s + 1) as f64 / sample_rate_hz;
            if next_break.total_cmp(&tn).is_lt() {
                return Ok(Some(s));
            }
            let t_ref = 0.5 * (t + tn);
            if !on_sample(s, t, t_ref, y, *mode) {
                return Ok(None);
            }
            let exact = *affine.get_or_insert_with(|| self.sys.forcing_affine(t_ref));
            let known = Known {
                affine: exact,
                same_piece: s > k,
            };
            self.interval(t, tn, t_ref, y, mode, s, on_substep, Some(known))?;
            t = tn;
        }
        Ok(Some(end))
    }

    /// Integrates `y` over the node interval `[t, tn]` (inputs from the pieces at `t_ref`):
    /// one exact step, one linear sub-step, or sub-steps with event location. Inlined for the
    /// one linear sub-step of a 10 kHz sample; the sub-steps with events are a call of their
    /// own (inlined twice with them, they keep the 3-DOF run's `advance` from being inlined:
    /// +1.5 % instructions).
    #[allow(
        clippy::too_many_arguments,
        reason = "the node loop's state, passed through"
    )]
    #[inline(always)]
    fn interval(
        &mut self,
        t: f64,
        tn: f64,
        t_ref: f64,
        y: &mut [f64],
        mode: &mut Mode,
        current: usize,
        on_substep: &mut impl FnMut(usize, f64, usize),
        known: Option<Known>,
    ) -> Result<(), SimError> {
        let try_exact = known.is_none_or(|k| k.affine);
        if try_exact && let Some(next) = self.exact_interval(t, tn, t_ref, y, *mode) {
            y[..2].copy_from_slice(&next);
            if !next.iter().all(|v| v.is_finite()) {
                return Err(SimError::NonFinite { time_s: tn });
            }
            return Ok(());
        }
        let n = substeps(tn - t, self.opts.max_substep_s);
        let h = (tn - t) / n as f64;
        self.substep_s = h;
        if n == 1
            && let Some(next) =
                self.one_linear_substep(t, tn, t_ref, y, *mode, known.is_some_and(|k| k.same_piece))
        {
            [y[0], y[1]] = next;
            on_substep(current, 0.0, 0);
            if !next.iter().all(|v| v.is_finite()) {
                return Err(SimError::NonFinite { time_s: tn });
            }
            return Ok(());
        }
        self.substeps_with_events(t, tn, t_ref, n, y, mode, current, on_substep)
    }

    /// The `n` sub-steps of `[t, tn]` through [`Integrator::advance`] (stick-slip events).
    #[allow(
        clippy::too_many_arguments,
        reason = "the node loop's state, passed through"
    )]
    #[inline(never)]
    fn substeps_with_events(
        &mut self,
        t: f64,
        tn: f64,
        t_ref: f64,
        n: usize,
        y: &mut [f64],
        mode: &mut Mode,
        current: usize,
        on_substep: &mut impl FnMut(usize, f64, usize),
    ) -> Result<(), SimError> {
        let h = self.substep_s;
        for s in 0..n {
            let a = t + s as f64 * h;
            let b = if s + 1 == n {
                tn
            } else {
                t + (s + 1) as f64 * h
            };
            let (st, ev) = self.advance(a, b, t_ref, y, mode)?;
            on_substep(current, st, ev);
        }
        if y.iter().any(|v| !v.is_finite()) {
            return Err(SimError::NonFinite { time_s: tn });
        }
        Ok(())
    }
}
