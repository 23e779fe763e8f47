//! The messages of `forcemap_msgs` (`msgs/msg/*.msg`). Field order and types follow the
//! `.msg` files exactly (CDR has no field names); see the files for units and layouts.

use forcemap_math::record::Channel;
use serde::{Deserialize, Serialize};

use crate::builtin_interfaces::{TIME_DEF, Time};
use crate::std_msgs::{HEADER_DEF, Header};
use crate::{MsgDef, ros_message};

pub const RIG_SAMPLE_DEF: MsgDef = MsgDef {
    name: "forcemap_msgs/RigSample",
    text: include_str!("../msg/RigSample.msg"),
    deps: &[HEADER_DEF],
};
pub const EXCITATION_STATE_DEF: MsgDef = MsgDef {
    name: "forcemap_msgs/ExcitationState",
    text: include_str!("../msg/ExcitationState.msg"),
    deps: &[HEADER_DEF, TIME_DEF],
};
pub const HARMONIC_PHASORS_DEF: MsgDef = MsgDef {
    name: "forcemap_msgs/HarmonicPhasors",
    text: include_str!("../msg/HarmonicPhasors.msg"),
    deps: &[HEADER_DEF, TIME_DEF],
};
pub const IDENTIFIED_PARAMETERS_DEF: MsgDef = MsgDef {
    name: "forcemap_msgs/IdentifiedParameters",
    text: include_str!("../msg/IdentifiedParameters.msg"),
    deps: &[HEADER_DEF],
};
pub const AXIS_SAMPLE_DEF: MsgDef = MsgDef {
    name: "forcemap_msgs/AxisSample",
    text: include_str!("../msg/AxisSample.msg"),
    deps: &[HEADER_DEF],
};
pub const GAP_DIAGNOSIS_DEF: MsgDef = MsgDef {
    name: "forcemap_msgs/GapDiagnosis",
    text: include_str!("../msg/GapDiagnosis.msg"),
    deps: &[HEADER_DEF],
};

/// The definitions of all `forcemap_msgs` messages.
pub const ALL: [MsgDef; 6] = [
    RIG_SAMPLE_DEF,
    EXCITATION_STATE_DEF,
    HARMONIC_PHASORS_DEF,
    IDENTIFIED_PARAMETERS_DEF,
    AXIS_SAMPLE_DEF,
    GAP_DIAGNOSIS_DEF,
];

/// `forcemap_msgs/msg/RigSample`: one sample of the measured channels. A channel that is not
/// measured is NaN and its bit in `present_channels` is clear; use [`RigSample::channel`] and
/// [`RigSample::set_channel`] to keep both in step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RigSample {
    pub header: Header,
    pub step: u32,
    pub present_channels: u32,
    pub base_displacement_m: f64,
    pub relative_displacement_m: f64,
    pub mass_acceleration_mps2: f64,
    pub mass_displacement_m: f64,
    pub base_acceleration_mps2: f64,
    pub force_n: f64,
    pub drive_point_displacement_m: f64,
}

ros_message!(RigSample, "forcemap_msgs/msg/RigSample", RIG_SAMPLE_DEF);

impl RigSample {
    pub const BASE_DISPLACEMENT: u32 = 1;
    pub const RELATIVE_DISPLACEMENT: u32 = 2;
    pub const MASS_ACCELERATION: u32 = 4;
    pub const MASS_DISPLACEMENT: u32 = 8;
    pub const BASE_ACCELERATION: u32 = 16;
    pub const FORCE: u32 = 32;
    pub const DRIVE_POINT_DISPLACEMENT: u32 = 64;

    /// A sample with no channel present (all NaN).
    pub fn new(header: Header, step: u32) -> RigSample {
        RigSample {
            header,
            step,
            present_channels: 0,
            base_displacement_m: f64::NAN,
            relative_displacement_m: f64::NAN,
            mass_acceleration_mps2: f64::NAN,
            mass_displacement_m: f64::NAN,
            base_acceleration_mps2: f64::NAN,
            force_n: f64::NAN,
            drive_point_displacement_m: f64::NAN,
        }
    }

    /// The `present_channels` bit of a channel.
    pub fn bit(channel: Channel) -> u32 {
        match channel {
            Channel::BaseDisplacementM => Self::BASE_DISPLACEMENT,
            Channel::RelativeDisplacementM => Self::RELATIVE_DISPLACEMENT,
            Channel::MassAccelerationMps2 => Self::MASS_ACCELERATION,
            Channel::MassDisplacementM => Self::MASS_DISPLACEMENT,
            Channel::BaseAccelerationMps2 => Self::BASE_ACCELERATION,
            Channel::ForceN => Self::FORCE,
            Channel::DrivePointDisplacementM => Self::DRIVE_POINT_DISPLACEMENT,
        }
    }

    fn field(&self, channel: Channel) -> f64 {
        match channel {
            Channel::BaseDisplacementM => self.base_displacement_m,
            Channel::RelativeDisplacementM => self.relative_displacement_m,
            Channel::MassAccelerationMps2 => self.mass_acceleration_mps2,
            Channel::MassDisplacementM => self.mass_displacement_m,
            Channel::BaseAccelerationMps2 => self.base_acceleration_mps2,
            Channel::ForceN => self.force_n,
            Channel::DrivePointDisplacementM => self.drive_point_displacement_m,
        }
    }

    fn field_mut(&mut self, channel: Channel) -> &mut f64 {
        match channel {
            Channel::BaseDisplacementM => &mut self.base_displacement_m,
            Channel::RelativeDisplacementM => &mut self.relative_displacement_m,
            Channel::MassAccelerationMps2 => &mut self.mass_acceleration_mps2,
            Channel::MassDisplacementM => &mut self.mass_displacement_m,
            Channel::BaseAccelerationMps2 => &mut self.base_acceleration_mps2,
            Channel::ForceN => &mut self.force_n,
            Channel::DrivePointDisplacementM => &mut self.drive_point_displacement_m,
        }
    }

    /// The value of a channel if its bit is set.
    pub fn channel(&self, channel: Channel) -> Option<f64> {
        (self.present_channels & Self::bit(channel) != 0).then(|| self.field(channel))
    }

    /// Sets a channel (bit and value); `None` clears the bit and stores NaN.
    pub fn set_channel(&mut self, channel: Channel, value: Option<f64>) {
        match value {
            Some(v) => {
                self.present_channels |= Self::bit(channel);
                *self.field_mut(channel) = v;
            }
            None => {
                self.present_channels &= !Self::bit(channel);
                *self.field_mut(channel) = f64::NAN;
            }
        }
    }

    /// Builder form of [`RigSample::set_channel`].
    pub fn with(mut self, channel: Channel, value: f64) -> Self {
        self.set_channel(channel, Some(value));
        self
    }

    /// The channels present, in [`Channel::ALL`] order.
    pub fn present(&self) -> Vec<Channel> {
        Channel::ALL
            .into_iter()
            .filter(|c| self.present_channels & Self::bit(*c) != 0)
            .collect()
    }
}

/// `forcemap_msgs/msg/ExcitationState`: what drives the rig during one step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExcitationState {
    pub header: Header,
    pub step: u32,
    pub start_time: Time,
    /// [`Self::SINE`], [`Self::RANDOM`] or [`Self::IDLE`].
    pub kind: u8,
    pub driven_channel: String,
    pub frequency_hz: f64,
    pub amplitude: f64,
    pub band_low_hz: f64,
    pub band_high_hz: f64,
    /// Samples in the step; 0 when not known in advance.
    pub sample_count: u32,
}

ros_message!(
    ExcitationState,
    "forcemap_msgs/msg/ExcitationState",
    EXCITATION_STATE_DEF
);

impl ExcitationState {
    pub const SINE: u8 = 0;
    pub const RANDOM: u8 = 1;
    pub const IDLE: u8 = 2;
    pub const SWEEP_LINEAR: u8 = 3;
    pub const SWEEP_LOG: u8 = 4;
    pub const MULTISINE: u8 = 5;
}

/// `forcemap_msgs/msg/HarmonicPhasors`: phasors of one settled step. The arrays
/// `phasor_real`, `phasor_imag`, `noise_std` are channel-major:
/// index `c * harmonic_orders.len() + k`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HarmonicPhasors {
    pub header: Header,
    pub step: u32,
    pub frequency_hz: f64,
    pub amplitude: f64,
    pub harmonic_orders: Vec<u32>,
    pub channel_names: Vec<String>,
    pub phasor_real: Vec<f64>,
    pub phasor_imag: Vec<f64>,
    pub noise_std: Vec<f64>,
    pub residual_rms: Vec<f64>,
    pub periods_used: u32,
    pub periods_available: u32,
    pub first_settled_sample: u32,
    pub samples_used: u32,
    pub harmonic_cap: u32,
    pub settled: bool,
    pub t_ref: Time,
}

ros_message!(
    HarmonicPhasors,
    "forcemap_msgs/msg/HarmonicPhasors",
    HARMONIC_PHASORS_DEF
);

impl HarmonicPhasors {
    /// `harmonic_cap` of a periodic multisine step's message: its entries are the bins of the
    /// averaged period (harmonics of the base frequency `frequency_hz`), not a sine step's fit.
    pub const MULTISINE_CAP: u32 = 0;

    /// Index of channel `c`, harmonic index `k` in the flattened arrays.
    pub fn index(&self, c: usize, k: usize) -> usize {
        c * self.harmonic_orders.len() + k
    }

    /// `(re, im)` of channel index `c`, harmonic index `k`, if the arrays hold it.
    pub fn phasor(&self, c: usize, k: usize) -> Option<(f64, f64)> {
        if c >= self.channel_names.len() || k >= self.harmonic_orders.len() {
            return None;
        }
        let i = self.index(c, k);
        Some((*self.phasor_real.get(i)?, *self.phasor_imag.get(i)?))
    }
}

/// `forcemap_msgs/msg/IdentifiedParameters`: theta with its uncertainty.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IdentifiedParameters {
    pub header: Header,
    pub model: String,
    pub method: String,
    pub parameter_names: Vec<String>,
    pub values: Vec<f64>,
    pub standard_deviations: Vec<f64>,
    /// Row-major `n x n`.
    pub covariance: Vec<f64>,
    pub r_percent: Vec<f64>,
    pub equations: u32,
    pub condition_number: f64,
    pub residual_rms: f64,
    pub steps_used: Vec<u32>,
    pub warnings: Vec<String>,
}

ros_message!(
    IdentifiedParameters,
    "forcemap_msgs/msg/IdentifiedParameters",
    IDENTIFIED_PARAMETERS_DEF
);

impl IdentifiedParameters {
    /// The value of a parameter by name.
    pub fn value(&self, name: &str) -> Option<f64> {
        let i = self.parameter_names.iter().position(|n| n == name)?;
        self.values.get(i).copied()
    }

    /// Covariance entry (i, j).
    pub fn covariance_at(&self, i: usize, j: usize) -> Option<f64> {
        let n = self.parameter_names.len();
        if i >= n || j >= n {
            return None;
        }
        self.covariance.get(i * n + j).copied()
    }
}

/// `forcemap_msgs/msg/AxisSample`: one sample of a single driven axis (e.g. the EMPS
/// benchmark). Quantities that were not measured are NaN.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AxisSample {
    pub header: Header,
    /// Measured position q [m].
    pub position_m: f64,
    /// Velocity q' [m/s]; NaN when not measured.
    pub velocity_mps: f64,
    /// Acceleration q'' [m/s^2]; NaN when not measured.
    pub acceleration_mps2: f64,
    /// Reference position of the position controller [m]; NaN if none.
    pub reference_position_m: f64,
    /// Drive force [N] (= gain * drive_input).
    pub force_n: f64,
    /// The drive's input signal in the drive's unit (EMPS: vir [V]).
    pub drive_input: f64,
}

ros_message!(AxisSample, "forcemap_msgs/msg/AxisSample", AXIS_SAMPLE_DEF);

impl AxisSample {
    /// A sample with every quantity NaN (not measured).
    pub fn new(header: Header) -> AxisSample {
        AxisSample {
            header,
            position_m: f64::NAN,
            velocity_mps: f64::NAN,
            acceleration_mps2: f64::NAN,
            reference_position_m: f64::NAN,
            force_n: f64::NAN,
            drive_input: f64::NAN,
        }
    }
}

/// `forcemap_msgs/msg/GapDiagnosis`: the live diagnosis of a baseline model's gap.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GapDiagnosis {
    pub header: Header,
    pub baseline_model: String,
    pub steps: u32,
    pub verdict: String,
    pub top_effect: String,
    pub gap_before_percent: f64,
    pub gap_after_percent: f64,
    pub noise_floor_percent: f64,
    pub ranked_effects: Vec<String>,
    pub ranked_gap_after_percent: Vec<f64>,
    pub ranked_significant: Vec<bool>,
}

ros_message!(
    GapDiagnosis,
    "forcemap_msgs/msg/GapDiagnosis",
    GAP_DIAGNOSIS_DEF
);
