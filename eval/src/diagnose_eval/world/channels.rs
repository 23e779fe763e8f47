//! The world's channel effects, applied to the simulated records (not to the physics): sensor
//! dynamics on a subset of the channels, and an exciter whose base motion differs from the
//! commanded one the base channels record.

use forcemap_math::record::{Channel, Record};
use forcemap_math::sim::Program;
use forcemap_math::sim::rig::RIG_CHANNELS;
use serde::Serialize;

/// Sensor dynamics: a first- or second-order low-pass (`order` 1 or 2, damping ratio for
/// order 2) with an optional delay, on the channels of `mask` (bit i: `RIG_CHANNELS[i]`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SensorDynamics {
    pub mask: u8,
    pub order: u8,
    pub cutoff_hz: f64,
    pub damping_ratio: f64,
    pub delay_s: f64,
}

impl SensorDynamics {
    /// Whether the filter acts on `channel`.
    pub fn applies_to(&self, channel: Channel) -> bool {
        RIG_CHANNELS
            .iter()
            .position(|c| *c == channel)
            .is_some_and(|i| self.mask & (1 << i) != 0)
    }

    /// The filtered samples of a signal sampled at `sample_rate_hz` starting at rest on its
    /// first value: the filter ODE integrated by RK4 (4 sub-steps per sample) on the samples
    /// interpolated by Catmull-Rom cubics, the input delayed by `delay_s` (the first value held
    /// before the start).
    pub fn filter(&self, u: &[f64], sample_rate_hz: f64) -> Vec<f64> {
        let Some(&u0) = u.first() else {
            return Vec::new();
        };
        let w = std::f64::consts::TAU * self.cutoff_hz;
        let dt = 1.0 / sample_rate_hz;
        let input = |t: f64| interpolate(u, (t - self.delay_s) * sample_rate_hz);
        let rate = |t: f64, y: [f64; 2]| -> [f64; 2] {
            if self.order == 1 {
                [w * (input(t) - y[0]), 0.0]
            } else {
                [
                    y[1],
                    w * w * (input(t) - y[0]) - 2.0 * self.damping_ratio * w * y[1],
                ]
            }
        };
        let sub = 4;
        let h = dt / sub as f64;
        let mut y = [u0, 0.0];
        let mut out = Vec::with_capacity(u.len());
        out.push(y[0]);
        for i in 1..u.len() {
            for s in 0..sub {
                let t = (i - 1) as f64 * dt + s as f64 * h;
                let add = |y: [f64; 2], k: [f64; 2], f: f64| [y[0] + f * k[0], y[1] + f * k[1]];
                let k1 = rate(t, y);
                let k2 = rate(t + 0.5 * h, add(y, k1, 0.5 * h));
                let k3 = rate(t + 0.5 * h, add(y, k2, 0.5 * h));
                let k4 = rate(t + h, add(y, k3, h));
                for j in 0..2 {
                    y[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
                }
            }
            out.push(y[0]);
        }
        out
    }

    /// Applies the filter to the run's records (contiguous, in step order): each chosen
    /// channel is filtered over the whole run, then cut back into the records.
    pub fn apply(&self, records: &mut [Record]) {
        let Some(fs) = records.first().map(|r| r.sample_rate_hz) else {
            return;
        };
        for c in RIG_CHANNELS {
            if !self.applies_to(c) {
                continue;
            }
            let run: Vec<f64> = records
                .iter()
                .filter_map(|r| r.channel(c))
                .flatten()
                .copied()
                .collect();
            let filtered = self.filter(&run, fs);
            let mut at = 0;
            for r in records.iter_mut() {
                if let Some(v) = r.channel_mut(c) {
                    let n = v.len();
                    v.copy_from_slice(&filtered[at..at + n]);
                    at += n;
                }
            }
        }
    }
}

/// Catmull-Rom interpolation of samples `u` at fractional index `s` (clamped to the ends).
fn interpolate(u: &[f64], s: f64) -> f64 {
    let n = u.len();
    if n == 1 || s <= 0.0 {
        return u[0];
    }
    if s >= (n - 1) as f64 {
        return u[n - 1];
    }
    let i = s.floor() as usize;
    let f = s - i as f64;
    let at = |k: isize| u[(i as isize + k).clamp(0, n as isize - 1) as usize];
    let (p0, p1, p2, p3) = (at(-1), at(0), at(1), at(2));
    p1 + 0.5
        * f
        * (p2 - p0 + f * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3 + f * (3.0 * (p1 - p2) + p3 - p0)))
}

/// How the base motion the rig receives differs from the command the base channels record:
/// received = lag(delay(command)) with a first-order lag of time constant `lag_s`, then (with
/// `resonance_hz`) through a second-order resonance of damping ratio `resonance_damping`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Exciter {
    pub delay_s: f64,
    pub lag_s: f64,
    pub resonance_hz: Option<f64>,
    pub resonance_damping: f64,
}

impl Exciter {
    /// Rewrites the base channels of records simulated with the program's signal as the base
    /// the rig received: the command that produced it, `command(t) = R(received)(t + delay)`
    /// with `R = 1 + lag d/dt` (and `(1 + 2 zeta/wn d/dt + 1/wn^2 d^2/dt^2)` for the
    /// resonance), from the signal's exact derivatives (the third and fourth by central
    /// differences of its exact acceleration).
    pub fn apply(&self, records: &mut [Record], program: &Program) {
        let h = 1e-3;
        let acc = |t: f64| program.signal.eval(t, t).d2;
        let (c1, c2) = match self.resonance_hz {
            Some(f) => {
                let wn = std::f64::consts::TAU * f;
                (2.0 * self.resonance_damping / wn, 1.0 / (wn * wn))
            }
            None => (0.0, 0.0),
        };
        // R = (1 + lag s)(1 + c1 s + c2 s^2) = 1 + a1 s + a2 s^2 + a3 s^3.
        let (a1, a2, a3) = (self.lag_s + c1, c2 + self.lag_s * c1, self.lag_s * c2);
        for r in records.iter_mut() {
            let times: Vec<f64> = (0..r.len()).map(|i| r.time_s(i) + self.delay_s).collect();
            if let Some(x) = r.channel_mut(Channel::BaseDisplacementM) {
                for (xi, &t) in x.iter_mut().zip(&times) {
                    let d = program.signal.eval(t, t);
                    let jerk = (acc(t + h) - acc(t - h)) / (2.0 * h);
                    *xi = d.value + a1 * d.d1 + a2 * d.d2 + a3 * jerk;
                }
            }
            if let Some(a) = r.channel_mut(Channel::BaseAccelerationMps2) {
                for (ai, &t) in a.iter_mut().zip(&times) {
                    let (am, a0, ap) = (acc(t - h), acc(t), acc(t + h));
                    let jerk = (ap - am) / (2.0 * h);
                    let snap = (ap - 2.0 * a0 + am) / (h * h);
                    let crackle = (acc(t + 2.0 * h) - 2.0 * ap + 2.0 * am - acc(t - 2.0 * h))
                        / (2.0 * h * h * h);
                    *ai = a0 + a1 * jerk + a2 * snap + a3 * crackle;
                }
            }
        }
    }
}
