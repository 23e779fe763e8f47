//! The sensor-dynamics family of the `sensor_lowpass` candidate: a first- or second-order
//! low-pass, with an optional pure delay, on a subset of the rig's channels.
//!
//! A known filter is undone exactly on a step's phasors (each harmonic divided by H(j n w)),
//! so members are cheap to compare. Filters on some channels only break the identities that
//! tie the channels together whatever the element does: the mass displacement is the base
//! displacement plus the relative one (x_o = x_i + x) and the mass acceleration is the second
//! derivative of the mass displacement (-A_n / (n w)^2 = X_o,n). Each member undoes its filter
//! and scores what is left of those identities ([`Consistency::chi2`]): the channel subset,
//! order, cutoff, damping ratio and delay are chosen there, a coarse grid refined by a simplex
//! search ([`best_subset_member`]). A filter on every channel alike leaves the identities intact
//! (a common delay is then invisible altogether); that member is searched by the element fit's
//! cross-validated error as before (`search`).

use std::f64::consts::TAU;

use num_complex::Complex64;
use serde::Serialize;

use super::score::delayed;
use crate::identify::{IdentifyError, element_harmonics};
use crate::phasor::HarmonicAnalysis;
use crate::recipe::Setup;
use crate::record::Channel;
use crate::signal::differentiate::central_difference_at_rate;
use crate::signal::lowpass::first_order_lowpass;
use crate::sim::rig::RIG_CHANNELS;

/// Every rig channel ([`RIG_CHANNELS`] bits).
pub const ALL_CHANNELS: u8 = 0b11111;

/// The channel subsets whose filter the identities can see, one channel each (the base
/// acceleration is not read by the diagnosis: a filter on it alone changes nothing it uses, and
/// "both accelerometers" is, for it, the mass accelerometer).
pub const SUBSET_CHANNELS: [Channel; 4] = [
    Channel::BaseDisplacementM,
    Channel::RelativeDisplacementM,
    Channel::MassAccelerationMps2,
    Channel::MassDisplacementM,
];

/// A sensor filter: H(s) = L(s) e^{-s d} on the channels of `mask` (bit i: `RIG_CHANNELS[i]`),
/// L = 1 / (1 + s / wc) (order 1) or 1 / (1 + 2 zeta s / wc + (s / wc)^2) (order 2).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SensorFilter {
    pub mask: u8,
    pub order: u8,
    pub cutoff_hz: f64,
    /// Damping ratio zeta of the second-order pole pair (unused for order 1).
    pub damping_ratio: f64,
    pub delay_s: f64,
}

fn bit(c: Channel) -> u8 {
    RIG_CHANNELS
        .iter()
        .position(|r| *r == c)
        .map_or(0, |i| 1 << i)
}

/// A channel's name without its unit ("mass_acceleration").
pub fn short_name(c: Channel) -> &'static str {
    match c {
        Channel::BaseDisplacementM => "base_displacement",
        Channel::RelativeDisplacementM => "relative_displacement",
        Channel::MassAccelerationMps2 => "mass_acceleration",
        Channel::MassDisplacementM => "mass_displacement",
        Channel::BaseAccelerationMps2 => "base_acceleration",
        Channel::ForceN => "force",
        Channel::DrivePointDisplacementM => "drive_point_displacement",
    }
}

impl SensorFilter {
    /// A first-order low-pass on every channel (the exact forms' planted sensor).
    pub fn first_order_on_all(cutoff_hz: f64) -> SensorFilter {
        SensorFilter {
            mask: ALL_CHANNELS,
            order: 1,
            cutoff_hz,
            damping_ratio: 1.0,
            delay_s: 0.0,
        }
    }

    pub fn on(channel: Channel, order: u8, cutoff_hz: f64, damping_ratio: f64) -> SensorFilter {
        SensorFilter {
            mask: bit(channel),
            order,
            cutoff_hz,
            damping_ratio,
            delay_s: 0.0,
        }
    }

    /// Whether the filter acts on `channel`.
    pub fn applies_to(&self, channel: Channel) -> bool {
        self.mask & bit(channel) != 0
    }

    /// H(j 2 pi f) of the filter.
    pub fn response(&self, frequency_hz: f64) -> Complex64 {
        let s = Complex64::new(0.0, frequency_hz / self.cutoff_hz);
        let den = if self.order == 1 {
            1.0 + s
        } else {
            1.0 + 2.0 * self.damping_ratio * s + s * s
        };
        Complex64::from_polar(1.0, -TAU * frequency_hz * self.delay_s) / den
    }

    /// H on `channel` (1 where the filter does not act).
    pub fn channel_response(&self, channel: Channel, frequency_hz: f64) -> Complex64 {
        if self.applies_to(channel) {
            self.response(frequency_hz)
        } else {
            Complex64::new(1.0, 0.0)
        }
    }

    /// "all channels", "channel mass_acceleration", "channels a, b".
    pub fn channels(&self) -> String {
        if self.mask & ALL_CHANNELS == ALL_CHANNELS {
            return "all channels".into();
        }
        let names: Vec<&str> = RIG_CHANNELS
            .iter()
            .filter(|c| self.applies_to(**c))
            .map(|c| short_name(*c))
            .collect();
        match names.len() {
            1 => format!("channel {}", names[0]),
            _ => format!("channels {}", names.join(", ")),
        }
    }

    /// The member and its shape: "channel mass_acceleration, 2nd order, 6.1 Hz, damping 0.70,
    /// delay 2.0 ms".
    pub fn describe(&self) -> String {
        let mut s = format!("{}, ", self.channels());
        if self.order == 1 {
            s.push_str(&format!("1st order, {:.1} Hz", self.cutoff_hz));
        } else {
            s.push_str(&format!(
                "2nd order, {:.1} Hz, damping {:.2}",
                self.cutoff_hz, self.damping_ratio
            ));
        }
        if self.delay_s > 0.0 {
            s.push_str(&format!(", delay {:.1} ms", 1e3 * self.delay_s));
        }
        s
    }

    /// The shape parameters searched (cutoff, damping ratio of order 2, a delay when there is
    /// one), as (name, value).
    pub fn searched(&self) -> Vec<(String, f64)> {
        let mut v = vec![("cutoff_hz".into(), self.cutoff_hz)];
        if self.order == 2 {
            v.push(("damping_ratio".into(), self.damping_ratio));
        }
        if self.delay_s > 0.0 {
            v.push(("sensor_delay_s".into(), self.delay_s));
        }
        v
    }

    /// Free parameters of the member: its shape parameters, plus one for the subset when it is
    /// not every channel (chosen among several).
    pub fn parameters(&self) -> usize {
        self.searched().len() + usize::from(self.mask & ALL_CHANNELS != ALL_CHANNELS)
    }
}

/// The analysis with each channel's phasors divided by the filter's response on it (noise
/// scaled alike): what the channels were before the sensor filter.
pub fn unfiltered(an: &HarmonicAnalysis, f: &SensorFilter) -> HarmonicAnalysis {
    let mut out = an.clone();
    for ch in &mut out.channels {
        if !f.applies_to(ch.channel) {
            continue;
        }
        for (n, (c, s)) in ch.phasors.iter_mut().zip(&mut ch.noise_std).enumerate() {
            let inv = f.response(n as f64 * an.frequency_hz).inv();
            *c *= inv;
            *s *= inv.norm();
        }
    }
    out
}

/// Whether a member's filtered force is exactly the true one through a per-harmonic factor
/// ([`force_response`]): with the mass displacement measured always; without it the force comes
/// from base + relative displacement, which then must be filtered alike.
pub fn exact_for(an: &HarmonicAnalysis, f: &SensorFilter) -> bool {
    an.channel(Channel::MassDisplacementM).is_some()
        || f.applies_to(Channel::BaseDisplacementM) == f.applies_to(Channel::RelativeDisplacementM)
}

/// Per harmonic n = 0..=N, the factor the measured element force went through: the rig's force
/// combines the mass displacement and the mass acceleration by inverse noise variance
/// (`element_harmonics`), so with filters H_o and H_a on them the measured force is
/// (w_o H_o + w_a H_a) G. Found by passing a unit force through `element_harmonics` (one way to
/// combine the channels), its channels filtered as the member says. DC passes unchanged.
pub fn force_response(
    setup: &Setup,
    an: &HarmonicAnalysis,
    f: &SensorFilter,
) -> Result<Vec<Complex64>, IdentifyError> {
    let Some(m) = setup.rig_mass_kg() else {
        return Ok(vec![Complex64::new(1.0, 0.0); an.harmonics + 1]);
    };
    let w = TAU * an.frequency_hz;
    let mut probe = an.clone();
    for ch in &mut probe.channels {
        for (n, c) in ch.phasors.iter_mut().enumerate() {
            let h = f.channel_response(ch.channel, n as f64 * an.frequency_hz);
            let wn2 = (n as f64 * w).powi(2);
            *c = match ch.channel {
                _ if n == 0 => Complex64::new(0.0, 0.0),
                // A unit force: x_o = 1 / (m (n w)^2), a = -1 / m (all of x_o on the base when
                // the mass displacement is built from base + relative).
                Channel::MassDisplacementM | Channel::BaseDisplacementM => h / (m * wn2),
                Channel::MassAccelerationMps2 => -h / m,
                _ => Complex64::new(0.0, 0.0),
            };
        }
    }
    let eh = element_harmonics(setup, &probe, false)?;
    let mut g = eh.force;
    if let Some(g0) = g.first_mut() {
        *g0 = Complex64::new(1.0, 0.0);
    }
    Ok(g)
}

/// One step's channels as the identities need them: (phasors, noise) per channel.
#[derive(Debug, Clone)]
struct StepChannels {
    frequency_hz: f64,
    base: (Vec<Complex64>, Vec<f64>),
    relative: (Vec<Complex64>, Vec<f64>),
    mass_displacement: Option<(Vec<Complex64>, Vec<f64>)>,
    mass_acceleration: Option<(Vec<Complex64>, Vec<f64>)>,
}

/// The channel identities of the sine steps (see the module docs).
#[derive(Debug, Clone)]
pub struct Consistency {
    steps: Vec<StepChannels>,
    /// Real equations (two per complex identity and harmonic).
    pub equations: usize,
}

impl Consistency {
    /// None without the base and relative displacement or without both mass channels.
    pub fn of(analyses: &[HarmonicAnalysis]) -> Option<Consistency> {
        let pick = |an: &HarmonicAnalysis, c: Channel| {
            an.channel(c)
                .map(|ch| (ch.phasors.clone(), ch.noise_std.clone()))
        };
        let mut steps = Vec::new();
        let mut equations = 0;
        for an in analyses {
            let s = StepChannels {
                frequency_hz: an.frequency_hz,
                base: pick(an, Channel::BaseDisplacementM)?,
                relative: pick(an, Channel::RelativeDisplacementM)?,
                mass_displacement: pick(an, Channel::MassDisplacementM),
                mass_acceleration: pick(an, Channel::MassAccelerationMps2),
            };
            let rows = usize::from(s.mass_displacement.is_some())
                + usize::from(s.mass_acceleration.is_some());
            if rows == 0 {
                return None;
            }
            equations += 2 * rows * (s.base.0.len().saturating_sub(1));
            steps.push(s);
        }
        (!steps.is_empty()).then_some(Consistency { steps, equations })
    }

    /// Chi-square of the identities with `f` undone (None: nothing undone), harmonics 1..=N:
    /// e1 = X_o - X_i - X, e2 = -A / (n w)^2 - X_o on the unfiltered channels, weighted by their
    /// joint noise covariance. It is the least-squares distance of the measured phasors from
    /// phasors that satisfy the identities exactly, so it is unchanged by rescaling an identity
    /// (undoing a strong filter does not buy a small chi-square by inflating the noise).
    pub fn chi2(&self, f: Option<&SensorFilter>) -> f64 {
        let mut chi2 = 0.0;
        for s in &self.steps {
            let h = |c: Channel, n: usize| {
                f.map_or(Complex64::new(1.0, 0.0), |f| {
                    f.channel_response(c, n as f64 * s.frequency_hz)
                })
            };
            let w = TAU * s.frequency_hz;
            for n in 1..s.base.0.len() {
                let undo = |c: Channel, ch: &(Vec<Complex64>, Vec<f64>), scale: f64| {
                    let g = h(c, n).inv() * scale;
                    (ch.0[n] * g, ch.1[n] * g.norm())
                };
                let (b, sb) = undo(Channel::BaseDisplacementM, &s.base, 1.0);
                let (r, sr) = undo(Channel::RelativeDisplacementM, &s.relative, 1.0);
                let o = s
                    .mass_displacement
                    .as_ref()
                    .map(|c| undo(Channel::MassDisplacementM, c, 1.0));
                let a = s.mass_acceleration.as_ref().map(|c| {
                    undo(
                        Channel::MassAccelerationMps2,
                        c,
                        -1.0 / (n as f64 * w).powi(2),
                    )
                });
                // Complex residuals with E|e|^2 = variance; the real chi-square is twice.
                let term = match (o, a) {
                    (Some((o, so)), Some((a, sa))) => {
                        let (e1, e2) = (o - b - r, a - o);
                        let s11 = so * so + sb * sb + sr * sr;
                        let s22 = sa * sa + so * so;
                        let s12 = -so * so;
                        let det = s11 * s22 - s12 * s12;
                        (s22 * e1.norm_sqr() + s11 * e2.norm_sqr()
                            - 2.0 * s12 * (e1 * e2.conj()).re)
                            / det
                    }
                    (Some((x, sx)), None) | (None, Some((x, sx))) => {
                        (x - b - r).norm_sqr() / (sx * sx + sb * sb + sr * sr)
                    }
                    (None, None) => 0.0,
                };
                if term.is_finite() {
                    chi2 += 2.0 * term;
                }
            }
        }
        chi2
    }
}

/// Cutoffs of the coarse grid, as multiples of the highest excitation frequency.
pub const SUBSET_CUTOFF_MULTIPLES: [f64; 9] = [0.75, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 9.0, 15.0];
/// Damping ratios of the coarse grid's second-order members.
pub const SUBSET_DAMPING_RATIOS: [f64; 3] = [0.5, 0.7, 1.0];
/// Bounds of the refined shape: cutoff relative to the highest excitation frequency, damping
/// ratio, delay [s].
const CUTOFF_BOUNDS: [f64; 2] = [0.3, 60.0];
const DAMPING_BOUNDS: [f64; 2] = [0.2, 2.0];
const DELAY_BOUNDS_S: [f64; 2] = [0.0, 0.02];

/// A member of one channel subset and its chi-square.
#[derive(Debug, Clone, Copy)]
pub struct SubsetMember {
    pub filter: SensorFilter,
    pub chi2: f64,
    /// The identities' chi-square with nothing undone.
    pub chi2_none: f64,
    /// Real equations behind the chi-square.
    pub equations: usize,
}

/// A single-channel member explains the channel identities when it leaves at most this share
/// of their chi-square's excess over the noise (the number of equations).
pub const IDENTITIES_LEFT_SHARE: f64 = 0.1;

impl SubsetMember {
    /// BIC of the member against no filter: chi-square drop minus p ln(equations).
    pub fn evidence(&self) -> f64 {
        self.chi2_none
            - self.chi2
            - self.filter.parameters() as f64 * (self.equations.max(2) as f64).ln()
    }

    /// Whether the member is offered as a candidate: the BIC prefers it to no filter, and it
    /// leaves at most [`IDENTITIES_LEFT_SHARE`] of the identities' excess over the noise. A
    /// sensor filter undone leaves the channels consistent; an exciter that moves the base the
    /// rig receives away from the recorded one (a delay, a lag, a resonance) breaks x_o = x_i +
    /// x in a way no causal low-pass on one channel undoes, and a member fitted to it leaves
    /// a fifth to three quarters of the excess (wide forms, seed 1), a sensor member a few
    /// thousandths at most. With no effect the identities hold to the noise (chi-square about
    /// the number of equations at 20 and 30 dB, 1.1-1.7 times at 40 dB) and no member has
    /// positive evidence.
    pub fn explains_identities(&self) -> bool {
        let noise = self.equations as f64;
        self.evidence() > 0.0
            && self.chi2 - noise <= IDENTITIES_LEFT_SHARE * (self.chi2_none - noise).max(0.0)
    }
}

/// The best single-channel member by the identities' chi-square plus its BIC penalty: every
/// channel of [`SUBSET_CHANNELS`], order 1 and 2, a coarse grid of cutoffs (and damping ratios)
/// without a delay, each (channel, order) refined with and without a delay by a simplex search.
pub fn best_subset_member(c: &Consistency, max_frequency_hz: f64) -> Option<SubsetMember> {
    let chi2_none = c.chi2(None);
    let penalty = |f: &SensorFilter| f.parameters() as f64 * (c.equations.max(2) as f64).ln();
    let mut best: Option<(f64, SensorFilter, f64)> = None;
    for ch in SUBSET_CHANNELS {
        for order in [1u8, 2] {
            let dampings: &[f64] = if order == 1 {
                &[1.0]
            } else {
                &SUBSET_DAMPING_RATIOS
            };
            let mut grid_best: Option<(f64, SensorFilter)> = None;
            for m in SUBSET_CUTOFF_MULTIPLES {
                for &z in dampings {
                    let f = SensorFilter::on(ch, order, m * max_frequency_hz, z);
                    let x = c.chi2(Some(&f));
                    if grid_best.is_none_or(|(b, _)| x < b) {
                        grid_best = Some((x, f));
                    }
                }
            }
            let Some((_, start)) = grid_best else {
                continue;
            };
            for with_delay in [false, true] {
                let f = refine(c, start, with_delay, max_frequency_hz);
                let x = c.chi2(Some(&f));
                let key = x + penalty(&f);
                if best.is_none_or(|(b, ..)| key < b) {
                    best = Some((key, f, x));
                }
            }
        }
    }
    best.map(|(_, filter, chi2)| SubsetMember {
        filter,
        chi2,
        chi2_none,
        equations: c.equations,
    })
}

/// The member's shape refined by a Nelder-Mead simplex on the chi-square over (ln cutoff,
/// damping ratio for order 2, delay when `with_delay`), within bounds.
fn refine(
    c: &Consistency,
    start: SensorFilter,
    with_delay: bool,
    max_frequency_hz: f64,
) -> SensorFilter {
    let second = start.order == 2;
    let build = |p: &[f64]| {
        let mut f = start;
        let lo = (CUTOFF_BOUNDS[0] * max_frequency_hz).ln();
        let hi = (CUTOFF_BOUNDS[1] * max_frequency_hz).ln();
        f.cutoff_hz = p[0].clamp(lo, hi).exp();
        let mut k = 1;
        if second {
            f.damping_ratio = p[k].clamp(DAMPING_BOUNDS[0], DAMPING_BOUNDS[1]);
            k += 1;
        }
        f.delay_s = if with_delay {
            p[k].clamp(DELAY_BOUNDS_S[0], DELAY_BOUNDS_S[1])
        } else {
            0.0
        };
        f
    };
    let mut x0 = vec![start.cutoff_hz.ln()];
    let mut step = vec![0.3];
    if second {
        x0.push(start.damping_ratio);
        step.push(0.15);
    }
    if with_delay {
        x0.push(0.002);
        step.push(0.002);
    }
    let best = nelder_mead(|p| c.chi2(Some(&build(p))), &x0, &step, 300);
    let f = build(&best);
    // A delay refined to (nearly) nothing is no delay.
    if f.delay_s < 1e-5 {
        SensorFilter { delay_s: 0.0, ..f }
    } else {
        f
    }
}

/// Minimises `f` from `x0` with initial simplex steps `step` (at most `evaluations` calls).
fn nelder_mead(
    f: impl Fn(&[f64]) -> f64,
    x0: &[f64],
    step: &[f64],
    evaluations: usize,
) -> Vec<f64> {
    let d = x0.len();
    let mut pts: Vec<(Vec<f64>, f64)> = Vec::with_capacity(d + 1);
    pts.push((x0.to_vec(), f(x0)));
    for i in 0..d {
        let mut p = x0.to_vec();
        p[i] += step[i];
        let v = f(&p);
        pts.push((p, v));
    }
    let mut calls = d + 1;
    while calls < evaluations {
        pts.sort_by(|a, b| a.1.total_cmp(&b.1));
        if (pts[d].1 - pts[0].1).abs() <= 1e-9 * (1.0 + pts[0].1.abs()) {
            break;
        }
        let centroid: Vec<f64> = (0..d)
            .map(|j| pts[..d].iter().map(|p| p.0[j]).sum::<f64>() / d as f64)
            .collect();
        let along = |t: f64| -> Vec<f64> {
            centroid
                .iter()
                .zip(&pts[d].0)
                .map(|(c, w)| c + t * (c - w))
                .collect()
        };
        let xr = along(1.0);
        let fr = f(&xr);
        calls += 1;
        if fr < pts[0].1 {
            let xe = along(2.0);
            let fe = f(&xe);
            calls += 1;
            pts[d] = if fe < fr { (xe, fe) } else { (xr, fr) };
        } else if fr < pts[d - 1].1 {
            pts[d] = (xr, fr);
        } else {
            let xc = along(-0.5);
            let fc = f(&xc);
            calls += 1;
            if fc < pts[d].1 {
                pts[d] = (xc, fc);
            } else {
                let x0 = pts[0].0.clone();
                for p in pts.iter_mut().skip(1) {
                    p.0 =
                        p.0.iter()
                            .zip(&x0)
                            .map(|(a, b)| b + 0.5 * (a - b))
                            .collect();
                    p.1 = f(&p.0);
                    calls += 1;
                }
            }
        }
    }
    pts.sort_by(|a, b| a.1.total_cmp(&b.1));
    pts.swap_remove(0).0
}

/// A channel's samples before the filter: the delay taken back (the samples advanced, the last
/// value held), then L undone, x + x' / wc (order 1) or x + 2 zeta x' / wc + x'' / wc^2 (order
/// 2), the derivatives by central differences (the held-out base input is low-passed first).
pub fn undo_samples(x: &[f64], sample_rate_hz: f64, f: &SensorFilter) -> Vec<f64> {
    let x = if f.delay_s > 0.0 {
        delayed(x, sample_rate_hz, -f.delay_s)
    } else {
        x.to_vec()
    };
    let wc = TAU * f.cutoff_hz;
    let d1 = central_difference_at_rate(&x, sample_rate_hz);
    if f.order == 1 {
        return x.iter().zip(&d1).map(|(x, d)| x + d / wc).collect();
    }
    let d2 = central_difference_at_rate(&d1, sample_rate_hz);
    x.iter()
        .zip(d1.iter().zip(&d2))
        .map(|(x, (d1, d2))| x + 2.0 * f.damping_ratio * d1 / wc + d2 / (wc * wc))
        .collect()
}

/// Samples passed through the filter, starting at rest on the first sample: order 1 by
/// [`first_order_lowpass`], order 2 by RK4 on the samples joined by Catmull-Rom cubics
/// (sub-steps of at most half the pole's time constant), then delayed.
pub fn apply_samples(u: &[f64], sample_rate_hz: f64, f: &SensorFilter) -> Vec<f64> {
    let y = if f.order == 1 {
        first_order_lowpass(u, sample_rate_hz, f.cutoff_hz)
    } else {
        second_order_lowpass(u, sample_rate_hz, f.cutoff_hz, f.damping_ratio)
    };
    if f.delay_s > 0.0 {
        delayed(&y, sample_rate_hz, f.delay_s)
    } else {
        y
    }
}

fn second_order_lowpass(u: &[f64], sample_rate_hz: f64, cutoff_hz: f64, zeta: f64) -> Vec<f64> {
    let Some(&u0) = u.first() else {
        return Vec::new();
    };
    let wc = TAU * cutoff_hz;
    let dt = 1.0 / sample_rate_hz;
    let sub = ((2.0 * wc * dt).ceil() as usize).max(4);
    let h = dt / sub as f64;
    let rate = |uu: f64, y: [f64; 2]| [y[1], wc * wc * (uu - y[0]) - 2.0 * zeta * wc * y[1]];
    let mut y = [u0, 0.0];
    let mut out = Vec::with_capacity(u.len());
    out.push(u0);
    let n = u.len() as isize;
    let sample = |i: isize| u[i.clamp(0, n - 1) as usize];
    for i in 0..u.len().saturating_sub(1) {
        let i = i as isize;
        let (p0, p1, p2, p3) = (sample(i - 1), sample(i), sample(i + 1), sample(i + 2));
        let at = |t: f64| {
            let f = t / dt;
            p1 + 0.5
                * f
                * (p2 - p0
                    + f * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3 + f * (3.0 * (p1 - p2) + p3 - p0)))
        };
        for k in 0..sub {
            let t = k as f64 * h;
            let add = |y: [f64; 2], d: [f64; 2], c: f64| [y[0] + c * d[0], y[1] + c * d[1]];
            let k1 = rate(at(t), y);
            let k2 = rate(at(t + 0.5 * h), add(y, k1, 0.5 * h));
            let k3 = rate(at(t + 0.5 * h), add(y, k2, 0.5 * h));
            let k4 = rate(at(t + h), add(y, k3, h));
            for j in 0..2 {
                y[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
            }
        }
        out.push(y[0]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn applying_then_undoing_a_filter_on_samples_is_the_identity_and_matches_h() {
        // A 2.5 Hz sine at 100 Hz through 2nd order 6 Hz (zeta 0.6) and 3 ms: gain and phase of
        // H after the start-up, and undone back to the sine.
        let fs = 100.0;
        let fr = 2.5;
        let f = SensorFilter {
            delay_s: 0.003,
            ..SensorFilter::on(Channel::MassAccelerationMps2, 2, 6.0, 0.6)
        };
        let x: Vec<f64> = (0..1000)
            .map(|i| (TAU * fr * i as f64 / fs).sin())
            .collect();
        let y = apply_samples(&x, fs, &f);
        let h = f.response(fr);
        // The last samples lack the neighbours the interpolation and the delay need.
        for (i, yi) in y.iter().enumerate().take(995).skip(500) {
            let t = i as f64 / fs;
            let want = h.norm() * (TAU * fr * t + h.arg()).sin();
            assert!((yi - want).abs() < 2e-3, "{i}: {yi} vs {want}");
        }
        let back = undo_samples(&y, fs, &f);
        for (i, b) in back.iter().enumerate().skip(500).take(400) {
            assert!((b - x[i]).abs() < 1e-2, "{i}: {b} vs {}", x[i]);
        }
    }

    #[test]
    fn the_identities_see_a_filter_on_one_channel_and_its_undoing_clears_them() {
        // Phasors of a consistent rig step (x_o = x_i + x, a = -(n w)^2 x_o), then the mass
        // accelerometer through 2nd order 5 Hz: the identities' chi-square is large; with that
        // filter undone it is zero, with the filter on another channel it is not.
        let f_hz = 2.0;
        let w = TAU * f_hz;
        let xi = [Complex64::new(0.0, 0.0), Complex64::new(0.006, 0.0)];
        let x = [Complex64::new(0.0, 0.0), Complex64::new(0.002, -0.001)];
        let xo: Vec<Complex64> = xi.iter().zip(&x).map(|(a, b)| a + b).collect();
        let truth = SensorFilter::on(Channel::MassAccelerationMps2, 2, 5.0, 0.7);
        let a: Vec<Complex64> = xo
            .iter()
            .enumerate()
            .map(|(n, v)| -v * (n as f64 * w).powi(2) * truth.response(n as f64 * f_hz))
            .collect();
        let noise = vec![1e-6, 1e-6];
        let ch = |p: &[Complex64], s: &[f64]| (p.to_vec(), s.to_vec());
        let c = Consistency {
            steps: vec![StepChannels {
                frequency_hz: f_hz,
                base: ch(&xi, &noise),
                relative: ch(&x, &noise),
                mass_displacement: Some(ch(&xo, &noise)),
                mass_acceleration: Some(ch(&a, &[1e-6, 1e-6 * w * w])),
            }],
            equations: 4,
        };
        assert!(c.chi2(None) > 1e3, "{}", c.chi2(None));
        assert!(c.chi2(Some(&truth)) < 1e-12, "{}", c.chi2(Some(&truth)));
        let elsewhere = SensorFilter {
            mask: bit(Channel::RelativeDisplacementM),
            ..truth
        };
        assert!(c.chi2(Some(&elsewhere)) > 1e3);
    }
}
