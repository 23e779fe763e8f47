//! Sampled records: what a test bench (or a simulator) hands to the analysis.

use serde::{Deserialize, Serialize};

use crate::phasor::SweepLaw;

/// A measured channel. The names are the CSV column names of the test-bench export (SI units).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Channel {
    /// Prescribed base (exciter) displacement x_i [m].
    BaseDisplacementM,
    /// Displacement across the nonlinear element x [m] (rig: mass minus base; 3-DOF: x2 - x3).
    RelativeDisplacementM,
    /// Mass acceleration x_o'' [m/s^2].
    MassAccelerationMps2,
    /// Mass displacement x_o [m].
    MassDisplacementM,
    /// Base acceleration x_i'' [m/s^2].
    BaseAccelerationMps2,
    /// Drive force [N] (3-DOF example: the force on m2).
    ForceN,
    /// Displacement of the driven end of the element [m] (3-DOF example: x2), used with the
    /// drive-point FRF of the linear substructure (eq. 22).
    DrivePointDisplacementM,
}

impl Channel {
    pub const ALL: [Channel; 7] = [
        Channel::BaseDisplacementM,
        Channel::RelativeDisplacementM,
        Channel::MassAccelerationMps2,
        Channel::MassDisplacementM,
        Channel::BaseAccelerationMps2,
        Channel::ForceN,
        Channel::DrivePointDisplacementM,
    ];

    /// The CSV column name (also the ROS message field name).
    pub fn name(self) -> &'static str {
        match self {
            Channel::BaseDisplacementM => "base_displacement_m",
            Channel::RelativeDisplacementM => "relative_displacement_m",
            Channel::MassAccelerationMps2 => "mass_acceleration_mps2",
            Channel::MassDisplacementM => "mass_displacement_m",
            Channel::BaseAccelerationMps2 => "base_acceleration_mps2",
            Channel::ForceN => "force_n",
            Channel::DrivePointDisplacementM => "drive_point_displacement_m",
        }
    }

    pub fn from_name(name: &str) -> Option<Channel> {
        Channel::ALL.into_iter().find(|c| c.name() == name)
    }
}

/// What drove the system during a record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Excitation {
    /// A stepped-sine step at one frequency. `amplitude` is in the unit of the driven
    /// quantity (m of base displacement for the rig, N of force for the 3-DOF example).
    Sine { frequency_hz: f64, amplitude: f64 },
    /// Band-limited random excitation. `band_hz` is known for simulated records and may be
    /// unknown for imported ones; `rms` is in the unit of the driven quantity.
    Random { band_hz: Option<[f64; 2]>, rms: f64 },
    /// A periodic multisine: sines at the lines `k * base_frequency_hz` (`k` in `lines`,
    /// ascending), repeated period after period; every period is `1 / base_frequency_hz`
    /// long from the record's first sample. `rms` is in the unit of the driven quantity.
    Multisine {
        base_frequency_hz: f64,
        lines: Vec<usize>,
        rms: f64,
    },
    /// A sine sweep `amplitude sin(phi(t))` from the record's first sample (phase 0 there) over
    /// `law.duration_s`; `law.amplitude` is in the unit of the driven quantity.
    Sweep { law: SweepLaw },
}

impl Excitation {
    /// What drove a record nobody labelled (no plan, or a run not yet cut into steps): random,
    /// band and level unknown.
    pub const UNKNOWN: Excitation = Excitation::Random {
        band_hz: None,
        rms: f64::NAN,
    };

    pub fn frequency_hz(&self) -> Option<f64> {
        match self {
            Excitation::Sine { frequency_hz, .. } => Some(*frequency_hz),
            Excitation::Random { .. } | Excitation::Multisine { .. } | Excitation::Sweep { .. } => {
                None
            }
        }
    }
}

/// One excitation step (or one random record): uniformly sampled channels, starting when the
/// excitation changed, so the first samples hold the transient.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Record {
    /// Record index within a run (0, 1, 2, ...).
    pub step: usize,
    pub excitation: Excitation,
    pub sample_rate_hz: f64,
    /// Time of the first sample [s] since the start of the run.
    pub start_time_s: f64,
    /// Channel samples, all of the same length.
    pub channels: Vec<(Channel, Vec<f64>)>,
}

impl Record {
    pub fn len(&self) -> usize {
        self.channels.first().map_or(0, |(_, v)| v.len())
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn channel(&self, c: Channel) -> Option<&[f64]> {
        self.channels
            .iter()
            .find(|(k, _)| *k == c)
            .map(|(_, v)| v.as_slice())
    }

    pub fn channel_mut(&mut self, c: Channel) -> Option<&mut Vec<f64>> {
        self.channels
            .iter_mut()
            .find(|(k, _)| *k == c)
            .map(|(_, v)| v)
    }

    /// Time of sample `i` [s].
    pub fn time_s(&self, i: usize) -> f64 {
        self.start_time_s + i as f64 / self.sample_rate_hz
    }
}
