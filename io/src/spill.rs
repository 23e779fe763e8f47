//! Records whose samples wait on disk: what a streamed identification keeps for after the fit
//! (the band-random records it validates on) without holding them in memory, so that memory
//! does not grow with the file.
//!
//! The samples go to an unnamed temporary file (created in the system's temporary directory
//! and already unlinked, so nothing is left behind when the process ends, however it ends);
//! each record's step, excitation, rate and channel names stay in memory. They are read back
//! in their order, a part of bounded size at a time, bit for bit as they were written.

use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::PathBuf;

use forcemap_math::record::Record;

/// A failure to write or read back spilled samples, naming the temporary directory.
#[derive(Debug, thiserror::Error)]
#[error("a temporary file in {}: {source}", dir.display())]
pub struct SpillError {
    pub dir: PathBuf,
    #[source]
    pub source: std::io::Error,
}

/// Records in their order, their samples in a temporary file (created by the first record).
#[derive(Default)]
pub struct SpilledRecords {
    file: Option<BufWriter<File>>,
    /// Each record with its channels named and emptied, and its length.
    records: Vec<(Record, usize)>,
}

const F64_BYTES: usize = std::mem::size_of::<f64>();

impl SpilledRecords {
    /// An empty store, with no file yet.
    pub fn new() -> SpilledRecords {
        SpilledRecords::default()
    }

    /// Writes `record`'s samples to the file and keeps the rest.
    pub fn push(&mut self, mut record: Record) -> Result<(), SpillError> {
        let file = match &mut self.file {
            Some(f) => f,
            None => self.file.insert(BufWriter::with_capacity(
                1 << 20,
                tempfile::tempfile().map_err(spill_error)?,
            )),
        };
        let len = record.len();
        for (_, values) in &mut record.channels {
            for v in values.iter() {
                file.write_all(&v.to_le_bytes()).map_err(spill_error)?;
            }
            *values = Vec::new();
        }
        self.records.push((record, len));
        Ok(())
    }

    /// How many records are held.
    pub fn len(&self) -> usize {
        self.records.len()
    }

    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// The records read back in their order, in parts of at least one record and, past the
    /// first, of at most `part_samples` samples (of one channel) each.
    pub fn into_parts(self, part_samples: usize) -> Result<SpilledParts, SpillError> {
        let file = match self.file {
            Some(f) => {
                let mut file = f.into_inner().map_err(|e| spill_error(e.into_error()))?;
                file.seek(SeekFrom::Start(0)).map_err(spill_error)?;
                Some(BufReader::with_capacity(1 << 20, file))
            }
            None => None,
        };
        Ok(SpilledParts {
            file,
            records: self.records.into_iter(),
            part_samples: part_samples.max(1),
            bytes: Vec::new(),
        })
    }
}

/// The spilled records read back a part at a time ([`SpilledRecords::into_parts`]).
pub struct SpilledParts {
    /// None when no record was spilled.
    file: Option<BufReader<File>>,
    records: std::vec::IntoIter<(Record, usize)>,
    part_samples: usize,
    bytes: Vec<u8>,
}

impl SpilledParts {
    fn read_record(&mut self, mut record: Record, len: usize) -> Result<Record, SpillError> {
        self.bytes.resize(len * F64_BYTES, 0);
        let file = self
            .file
            .as_mut()
            .expect("a record spilled, so a file written");
        for (_, values) in &mut record.channels {
            file.read_exact(&mut self.bytes).map_err(spill_error)?;
            *values = self
                .bytes
                .chunks_exact(F64_BYTES)
                .map(|b| f64::from_le_bytes(b.try_into().expect("chunks of eight bytes")))
                .collect();
        }
        Ok(record)
    }
}

impl Iterator for SpilledParts {
    type Item = Result<Vec<Record>, SpillError>;

    fn next(&mut self) -> Option<Self::Item> {
        let mut part = Vec::new();
        let mut samples = 0;
        while let Some((_, len)) = self.records.as_slice().first() {
            if !part.is_empty() && samples + len > self.part_samples {
                break;
            }
            let (record, len) = self.records.next().expect("a first record");
            samples += len;
            match self.read_record(record, len) {
                Ok(r) => part.push(r),
                Err(e) => {
                    // A read that failed leaves the file's position unknown: nothing after it.
                    self.records = Vec::new().into_iter();
                    return Some(Err(e));
                }
            }
        }
        (!part.is_empty()).then_some(Ok(part))
    }
}

fn spill_error(source: std::io::Error) -> SpillError {
    SpillError {
        dir: std::env::temp_dir(),
        source,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use forcemap_math::record::{Channel, Excitation};

    fn record(step: usize, len: usize, channels: &[Channel]) -> Record {
        Record {
            step,
            excitation: if step.is_multiple_of(2) {
                Excitation::UNKNOWN
            } else {
                Excitation::Sine {
                    frequency_hz: 1.5,
                    amplitude: 2e-3,
                }
            },
            sample_rate_hz: 100.0 + step as f64,
            start_time_s: step as f64 * 0.37,
            channels: channels
                .iter()
                .enumerate()
                .map(|(k, &c)| {
                    let values = (0..len)
                        .map(|i| {
                            // Every bit pattern class: subnormals, signed zeros, NaN, infinities.
                            match (i + k + step) % 7 {
                                0 => f64::MIN_POSITIVE / 3.0,
                                1 => -0.0,
                                2 => f64::NAN,
                                3 => f64::NEG_INFINITY,
                                _ => (i as f64 * 0.1 + k as f64).sin() * 1e-4,
                            }
                        })
                        .collect();
                    (c, values)
                })
                .collect(),
        }
    }

    /// A record as its step, its other fields' text and its channels' bits.
    type Bits = (usize, String, Vec<(Channel, Vec<u64>)>);

    fn bits(records: &[Record]) -> Vec<Bits> {
        records
            .iter()
            .map(|r| {
                (
                    r.step,
                    format!("{:?} {} {}", r.excitation, r.sample_rate_hz, r.start_time_s),
                    r.channels
                        .iter()
                        .map(|(c, v)| (*c, v.iter().map(|x| x.to_bits()).collect()))
                        .collect(),
                )
            })
            .collect()
    }

    #[test]
    fn records_read_back_bit_for_bit_in_order_in_bounded_parts() {
        let rig = [
            Channel::BaseDisplacementM,
            Channel::RelativeDisplacementM,
            Channel::MassAccelerationMps2,
        ];
        let lens = [5, 0, 130, 1, 64, 64, 200, 3];
        let records: Vec<Record> = lens
            .iter()
            .enumerate()
            .map(|(s, &n)| record(s, n, if s == 3 { &rig[..1] } else { &rig }))
            .collect();
        for part_samples in [1, 64, 128, 129, 1000, usize::MAX] {
            let mut spill = SpilledRecords::new();
            for r in &records {
                spill.push(r.clone()).unwrap();
            }
            assert_eq!(spill.len(), records.len());
            let parts: Vec<Vec<Record>> = spill
                .into_parts(part_samples)
                .unwrap()
                .map(Result::unwrap)
                .collect();
            for p in &parts {
                let samples: usize = p.iter().map(Record::len).sum();
                assert!(!p.is_empty());
                assert!(p.len() == 1 || samples <= part_samples, "{part_samples}");
            }
            let back: Vec<Record> = parts.into_iter().flatten().collect();
            assert_eq!(bits(&back), bits(&records), "parts of {part_samples}");
        }
    }

    #[test]
    fn an_empty_store_reads_back_nothing() {
        let spill = SpilledRecords::new();
        assert!(spill.is_empty());
        assert_eq!(spill.into_parts(10).unwrap().count(), 0);
    }
}
