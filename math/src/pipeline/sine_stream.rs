//! Sine steps analysed as a long recording is read ([`SineStepStream`]): the steps are gathered
//! in batches and each batch is analysed on a thread of its own (its steps over the machine's
//! cores, [`analyse_sine_steps`]) while the reading goes on, so that the reading waits for the
//! analysis only when a batch is ready before the last one is done. The analyses and notes are
//! those of [`analyse_sine_steps`] over all the steps, in the steps' order.

use std::sync::mpsc::{SyncSender, sync_channel};
use std::thread::JoinHandle;

use super::{PipelineError, analyse_sine_steps};
use crate::parallel;
use crate::phasor::{HarmonicAnalysis, PhasorOptions};
use crate::record::Record;

/// The analyses and notes of the steps, or the first analysis that failed.
pub type Analysed = Result<(Vec<HarmonicAnalysis>, Vec<String>), PipelineError>;

/// Samples a batch holds per core: four parts of the least a part holds, so that the cores
/// share a batch evenly.
const BATCH_SAMPLES_PER_CORE: usize = 4 * parallel::PART_MIN_SAMPLES;

/// Sine steps handed over one at a time ([`SineStepStream::push`]) and analysed in batches on
/// a worker thread; [`SineStepStream::finish`] gives what [`analyse_sine_steps`] gives on all
/// of them. Memory: the batch being gathered, the one being analysed and one waiting.
pub struct SineStepStream {
    pending: Vec<Record>,
    samples: usize,
    batch_samples: usize,
    sender: Option<SyncSender<Vec<Record>>>,
    worker: Option<JoinHandle<Analysed>>,
}

impl SineStepStream {
    /// A stream analysed with `options`, in batches of about [`BATCH_SAMPLES_PER_CORE`]
    /// samples a core.
    pub fn new(options: PhasorOptions) -> SineStepStream {
        SineStepStream::with_batch_samples(options, BATCH_SAMPLES_PER_CORE * parallel::threads())
    }

    /// A stream analysed in batches of at least `batch_samples` samples.
    pub fn with_batch_samples(options: PhasorOptions, batch_samples: usize) -> SineStepStream {
        let (sender, batches) = sync_channel::<Vec<Record>>(1);
        let worker = std::thread::spawn(move || {
            let mut analysed: Analysed = Ok((Vec::new(), Vec::new()));
            // Every batch is received (the reader never waits on a worker that stopped), and
            // none is analysed after the first failure.
            for batch in batches {
                let Ok((analyses, notes)) = &mut analysed else {
                    continue;
                };
                match analyse_sine_steps(&batch, &options) {
                    Ok((a, n)) => {
                        analyses.extend(a);
                        notes.extend(n);
                    }
                    Err(e) => analysed = Err(e.into()),
                }
            }
            analysed
        });
        SineStepStream {
            pending: Vec::new(),
            samples: 0,
            batch_samples: batch_samples.max(1),
            sender: Some(sender),
            worker: Some(worker),
        }
    }

    /// The next sine step (a record that is no sine step is left out, as
    /// [`analyse_sine_steps`] leaves it).
    pub fn push(&mut self, step: Record) {
        self.samples += step.len();
        self.pending.push(step);
        if self.samples >= self.batch_samples {
            self.send();
        }
    }

    fn send(&mut self) {
        let batch = std::mem::take(&mut self.pending);
        self.samples = 0;
        if batch.is_empty() {
            return;
        }
        if let Some(sender) = &self.sender {
            // The worker receives until the sender is dropped; it cannot have gone.
            sender
                .send(batch)
                .unwrap_or_else(|_| unreachable!("the analysis thread receives every batch"));
        }
    }

    /// The analyses of every step pushed, in order, and their notes.
    pub fn finish(mut self) -> Analysed {
        self.send();
        drop(self.sender.take());
        let worker = self.worker.take().expect("the worker is joined once");
        // A panic of the analysis is this call's panic.
        worker
            .join()
            .unwrap_or_else(|e| std::panic::resume_unwind(e))
    }
}

impl Drop for SineStepStream {
    fn drop(&mut self) {
        // Not finished (the reading failed): the worker ends once its sender is gone.
        drop(self.sender.take());
        if let Some(worker) = self.worker.take() {
            let _ = worker.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phasor::PhasorOptions;
    use crate::record::Excitation;
    use crate::sim::RunSpec;

    #[test]
    fn streamed_analyses_are_those_of_all_the_steps_at_once() {
        let records = RunSpec::paper_rig(Some(40.0), 3).simulate().unwrap();
        let options = PhasorOptions::for_identification();
        let sines: Vec<Record> = records
            .iter()
            .filter(|r| matches!(r.excitation, Excitation::Sine { .. }))
            .cloned()
            .collect();
        let (all, all_notes) = analyse_sine_steps(&sines, &options).unwrap();
        assert!(all.len() >= 10);
        // Batches of one step, of a few and of all of them.
        for batch_samples in [1, 3000, usize::MAX] {
            let mut stream = SineStepStream::with_batch_samples(options.clone(), batch_samples);
            for r in &sines {
                stream.push(r.clone());
            }
            let (got, notes) = stream.finish().unwrap();
            assert_eq!(got, all, "batches of {batch_samples} samples");
            assert_eq!(notes, all_notes);
        }
    }

    #[test]
    fn the_first_failure_is_the_streams_and_an_unfinished_stream_ends_its_thread() {
        let records = RunSpec::paper_rig(Some(40.0), 3).simulate().unwrap();
        let options = PhasorOptions::for_identification();
        let mut sines: Vec<Record> = records
            .into_iter()
            .filter(|r| matches!(r.excitation, Excitation::Sine { .. }))
            .collect();
        // Steps 2 and 4 too short for an analysis: the error is step 2's.
        for k in [2, 4] {
            for (_, x) in &mut sines[k].channels {
                x.truncate(5);
            }
        }
        let expected = analyse_sine_steps(&sines, &options)
            .unwrap_err()
            .to_string();
        let mut stream = SineStepStream::with_batch_samples(options.clone(), 1);
        for r in &sines {
            stream.push(r.clone());
        }
        let got = stream.finish().unwrap_err().to_string();
        assert_eq!(got, expected);
        // Dropped before it is finished: no thread is left waiting.
        let mut stream = SineStepStream::with_batch_samples(options, 1);
        stream.push(sines[0].clone());
        drop(stream);
    }
}
