//! Writing records in the CSV contract, atomically.

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use forcemap_math::recipe::SetupKind;
use forcemap_math::record::{Channel, Excitation, Record};

use super::contract::{FREQUENCY_COLUMN, STEP_COLUMN, TIME_COLUMN};
use super::error::{CsvError, csv_error};
use super::multisine::{MULTISINE_COLUMNS, format_lines, lines_fault};
use super::sweep::{SWEEP_COLUMNS, law_name};

/// Writes `records` in the CSV contract of this module for `profile`, atomically.
///
/// Columns: `time_s, step, frequency_hz`, then `multisine_base_hz, multisine_lines` when a
/// record is a periodic multisine (0 and empty on the other records), `sweep_law,
/// sweep_start_hz, sweep_end_hz` when a record is a sweep (empty and 0 on the others; the
/// record must be the whole sweep, from phase 0), then every channel of the records in
/// [`Channel::ALL`] order. Time of sample `i` is [`Record::time_s`]; random records write
/// frequency `0`. Numbers use Rust's shortest round-trip formatting, so reading the file back
/// gives the same f64 values bit for bit.
///
/// Everything is checked before the file system is touched (all records with the same
/// channels, the profile's channels present, at least 3 finite samples per channel, a
/// positive sample rate (each record its own), contiguous steps, increasing time, sine frequencies finite and
/// positive, multisine base frequencies positive with ascending lines). The data
/// go to a temporary file in the target directory which is renamed over `path` at the end; on
/// any error the temporary file is removed and `path` is untouched.
pub fn write_csv(
    path: impl AsRef<Path>,
    records: &[Record],
    profile: SetupKind,
) -> Result<(), CsvError> {
    let path = path.as_ref();
    let channels = validate_for_write(path, records, profile)?;

    let mut tmp = TempFile::create(path)?;
    let io_err = |source: io::Error| CsvError::Io {
        path: path.to_path_buf(),
        action: "cannot write",
        source,
    };
    {
        let file = tmp.file.take().expect("temporary file is open");
        let mut wtr = csv::WriterBuilder::new().from_writer(BufWriter::new(file));
        // The multisine columns only when a record is a multisine: other exports stay as they
        // were.
        let multisine = records
            .iter()
            .any(|r| matches!(r.excitation, Excitation::Multisine { .. }));
        let mut header = vec![TIME_COLUMN, STEP_COLUMN, FREQUENCY_COLUMN];
        if multisine {
            header.extend(MULTISINE_COLUMNS);
        }
        let sweep = records
            .iter()
            .any(|r| matches!(r.excitation, Excitation::Sweep { .. }));
        if sweep {
            header.extend(SWEEP_COLUMNS);
        }
        header.extend(channels.iter().map(|c| c.name()));
        wtr.write_record(&header).map_err(|e| csv_error(path, e))?;
        let mut fields: Vec<String> = Vec::with_capacity(header.len());
        for r in records {
            let step = r.step.to_string();
            let freq = match r.excitation {
                Excitation::Sine { frequency_hz, .. } => fmt_f64(frequency_hz),
                Excitation::Random { .. }
                | Excitation::Multisine { .. }
                | Excitation::Sweep { .. } => "0".to_string(),
            };
            let sweep_cells = match &r.excitation {
                Excitation::Sweep { law } => [
                    law_name(law.kind).to_string(),
                    fmt_f64(law.start_frequency_hz),
                    fmt_f64(law.end_frequency_hz),
                ],
                _ => [String::new(), "0".to_string(), "0".to_string()],
            };
            let (base, lines) = match &r.excitation {
                Excitation::Multisine {
                    base_frequency_hz,
                    lines,
                    ..
                } => (fmt_f64(*base_frequency_hz), format_lines(lines)),
                _ => ("0".to_string(), String::new()),
            };
            let samples: Vec<&[f64]> = channels
                .iter()
                .map(|&c| r.channel(c).expect("validated"))
                .collect();
            for i in 0..r.len() {
                fields.clear();
                fields.push(fmt_f64(r.time_s(i)));
                fields.push(step.clone());
                fields.push(freq.clone());
                if multisine {
                    fields.push(base.clone());
                    fields.push(lines.clone());
                }
                if sweep {
                    fields.extend(sweep_cells.iter().cloned());
                }
                fields.extend(samples.iter().map(|x| fmt_f64(x[i])));
                wtr.write_record(&fields).map_err(|e| csv_error(path, e))?;
            }
        }
        let buf = wtr
            .into_inner()
            .map_err(|e| io_err(io::Error::other(e.to_string())))?;
        let file = buf.into_inner().map_err(|e| io_err(e.into_error()))?;
        file.sync_all().map_err(io_err)?;
    }
    tmp.persist()
}

/// Channels to write, in [`Channel::ALL`] order, after checking the records.
fn validate_for_write(
    path: &Path,
    records: &[Record],
    profile: SetupKind,
) -> Result<Vec<Channel>, CsvError> {
    let bad = |reason: String| CsvError::InvalidRecords {
        path: path.to_path_buf(),
        reason,
    };
    let Some(first) = records.first() else {
        return Err(bad("there are no records".into()));
    };
    let channels: Vec<Channel> = Channel::ALL
        .into_iter()
        .filter(|&c| first.channel(c).is_some())
        .collect();
    for &c in profile.required_channels() {
        if !channels.contains(&c) {
            return Err(bad(format!(
                "the {profile} profile requires channel '{}', which record 0 (step {}) lacks",
                c.name(),
                first.step
            )));
        }
    }
    if profile == SetupKind::DrivePoint && channels.contains(&Channel::BaseDisplacementM) {
        return Err(bad(format!(
            "the records carry '{}', which would make the file read back as the rig profile; \
             write them with the rig profile or drop that channel",
            Channel::BaseDisplacementM.name()
        )));
    }
    let mut prev_time: Option<f64> = None;
    for (k, r) in records.iter().enumerate() {
        let what = format!("record {k} (step {})", r.step);
        if r.step != first.step + k {
            return Err(bad(format!(
                "{what}: steps must be contiguous, expected step {}",
                first.step + k
            )));
        }
        let mut seen: Vec<Channel> = r.channels.iter().map(|(c, _)| *c).collect();
        seen.sort();
        if seen.windows(2).any(|w| w[0] == w[1]) {
            return Err(bad(format!("{what}: a channel appears twice")));
        }
        if seen != channels {
            let names = |v: &[Channel]| v.iter().map(|c| c.name()).collect::<Vec<_>>().join(", ");
            return Err(bad(format!(
                "{what} has channels [{}] but record 0 has [{}]; all records must have the same \
                 channels",
                names(&seen),
                names(&channels)
            )));
        }
        let n = r.len();
        if n < 3 {
            return Err(bad(format!(
                "{what} has {n} sample(s); at least 3 are required"
            )));
        }
        for (c, x) in &r.channels {
            if x.len() != n {
                return Err(bad(format!(
                    "{what}: channel '{}' has {} samples but '{}' has {n}",
                    c.name(),
                    x.len(),
                    r.channels[0].0.name()
                )));
            }
        }
        for &c in &channels {
            let x = r.channel(c).expect("present");
            if let Some(i) = x.iter().position(|v| !v.is_finite()) {
                return Err(CsvError::NonFiniteSample {
                    path: path.to_path_buf(),
                    record: k,
                    step: r.step,
                    channel: c,
                    index: i,
                    value: x[i],
                });
            }
        }
        if !(r.sample_rate_hz.is_finite() && r.sample_rate_hz > 0.0) {
            return Err(bad(format!(
                "{what}: sample rate {} Hz is not a positive number",
                r.sample_rate_hz
            )));
        }
        if !r.start_time_s.is_finite() {
            return Err(bad(format!(
                "{what}: start time {} is not finite",
                r.start_time_s
            )));
        }
        match r.excitation {
            Excitation::Sine { frequency_hz, .. } => {
                if !(frequency_hz.is_finite() && frequency_hz > 0.0) {
                    return Err(bad(format!(
                        "{what}: sine frequency {frequency_hz} Hz is not a positive number"
                    )));
                }
            }
            Excitation::Random { .. } => {}
            Excitation::Sweep { law } => {
                let ok = |f: f64| f.is_finite() && f > 0.0;
                let rate = r.sample_rate_hz;
                let duration = n as f64 / rate;
                if !(ok(law.start_frequency_hz) && ok(law.end_frequency_hz)) {
                    return Err(bad(format!(
                        "{what}: sweep {} -> {} Hz: frequencies must be positive numbers",
                        law.start_frequency_hz, law.end_frequency_hz
                    )));
                }
                // The contract's sweep lasts its record: a law of another duration would read
                // back as a different sweep.
                if (law.duration_s - duration).abs() > 0.5 / rate {
                    return Err(bad(format!(
                        "{what}: the sweep lasts {} s but the record {duration} s; the CSV \
                         contract's sweep is the whole record",
                        law.duration_s
                    )));
                }
            }
            Excitation::Multisine {
                base_frequency_hz,
                ref lines,
                ..
            } => {
                if !(base_frequency_hz.is_finite() && base_frequency_hz > 0.0) {
                    return Err(bad(format!(
                        "{what}: multisine base frequency {base_frequency_hz} Hz is not a \
                         positive number"
                    )));
                }
                if let Some(reason) = lines_fault(lines) {
                    return Err(bad(format!("{what}: multisine lines {lines:?}: {reason}")));
                }
            }
        }
        for i in 0..n {
            let t = r.time_s(i);
            if let Some(t0) = prev_time
                && t <= t0
            {
                return Err(bad(format!(
                    "{what}: time of sample {i} ({t} s) does not increase (previous sample at \
                     {t0} s)"
                )));
            }
            prev_time = Some(t);
        }
    }
    Ok(channels)
}

/// Shortest round-trip formatting; exponent form for very large or small magnitudes to keep
/// cells short. Both forms parse back to the identical f64.
pub(crate) fn fmt_f64(v: f64) -> String {
    let mut s = String::new();
    write_f64(&mut s, v);
    s
}

/// [`fmt_f64`] appended to `out`.
pub(crate) fn write_f64(out: &mut String, v: f64) {
    use std::fmt::Write;
    let a = v.abs();
    let _ = if a == 0.0 || (1e-5..1e16).contains(&a) {
        write!(out, "{v}")
    } else {
        write!(out, "{v:e}")
    };
}

/// A temporary file next to the target, removed on drop unless persisted.
struct TempFile {
    tmp_path: PathBuf,
    target: PathBuf,
    file: Option<File>,
    persisted: bool,
}

impl TempFile {
    fn create(target: &Path) -> Result<TempFile, CsvError> {
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        let dir = match target.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let name = target
            .file_name()
            .map_or_else(|| "export.csv".into(), |n| n.to_string_lossy().into_owned());
        let mut attempt = 0;
        loop {
            let tmp_path = dir.join(format!(
                ".{name}.{}.{}.tmp",
                std::process::id(),
                COUNTER.fetch_add(1, Ordering::Relaxed)
            ));
            match OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&tmp_path)
            {
                Ok(file) => {
                    return Ok(TempFile {
                        tmp_path,
                        target: target.to_path_buf(),
                        file: Some(file),
                        persisted: false,
                    });
                }
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists && attempt < 100 => {
                    attempt += 1;
                }
                Err(source) => {
                    return Err(CsvError::Io {
                        path: target.to_path_buf(),
                        action: "cannot create a temporary file in the target directory",
                        source,
                    });
                }
            }
        }
    }

    fn persist(mut self) -> Result<(), CsvError> {
        fs::rename(&self.tmp_path, &self.target).map_err(|source| CsvError::Io {
            path: self.target.clone(),
            action: "cannot rename the temporary file onto the target",
            source,
        })?;
        self.persisted = true;
        // Make the rename durable where the platform allows it; failure here is harmless.
        if let Some(dir) = self.target.parent()
            && let Ok(d) = File::open(if dir.as_os_str().is_empty() {
                Path::new(".")
            } else {
                dir
            })
        {
            let _ = d.sync_all();
        }
        Ok(())
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        if !self.persisted {
            drop(self.file.take());
            let _ = fs::remove_file(&self.tmp_path);
        }
    }
}
