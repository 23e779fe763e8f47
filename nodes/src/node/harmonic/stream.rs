//! The harmonic node's stream of the step being assembled, and what it hands to the analysis
//! when the step completes: the stream, or the record when the stream does not match it.

use forcemap_io::steps::{StepPlan, StepSample};
use forcemap_math::phasor::{
    HarmonicAnalysis, MultisineOptions, PhasorOptions, PhasorStream, ProvisionalUpdates,
    analyse_multisine, analyse_record,
};
use forcemap_math::record::{Excitation, Record};

/// A complete sine or multisine step, ready for its analysis.
pub enum Analysis {
    /// Accumulated as the samples arrived: only the settling and the joint fit remain.
    Streamed(Box<PhasorStream>),
    /// The record, to be analysed whole (the stream did not match it; see the module docs).
    Batch(Record),
    /// A periodic multisine record (its lines found when it was assembled), analysed whole at
    /// its end ([`analyse_multisine`]): its averaged period as harmonics of the base frequency.
    Multisine(Record),
}

impl Analysis {
    pub fn step(&self) -> usize {
        match self {
            Analysis::Streamed(s) => s.step(),
            Analysis::Batch(r) | Analysis::Multisine(r) => r.step,
        }
    }

    pub fn is_streamed(&self) -> bool {
        matches!(self, Analysis::Streamed(_))
    }

    pub fn is_multisine(&self) -> bool {
        matches!(self, Analysis::Multisine(_))
    }

    /// Whether [`Analysis::analyse`] only hands over what was computed as the samples came
    /// (a stream told the step's length): cheap enough to run without a thread of its own.
    pub fn analysed_ahead(&self) -> bool {
        matches!(self, Analysis::Streamed(s) if s.analysed_ahead())
    }

    /// The phasors of the step (the same either way for the same record); a multisine's are
    /// the bins of its averaged period ([`MultisineAnalysis::as_harmonic_analysis`]).
    ///
    /// [`MultisineAnalysis::as_harmonic_analysis`]: forcemap_math::phasor::MultisineAnalysis::as_harmonic_analysis
    pub fn run(mut self, options: &PhasorOptions) -> Result<HarmonicAnalysis, String> {
        self.analyse(options)
    }

    /// [`Analysis::run`] keeping the stream or record, so that the caller frees their memory
    /// (megabytes at 10 kHz, whose release took up to about 1 ms) after the phasors are out.
    pub fn analyse(&mut self, options: &PhasorOptions) -> Result<HarmonicAnalysis, String> {
        match self {
            Analysis::Streamed(s) => s.analyse().map_err(|e| e.to_string()),
            Analysis::Batch(r) => analyse_record(r, options).map_err(|e| e.to_string()),
            Analysis::Multisine(r) => {
                let Excitation::Multisine { rms, .. } = r.excitation else {
                    return Err(format!("step {}: not a multisine record", r.step));
                };
                analyse_multisine(r, &MultisineOptions::default())
                    .map(|an| an.as_harmonic_analysis(rms))
                    .map_err(|e| e.to_string())
            }
        }
    }
}

/// The stream of the step being assembled.
pub(super) struct StepStream {
    pub(super) step: usize,
    excitation: Excitation,
    /// The plan's sample count (0: not known).
    expected: usize,
    /// The first sample's time and values, held until the second gives the sample rate.
    first: Option<(f64, Vec<f64>)>,
    /// `None` until the second sample, and when the stream cannot run (random excitation, an
    /// unusable first interval): the record is then analysed in batch if at all.
    phasors: Option<PhasorStream>,
    /// The values of the sample being pushed (reused: no allocation per sample).
    values: Vec<f64>,
}

impl StepStream {
    pub(super) fn new(step: usize, plan: Option<&StepPlan>) -> StepStream {
        StepStream {
            step,
            excitation: plan.map_or(Excitation::UNKNOWN, |p| p.excitation.clone()),
            expected: plan.map_or(0, |p| p.sample_count),
            first: None,
            phasors: None,
            values: Vec::new(),
        }
    }

    pub(super) fn push(&mut self, sample: &StepSample, options: &PhasorOptions) {
        if !matches!(self.excitation, Excitation::Sine { .. }) {
            return;
        }
        let values = || sample.values.iter().map(|(_, v)| *v);
        if let Some(s) = &mut self.phasors {
            self.values.clear();
            self.values.extend(values());
            s.push(&self.values);
            return;
        }
        let Some((t0, first)) = self.first.take() else {
            self.first = Some((sample.t_s, values().collect()));
            return;
        };
        // Rigs sample at whole rates and the assembler snaps a step's rate to them; a rate that
        // is not one is caught when the step completes.
        let rate_hz = (1.0 / (sample.t_s - t0)).round();
        let channels = sample.values.iter().map(|(c, _)| *c).collect();
        if let Ok(mut s) =
            PhasorStream::new(self.step, &self.excitation, rate_hz, t0, channels, options)
        {
            s.expect_samples(self.expected);
            s.push(&first);
            s.push(&values().collect::<Vec<_>>());
            self.phasors = Some(s);
        }
    }

    /// A copy of the stream when provisional phasors are due after the sample just pushed
    /// (every `update_period_s` of the step's samples, not at its last: see
    /// [`ProvisionalUpdates`]); the copy is analysed off the intake path.
    pub(super) fn provisional(&self, update_period_s: f64) -> Option<PhasorStream> {
        let s = self.phasors.as_ref()?;
        let updates = ProvisionalUpdates::new(update_period_s, s.sample_rate_hz()).ok()?;
        updates.due(s.samples(), self.expected).then(|| s.clone())
    }

    /// The stream if it holds exactly the samples of `record` at its rate and frequency (a
    /// label the data corrected is not the stream's).
    pub(super) fn matching(self, record: &Record) -> Option<PhasorStream> {
        let s = self.phasors?;
        let frequency = match record.excitation {
            Excitation::Sine { frequency_hz, .. } => Some(frequency_hz),
            _ => None,
        };
        let same = s.step() == record.step
            && s.samples() == record.len()
            && s.sample_rate_hz() == record.sample_rate_hz
            && frequency == Some(s.frequency_hz())
            && s.channels()
                .iter()
                .eq(record.channels.iter().map(|(c, _)| c));
        same.then_some(s)
    }
}
