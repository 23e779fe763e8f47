//! Measurement noise at a chosen signal-to-noise ratio.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use crate::record::{Channel, Record};

/// RMS of `channel` over all records of a run (None if no record has it).
pub fn run_rms(records: &[Record], channel: Channel) -> Option<f64> {
    let mut acc = RunRms::default();
    records.iter().for_each(|r| acc.add(r));
    acc.rms(channel)
}

/// [`run_rms`] of every channel, accumulated record by record (for a run streamed in records;
/// the same sums in the same order, so the same RMS bit for bit).
#[derive(Debug, Clone, Default)]
pub struct RunRms {
    /// Sum of squares and sample count per channel of `Channel::ALL`.
    sums: [(f64, usize); Channel::ALL.len()],
}

impl RunRms {
    pub fn add(&mut self, record: &Record) {
        for (c, (ss, n)) in Channel::ALL.into_iter().zip(self.sums.iter_mut()) {
            if let Some(v) = record.channel(c) {
                *ss += v.iter().map(|x| x * x).sum::<f64>();
                *n += v.len();
            }
        }
    }

    pub fn rms(&self, channel: Channel) -> Option<f64> {
        let i = Channel::ALL.iter().position(|c| *c == channel)?;
        let (ss, n) = self.sums[i];
        (n > 0).then(|| (ss / n as f64).sqrt())
    }
}

/// The noise [`add_noise`] adds to a run, added record by record: each channel's share of the
/// one ChaCha8 stream is found ahead (drawing the earlier channels' samples without keeping
/// them), so a run streamed in records gets the noise of its whole-run simulation bit for bit.
pub struct NoiseStreams {
    channels: Vec<(Channel, Normal<f64>, ChaCha8Rng)>,
}

impl NoiseStreams {
    /// The noise of a run whose noise-free records gave `rms`; None for a noise-free run.
    pub fn new(rms: &RunRms, snr_db: Option<f64>, seed: u64) -> Option<NoiseStreams> {
        let snr = snr_db?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut channels = Vec::new();
        for (c, &(_, n)) in Channel::ALL.into_iter().zip(&rms.sums) {
            let Some(rms) = rms.rms(c) else {
                continue;
            };
            let std = rms / 10f64.powf(snr / 20.0);
            if !super::is_positive(std) {
                continue;
            }
            let normal = Normal::new(0.0, std).expect("finite positive std");
            channels.push((c, normal, rng.clone()));
            // The draws of a sample do not depend on the standard deviation.
            for _ in 0..n {
                normal.sample(&mut rng);
            }
        }
        Some(NoiseStreams { channels })
    }

    /// Adds the noise of the run's next record.
    pub fn add(&mut self, record: &mut Record) {
        for (c, normal, rng) in &mut self.channels {
            if let Some(v) = record.channel_mut(*c) {
                for x in v.iter_mut() {
                    *x += normal.sample(rng);
                }
            }
        }
    }
}

/// Adds white Gaussian noise to every channel of a run: per channel, standard deviation
/// `RMS(channel over the whole run) / 10^(snr_db / 20)`. `None` leaves the records
/// noise-free. The noise comes from one ChaCha8 stream seeded with `seed`, drawn channel by
/// channel in `Channel::ALL` order and record by record, so a run is reproducible.
pub fn add_noise(records: &mut [Record], snr_db: Option<f64>, seed: u64) {
    let Some(snr) = snr_db else { return };
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for c in Channel::ALL {
        let Some(rms) = run_rms(records, c) else {
            continue;
        };
        let std = rms / 10f64.powf(snr / 20.0);
        if !super::is_positive(std) {
            continue;
        }
        let normal = Normal::new(0.0, std).expect("finite positive std");
        for r in records.iter_mut() {
            if let Some(v) = r.channel_mut(c) {
                for x in v.iter_mut() {
                    *x += normal.sample(&mut rng);
                }
            }
        }
    }
}
