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
//! cross-validated error on a grid (`search`) and refined there continuously
//! ([`refine_on_every_channel`]).

use std::f64::consts::TAU;

use num_complex::Complex64;
use serde::Serialize;

use crate::identify::{IdentifyError, element_harmonics};
use crate::phasor::{HarmonicAnalysis, MultisineAnalysis};
use crate::recipe::Setup;
use crate::record::Channel;
use crate::sim::rig::RIG_CHANNELS;

mod every_channel;
mod identities;
mod samples;

pub use every_channel::{EVERY_CHANNEL_REFINE_EVALUATIONS, refine_on_every_channel};
pub use identities::{
    Consistency, IDENTITIES_LEFT_SHARE, SUBSET_CUTOFF_MULTIPLES, SUBSET_DAMPING_RATIOS,
    SubsetMember, best_subset_member,
};
pub use samples::{apply_samples, undo_samples};

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

pub(crate) fn bit(c: Channel) -> u8 {
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

/// [`unfiltered`] for a multisine record: each channel's bin `k` divided by the filter's
/// response at `k f0` (noise scaled alike).
pub fn unfiltered_multisine(an: &MultisineAnalysis, f: &SensorFilter) -> MultisineAnalysis {
    let mut out = an.clone();
    for ch in &mut out.channels {
        if !f.applies_to(ch.channel) {
            continue;
        }
        for (k, (c, s)) in ch.phasors.iter_mut().zip(&mut ch.noise_std).enumerate() {
            let inv = f.response(k as f64 * an.base_frequency_hz).inv();
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
