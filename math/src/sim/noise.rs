//! Measurement noise at a chosen signal-to-noise ratio.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use crate::record::{Channel, Record};

/// RMS of `channel` over all records of a run (None if no record has it).
pub fn run_rms(records: &[Record], channel: Channel) -> Option<f64> {
    let mut ss = 0.0;
    let mut n = 0usize;
    for r in records {
        if let Some(v) = r.channel(channel) {
            ss += v.iter().map(|x| x * x).sum::<f64>();
            n += v.len();
        }
    }
    (n > 0).then(|| (ss / n as f64).sqrt())
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
