//! Conversions between the messages and the `forcemap_math` types.

use forcemap_math::identify::{Identification, Parameter};
use forcemap_math::phasor::{ChannelPhasors, HarmonicAnalysis, SweepKind, SweepLaw};
use forcemap_math::record::{Channel, Excitation, Record};
use num_complex::Complex64;

use crate::builtin_interfaces::Time;
use crate::msg::{ExcitationState, HarmonicPhasors, IdentifiedParameters, RigSample};
use crate::std_msgs::Header;

/// Why a message does not convert to a `forcemap_math` type.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConversionError {
    #[error(
        "{message}: unknown channel name {name:?} (expected a RigSample field name such as \"relative_displacement_m\")"
    )]
    UnknownChannel { message: &'static str, name: String },
    #[error(
        "ExcitationState: kind {0} is not an excitation (expected SINE=0, RANDOM=1, SWEEP_LINEAR=3, SWEEP_LOG=4 or MULTISINE=5; IDLE=2 means none)"
    )]
    UnknownKind(u8),
    #[error("{message}: {field} has {actual} entries, expected {expected}")]
    Length {
        message: &'static str,
        field: &'static str,
        expected: usize,
        actual: usize,
    },
    #[error("HarmonicPhasors: harmonic_orders must be 0, 1, ..., N, got {0:?}")]
    HarmonicOrders(Vec<u32>),
}

fn u32_sat(n: usize) -> u32 {
    u32::try_from(n).unwrap_or(u32::MAX)
}

fn check_len(
    message: &'static str,
    field: &'static str,
    actual: usize,
    expected: usize,
) -> Result<(), ConversionError> {
    if actual == expected {
        Ok(())
    } else {
        Err(ConversionError::Length {
            message,
            field,
            expected,
            actual,
        })
    }
}

impl RigSample {
    /// Sample `i` of a record: every channel of the record is present, the others NaN.
    /// Panics if `i` is out of range of a channel.
    pub fn from_record(record: &Record, i: usize, header: Header) -> RigSample {
        let mut s = RigSample::new(header, u32_sat(record.step));
        for (c, v) in &record.channels {
            s.set_channel(*c, Some(v[i]));
        }
        s
    }
}

impl ExcitationState {
    /// The state of a step driven by `excitation` on channel `driven` (the unit of amplitude),
    /// lasting `sample_count` samples (0 when not known in advance).
    pub fn from_excitation(
        header: Header,
        step: usize,
        start_time: Time,
        excitation: &Excitation,
        driven: Channel,
        sample_count: usize,
    ) -> ExcitationState {
        let (kind, frequency_hz, amplitude, band) = match excitation {
            Excitation::Sine {
                frequency_hz,
                amplitude,
            } => (Self::SINE, *frequency_hz, *amplitude, [f64::NAN; 2]),
            Excitation::Random { band_hz, rms } => {
                (Self::RANDOM, 0.0, *rms, band_hz.unwrap_or([f64::NAN; 2]))
            }
            // The line set is not carried (a random-odd design does not fit the number
            // fields): a reader finds it from the driven channel (`io::steps`).
            Excitation::Multisine {
                base_frequency_hz,
                lines,
                rms,
            } => {
                let band = match (lines.first(), lines.last()) {
                    (Some(lo), Some(hi)) => [
                        *lo as f64 * base_frequency_hz,
                        *hi as f64 * base_frequency_hz,
                    ],
                    _ => [f64::NAN; 2],
                };
                (Self::MULTISINE, *base_frequency_hz, *rms, band)
            }
            Excitation::Sweep { law } => (
                match law.kind {
                    SweepKind::Linear => Self::SWEEP_LINEAR,
                    SweepKind::Logarithmic => Self::SWEEP_LOG,
                },
                0.0,
                law.amplitude,
                [law.start_frequency_hz, law.end_frequency_hz],
            ),
        };
        ExcitationState {
            header,
            step: u32_sat(step),
            start_time,
            kind,
            driven_channel: driven.name().to_string(),
            frequency_hz,
            amplitude,
            band_low_hz: band[0],
            band_high_hz: band[1],
            sample_count: u32_sat(sample_count),
        }
    }

    /// The state that says the exciter is off from `start_time` on (the run has ended).
    pub fn idle(header: Header, step: usize, start_time: Time, driven: Channel) -> ExcitationState {
        ExcitationState {
            header,
            step: u32_sat(step),
            start_time,
            kind: Self::IDLE,
            driven_channel: driven.name().to_string(),
            frequency_hz: 0.0,
            amplitude: 0.0,
            band_low_hz: f64::NAN,
            band_high_hz: f64::NAN,
            sample_count: 0,
        }
    }

    pub fn is_idle(&self) -> bool {
        self.kind == Self::IDLE
    }

    /// The excitation (a band with a NaN edge is taken as unknown; a multisine's lines empty,
    /// for the reader of its samples to find).
    pub fn excitation(&self) -> Result<Excitation, ConversionError> {
        match self.kind {
            Self::SINE => Ok(Excitation::Sine {
                frequency_hz: self.frequency_hz,
                amplitude: self.amplitude,
            }),
            Self::RANDOM => Ok(Excitation::Random {
                band_hz: (!self.band_low_hz.is_nan() && !self.band_high_hz.is_nan())
                    .then_some([self.band_low_hz, self.band_high_hz]),
                rms: self.amplitude,
            }),
            Self::SWEEP_LINEAR | Self::SWEEP_LOG => Ok(Excitation::Sweep {
                law: SweepLaw {
                    kind: if self.kind == Self::SWEEP_LINEAR {
                        SweepKind::Linear
                    } else {
                        SweepKind::Logarithmic
                    },
                    amplitude: self.amplitude,
                    start_frequency_hz: self.band_low_hz,
                    end_frequency_hz: self.band_high_hz,
                    // The sweep lasts its step, whose length the message may not know: the
                    // step's assembler sets it from the samples (`io::steps`).
                    duration_s: f64::NAN,
                },
            }),
            // The lines are found from the samples when the step is complete (`io::steps`).
            Self::MULTISINE => Ok(Excitation::Multisine {
                base_frequency_hz: self.frequency_hz,
                lines: Vec::new(),
                rms: self.amplitude,
            }),
            k => Err(ConversionError::UnknownKind(k)),
        }
    }

    /// The driven channel.
    pub fn driven(&self) -> Result<Channel, ConversionError> {
        Channel::from_name(&self.driven_channel).ok_or_else(|| ConversionError::UnknownChannel {
            message: "ExcitationState",
            name: self.driven_channel.clone(),
        })
    }
}

impl HarmonicPhasors {
    /// The message of a harmonic analysis. `run_start` is the time of `t = 0` of the run (the
    /// analysis' `t_ref_s` counts from it), so `t_ref = run_start + t_ref_s`.
    pub fn from_analysis(
        analysis: &HarmonicAnalysis,
        run_start: Time,
        header: Header,
    ) -> HarmonicPhasors {
        let orders = analysis.harmonics + 1;
        let cells = analysis.channels.len() * orders;
        let mut phasor_real = Vec::with_capacity(cells);
        let mut phasor_imag = Vec::with_capacity(cells);
        let mut noise_std = Vec::with_capacity(cells);
        for ch in &analysis.channels {
            for k in 0..orders {
                let c = ch
                    .phasors
                    .get(k)
                    .copied()
                    .unwrap_or(Complex64::new(f64::NAN, f64::NAN));
                phasor_real.push(c.re);
                phasor_imag.push(c.im);
                noise_std.push(ch.noise_std.get(k).copied().unwrap_or(f64::NAN));
            }
        }
        HarmonicPhasors {
            header,
            step: u32_sat(analysis.step),
            frequency_hz: analysis.frequency_hz,
            amplitude: analysis.amplitude,
            harmonic_orders: (0..u32_sat(orders)).collect(),
            channel_names: analysis
                .channels
                .iter()
                .map(|c| c.channel.name().to_string())
                .collect(),
            phasor_real,
            phasor_imag,
            noise_std,
            residual_rms: analysis.channels.iter().map(|c| c.residual_rms).collect(),
            periods_used: u32_sat(analysis.periods_used),
            periods_available: u32_sat(analysis.periods_available),
            first_settled_sample: u32_sat(analysis.first_settled_sample),
            samples_used: u32_sat(analysis.samples_used),
            harmonic_cap: u32_sat(analysis.harmonic_cap),
            settled: analysis.settled,
            t_ref: run_start.add_secs_f64(analysis.t_ref_s),
        }
    }

    /// Back to a harmonic analysis (what the identifier needs); `run_start` as in
    /// [`HarmonicPhasors::from_analysis`].
    pub fn to_analysis(&self, run_start: Time) -> Result<HarmonicAnalysis, ConversionError> {
        const M: &str = "HarmonicPhasors";
        let orders = self.harmonic_orders.len();
        if orders == 0
            || self
                .harmonic_orders
                .iter()
                .enumerate()
                .any(|(k, n)| *n as usize != k)
        {
            return Err(ConversionError::HarmonicOrders(
                self.harmonic_orders.clone(),
            ));
        }
        let cells = self.channel_names.len() * orders;
        check_len(M, "phasor_real", self.phasor_real.len(), cells)?;
        check_len(M, "phasor_imag", self.phasor_imag.len(), cells)?;
        check_len(M, "noise_std", self.noise_std.len(), cells)?;
        check_len(
            M,
            "residual_rms",
            self.residual_rms.len(),
            self.channel_names.len(),
        )?;
        let channels = self
            .channel_names
            .iter()
            .enumerate()
            .map(|(c, name)| {
                let channel =
                    Channel::from_name(name).ok_or_else(|| ConversionError::UnknownChannel {
                        message: M,
                        name: name.clone(),
                    })?;
                let r = c * orders..(c + 1) * orders;
                Ok(ChannelPhasors {
                    channel,
                    phasors: self.phasor_real[r.clone()]
                        .iter()
                        .zip(&self.phasor_imag[r.clone()])
                        .map(|(re, im)| Complex64::new(*re, *im))
                        .collect(),
                    noise_std: self.noise_std[r].to_vec(),
                    residual_rms: self.residual_rms[c],
                    // The message carries settled steps' phasors, which do not change.
                    rate_per_s: Vec::new(),
                })
            })
            .collect::<Result<Vec<_>, ConversionError>>()?;
        Ok(HarmonicAnalysis {
            step: self.step as usize,
            frequency_hz: self.frequency_hz,
            amplitude: self.amplitude,
            t_ref_s: self.t_ref.secs_since(run_start),
            periods_used: self.periods_used as usize,
            periods_available: self.periods_available as usize,
            first_settled_sample: self.first_settled_sample as usize,
            samples_used: self.samples_used as usize,
            settled: self.settled,
            harmonics: orders - 1,
            harmonic_cap: self.harmonic_cap as usize,
            channels,
            frequency_rate_hz_per_s: 0.0,
        })
    }
}

/// `(analysis, run_start)`, with a default header; see [`HarmonicPhasors::from_analysis`].
impl From<(&HarmonicAnalysis, Time)> for HarmonicPhasors {
    fn from((analysis, run_start): (&HarmonicAnalysis, Time)) -> Self {
        HarmonicPhasors::from_analysis(analysis, run_start, Header::default())
    }
}

impl IdentifiedParameters {
    /// The message of an identification with the given header.
    pub fn from_identification(id: &Identification, header: Header) -> IdentifiedParameters {
        let names: Vec<String> = id.parameters.iter().map(|p| p.name.clone()).collect();
        let r_percent = names
            .iter()
            .enumerate()
            .map(|(i, n)| {
                id.r.iter()
                    .find(|(rn, _)| rn == n)
                    .or_else(|| id.r.get(i))
                    .map_or(f64::NAN, |(_, v)| *v)
            })
            .collect();
        IdentifiedParameters {
            header,
            model: id.model.clone(),
            method: id.method.clone(),
            values: id.parameters.iter().map(|p| p.value).collect(),
            standard_deviations: id.parameters.iter().map(|p| p.std).collect(),
            covariance: id.covariance.iter().flatten().copied().collect(),
            r_percent,
            parameter_names: names,
            equations: u32_sat(id.equations),
            condition_number: id.condition_number,
            residual_rms: id.residual_rms,
            steps_used: id.steps_used.iter().map(|s| u32_sat(*s)).collect(),
            warnings: id.warnings.clone(),
        }
    }

    /// Back to an identification; the arrays must have matching lengths.
    pub fn to_identification(&self) -> Result<Identification, ConversionError> {
        const M: &str = "IdentifiedParameters";
        let n = self.parameter_names.len();
        check_len(M, "values", self.values.len(), n)?;
        check_len(M, "standard_deviations", self.standard_deviations.len(), n)?;
        check_len(M, "covariance", self.covariance.len(), n * n)?;
        check_len(M, "r_percent", self.r_percent.len(), n)?;
        Ok(Identification {
            model: self.model.clone(),
            method: self.method.clone(),
            parameters: (0..n)
                .map(|i| Parameter {
                    name: self.parameter_names[i].clone(),
                    value: self.values[i],
                    std: self.standard_deviations[i],
                })
                .collect(),
            covariance: (0..n)
                .map(|i| self.covariance[i * n..(i + 1) * n].to_vec())
                .collect(),
            condition_number: self.condition_number,
            equations: self.equations as usize,
            r: self
                .parameter_names
                .iter()
                .cloned()
                .zip(self.r_percent.iter().copied())
                .collect(),
            residual_rms: self.residual_rms,
            // Not on the wire (its warning is, among the warnings).
            fit_quality: None,
            misfit_noise_std: None,
            steps_used: self.steps_used.iter().map(|s| *s as usize).collect(),
            warnings: self.warnings.clone(),
        })
    }
}

/// With a default header; set `header` afterwards.
impl From<&Identification> for IdentifiedParameters {
    fn from(id: &Identification) -> Self {
        IdentifiedParameters::from_identification(id, Header::default())
    }
}
