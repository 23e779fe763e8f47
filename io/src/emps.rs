//! Importer of the EMPS benchmark (Janot, Gautier, Brunot 2019): an electro-mechanical
//! prismatic drive with viscous and Coulomb friction, sampled at 1 kHz, published as MATLAB v5
//! files (`DATA_EMPS.mat` for fitting, `DATA_EMPS_PULSES.mat` for validation).
//!
//! Variables read (each a real double array; the vectors of equal length N, n x 1 or 1 x n):
//! `t` [s], `qm` (measured position [m]), `qg` (reference position [m]), `vir` (drive input:
//! the amplifier's current reference [V]), `gtau` (drive gain [N/V], force = gtau * vir),
//! `kp`, `kv` (gains of the position and velocity loops, stored as in the file). Other numeric
//! variables (`pulses_N` in `DATA_EMPS_PULSES.mat`) are kept in [`EmpsData::extra`].
//!
//! The bag (see [`write_emps_bag`]) has two topics:
//! - `/emps/axis` (`forcemap_msgs/msg/AxisSample`): one message per sample, stamp = [`EPOCH_NS`]
//!   + t, frame_id `emps`; velocity and acceleration are NaN (not measured);
//! - `/emps/parameters` (`diagnostic_msgs/msg/DiagnosticStatus`, QoS transient local depth 1,
//!   so a late subscriber still gets it): one message at the first sample's time whose
//!   key-value pairs hold gtau, kp, kv (shortest round-trip decimal text, so the f64 values
//!   are exact), their units, the source file name, the epoch, and every extra variable's
//!   values (`pulses_N` as a run-length list `value*count,...`, exact and short).
//!
//! The bag writer's metadata.yaml has no custom_data support (it always writes `{}`), which is
//! why the gains travel on a latched topic.
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use forcemap_msgs::RosMessage;
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::{DiagnosticStatus, KeyValue};
use forcemap_msgs::msg::AxisSample;
use forcemap_msgs::std_msgs::Header;

use crate::bag::{BagError, BagWriter, QosProfile, TopicSpec};
use forcemap_math::diagnose::time_domain::{
    AxisBaseline, AxisModelFit, AxisRecord, TimeDomainOptions, fit_axis_model,
};

/// The epoch the sample times `t` are added to: 2018-11-06T00:00:00Z, the day the published
/// files were written (their MAT headers say so). Fixed, so that an import is reproducible.
pub const EPOCH_NS: u64 = 1_541_462_400_000_000_000;
/// Topic of the samples.
pub const AXIS_TOPIC: &str = "/emps/axis";
/// Topic of the gains (latched).
pub const PARAMETERS_TOPIC: &str = "/emps/parameters";
/// `header.frame_id` of the samples.
pub const FRAME_ID: &str = "emps";
/// Unit of `vir` (the drive input) and of gtau.
pub const DRIVE_INPUT_UNIT: &str = "V";
pub const GTAU_UNIT: &str = "N/V";

/// The per-sample vectors read from a file, in the order they are checked.
const VECTORS: [&str; 4] = ["t", "qm", "qg", "vir"];
const SCALARS: [&str; 3] = ["gtau", "kp", "kv"];

/// One EMPS record.
#[derive(Debug, Clone, PartialEq)]
pub struct EmpsData {
    /// The file it was read from.
    pub source: PathBuf,
    /// `t` [s].
    pub time_s: Vec<f64>,
    /// `qm`, measured position [m].
    pub position_m: Vec<f64>,
    /// `qg`, reference position [m].
    pub reference_m: Vec<f64>,
    /// `vir`, drive input [V].
    pub drive_input: Vec<f64>,
    /// gtau * vir [N].
    pub force_n: Vec<f64>,
    /// Drive gain [N/V].
    pub gtau: f64,
    /// Position loop gain (as in the file).
    pub kp: f64,
    /// Velocity loop gain (as in the file).
    pub kv: f64,
    /// Other numeric variables of the file (name, values in MATLAB column-major order), e.g.
    /// `pulses_N` of `DATA_EMPS_PULSES.mat`.
    pub extra: Vec<(String, Vec<f64>)>,
}

impl EmpsData {
    pub fn len(&self) -> usize {
        self.time_s.len()
    }

    pub fn is_empty(&self) -> bool {
        self.time_s.is_empty()
    }

    /// Mean sample rate [Hz] from the first and last time.
    pub fn sample_rate_hz(&self) -> f64 {
        let n = self.len();
        if n < 2 {
            return f64::NAN;
        }
        (n - 1) as f64 / (self.time_s[n - 1] - self.time_s[0])
    }

    /// The sample `i` as a message.
    pub fn sample(&self, i: usize) -> AxisSample {
        let stamp = Time::from_nanos(stamp_ns(self.time_s[i]) as i64);
        AxisSample {
            header: Header::new(stamp, FRAME_ID),
            position_m: self.position_m[i],
            velocity_mps: f64::NAN,
            acceleration_mps2: f64::NAN,
            reference_position_m: self.reference_m[i],
            force_n: self.force_n[i],
            drive_input: self.drive_input[i],
        }
    }

    /// The `/emps/parameters` message.
    pub fn parameters(&self) -> DiagnosticStatus {
        let file = self
            .source
            .file_name()
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_default();
        let mut s = DiagnosticStatus::new(
            DiagnosticStatus::OK,
            "emps/parameters",
            format!("EMPS benchmark constants from {file}"),
            FRAME_ID,
        )
        .with_value("gtau", self.gtau)
        .with_value("gtau_unit", GTAU_UNIT)
        .with_value("kp", self.kp)
        .with_value("kv", self.kv)
        .with_value("drive_input", "vir")
        .with_value("drive_input_unit", DRIVE_INPUT_UNIT)
        .with_value("force", "force_n = gtau * vir [N]")
        .with_value("source_file", file)
        .with_value("epoch_ns", EPOCH_NS)
        .with_value("samples", self.len());
        for (name, values) in &self.extra {
            s.values
                .push(KeyValue::new(name.clone(), run_length(values)));
        }
        s
    }
}

/// Stamp [ns since the Unix epoch] of a sample time `t` [s].
pub fn stamp_ns(t: f64) -> u64 {
    (EPOCH_NS as i128 + (t * 1e9).round() as i128).clamp(0, u64::MAX as i128) as u64
}

/// Exact text of a vector: runs `value*count` (count omitted when 1) separated by commas, each
/// value in Rust's shortest round-trip form.
pub fn run_length(values: &[f64]) -> String {
    let mut out = String::new();
    let mut i = 0;
    while i < values.len() {
        let v = values[i];
        let mut j = i + 1;
        while j < values.len() && values[j].to_bits() == v.to_bits() {
            j += 1;
        }
        if !out.is_empty() {
            out.push(',');
        }
        let _ = write!(out, "{v:?}");
        if j - i > 1 {
            let _ = write!(out, "*{}", j - i);
        }
        i = j;
    }
    out
}

/// Inverse of [`run_length`].
pub fn parse_run_length(text: &str) -> Option<Vec<f64>> {
    let mut out = Vec::new();
    if text.is_empty() {
        return Some(out);
    }
    for run in text.split(',') {
        let (v, n) = match run.split_once('*') {
            Some((v, n)) => (v, n.parse::<usize>().ok()?),
            None => (run, 1),
        };
        let v: f64 = v.parse().ok()?;
        out.extend(std::iter::repeat_n(v, n));
    }
    Some(out)
}

/// What can go wrong importing an EMPS file.
#[derive(Debug, thiserror::Error)]
pub enum EmpsError {
    #[error("{}: cannot read: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: not a readable MATLAB v5 .mat file: {detail}", path.display())]
    Parse { path: PathBuf, detail: String },
    #[error(
        "{}: variable '{variable}' is missing (or is not a numeric array); the file has: {}",
        path.display(),
        if present.is_empty() { "no numeric variables".to_string() } else { present.join(", ") }
    )]
    Missing {
        path: PathBuf,
        variable: String,
        present: Vec<String>,
    },
    #[error("{}: variable '{variable}' is {class}, expected real double", path.display())]
    WrongClass {
        path: PathBuf,
        variable: String,
        class: String,
    },
    #[error("{}: variable '{variable}' has shape {shape:?}, expected {expected}", path.display())]
    WrongShape {
        path: PathBuf,
        variable: String,
        shape: Vec<usize>,
        expected: String,
    },
    #[error(
        "{}: variable '{variable}' holds {value} at index {index} (1-based, as in MATLAB); \
         expected finite values",
        path.display(),
        index = index + 1
    )]
    NonFinite {
        path: PathBuf,
        variable: String,
        index: usize,
        value: f64,
    },
    #[error(
        "{}: variable 't' does not increase at index {index} (1-based): {prev} then {next}",
        path.display(),
        index = index + 1
    )]
    TimeNotIncreasing {
        path: PathBuf,
        index: usize,
        prev: f64,
        next: f64,
    },
    #[error("{}: {detail}", path.display())]
    Fit { path: PathBuf, detail: String },
    #[error(transparent)]
    Bag(#[from] BagError),
}

fn class_name(d: &matfile::NumericData) -> &'static str {
    use matfile::NumericData as N;
    match d {
        N::Int8 { .. } => "int8",
        N::UInt8 { .. } => "uint8",
        N::Int16 { .. } => "int16",
        N::UInt16 { .. } => "uint16",
        N::Int32 { .. } => "int32",
        N::UInt32 { .. } => "uint32",
        N::Int64 { .. } => "int64",
        N::UInt64 { .. } => "uint64",
        N::Single { .. } => "single",
        N::Double { .. } => "double",
    }
}

/// The real double values of a variable, with its shape.
fn doubles(
    path: &Path,
    mat: &matfile::MatFile,
    name: &str,
) -> Result<(Vec<usize>, Vec<f64>), EmpsError> {
    let arr = mat.find_by_name(name).ok_or_else(|| EmpsError::Missing {
        path: path.to_path_buf(),
        variable: name.to_string(),
        present: mat.arrays().iter().map(|a| a.name().to_string()).collect(),
    })?;
    match arr.data() {
        matfile::NumericData::Double { real, imag: None } => {
            if let Some((index, &value)) = real.iter().enumerate().find(|(_, v)| !v.is_finite()) {
                return Err(EmpsError::NonFinite {
                    path: path.to_path_buf(),
                    variable: name.to_string(),
                    index,
                    value,
                });
            }
            Ok((arr.size().clone(), real.clone()))
        }
        matfile::NumericData::Double { imag: Some(_), .. } => Err(EmpsError::WrongClass {
            path: path.to_path_buf(),
            variable: name.to_string(),
            class: "complex double".into(),
        }),
        other => Err(EmpsError::WrongClass {
            path: path.to_path_buf(),
            variable: name.to_string(),
            class: class_name(other).into(),
        }),
    }
}

fn is_vector(shape: &[usize]) -> bool {
    shape.len() == 2 && (shape[0] == 1 || shape[1] == 1)
}

/// Reads an EMPS .mat file and checks it: every variable present, real double, finite; t, qm,
/// qg, vir vectors of one length (at least 2); gtau, kp, kv scalars; t strictly increasing.
pub fn read_emps(path: impl AsRef<Path>) -> Result<EmpsData, EmpsError> {
    let path = path.as_ref();
    let file = std::fs::File::open(path).map_err(|source| EmpsError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mat = matfile::MatFile::parse(std::io::BufReader::new(file)).map_err(|e| match e {
        matfile::Error::IOError(source) => EmpsError::Io {
            path: path.to_path_buf(),
            source,
        },
        other => EmpsError::Parse {
            path: path.to_path_buf(),
            detail: format!("{other} ({other:?})"),
        },
    })?;
    let mut vectors = Vec::new();
    let mut n = None;
    for name in VECTORS {
        let (shape, v) = doubles(path, &mat, name)?;
        let expected = match n {
            Some(len) => format!("{len} x 1 or 1 x {len} (the length of t)"),
            None => "a vector of at least 2 samples (n x 1 or 1 x n)".to_string(),
        };
        if !is_vector(&shape) || v.len() < 2 || n.is_some_and(|len| len != v.len()) {
            return Err(EmpsError::WrongShape {
                path: path.to_path_buf(),
                variable: name.to_string(),
                shape,
                expected,
            });
        }
        n = Some(v.len());
        vectors.push(v);
    }
    let mut scalars = Vec::new();
    for name in SCALARS {
        let (shape, v) = doubles(path, &mat, name)?;
        if v.len() != 1 {
            return Err(EmpsError::WrongShape {
                path: path.to_path_buf(),
                variable: name.to_string(),
                shape,
                expected: "1 x 1 (a scalar)".into(),
            });
        }
        scalars.push(v[0]);
    }
    let [time_s, position_m, reference_m, drive_input]: [Vec<f64>; 4] =
        vectors.try_into().expect("four vectors");
    if let Some(i) = time_s.windows(2).position(|w| w[1] <= w[0]) {
        return Err(EmpsError::TimeNotIncreasing {
            path: path.to_path_buf(),
            index: i + 1,
            prev: time_s[i],
            next: time_s[i + 1],
        });
    }
    let (gtau, kp, kv) = (scalars[0], scalars[1], scalars[2]);
    let force_n = drive_input.iter().map(|v| gtau * v).collect();
    let mut extra = Vec::new();
    for arr in mat.arrays() {
        let name = arr.name();
        if VECTORS.contains(&name) || SCALARS.contains(&name) {
            continue;
        }
        let (_, values) = doubles(path, &mat, name)?;
        extra.push((name.to_string(), values));
    }
    Ok(EmpsData {
        source: path.to_path_buf(),
        time_s,
        position_m,
        reference_m,
        drive_input,
        force_n,
        gtau,
        kp,
        kv,
        extra,
    })
}

/// The `/emps/axis` topic.
pub fn axis_topic() -> TopicSpec {
    TopicSpec::new(AXIS_TOPIC, AxisSample::TYPE_NAME, &AxisSample::schema())
}

/// The `/emps/parameters` topic (transient local, depth 1: latched).
pub fn parameters_topic() -> TopicSpec {
    let mut spec = TopicSpec::new(
        PARAMETERS_TOPIC,
        DiagnosticStatus::TYPE_NAME,
        &DiagnosticStatus::schema(),
    );
    spec.offered_qos_profiles = QosProfile {
        depth: 1,
        reliable: true,
        transient_local: true,
    }
    .to_yaml_string();
    spec
}

/// Writes the bag directory `out_dir` (which must not exist; written atomically, nothing is
/// left on error): the parameters message, then one AxisSample per sample. Returns the bag
/// directory.
pub fn write_emps_bag(data: &EmpsData, out_dir: impl AsRef<Path>) -> Result<PathBuf, EmpsError> {
    let mut w = BagWriter::create(out_dir)?;
    let axis = w.add_topic(&axis_topic())?;
    let params = w.add_topic(&parameters_topic())?;
    let t0 = stamp_ns(data.time_s.first().copied().unwrap_or(0.0));
    w.write(params, t0, t0, &data.parameters().to_cdr())?;
    for i in 0..data.len() {
        let msg = data.sample(i);
        let ns = msg.header.stamp.as_nanos() as u64;
        w.write(axis, ns, ns, &msg.to_cdr())?;
    }
    Ok(w.finish()?)
}

/// What [`import_emps`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportSummary {
    pub source: PathBuf,
    pub bag: PathBuf,
    /// Messages on `/emps/axis` (= the length of t).
    pub samples: u64,
    /// Messages on `/emps/parameters` (1).
    pub parameter_messages: u64,
    /// Extra variables kept in the parameters message (e.g. `pulses_N`).
    pub extra_variables: Vec<String>,
    pub duration_s: f64,
    pub sample_rate_hz: f64,
    pub gtau: f64,
    pub kp: f64,
    pub kv: f64,
}

/// Reads `mat` and writes the bag `out`.
pub fn import_emps(mat: &Path, out: &Path) -> anyhow::Result<ImportSummary> {
    let data = read_emps(mat)?;
    let bag = write_emps_bag(&data, out)?;
    Ok(ImportSummary {
        source: mat.to_path_buf(),
        bag,
        samples: data.len() as u64,
        parameter_messages: 1,
        extra_variables: data.extra.iter().map(|(n, _)| n.clone()).collect(),
        duration_s: data.time_s[data.len() - 1] - data.time_s[0],
        sample_rate_hz: data.sample_rate_hz(),
        gtau: data.gtau,
        kp: data.kp,
        kv: data.kv,
    })
}

/// Options of [`fit_reference_model`]: the preprocessing of the time-domain diagnosis, the
/// one implementation of the published procedure (position low-passed without phase shift,
/// central differences, parallel decimation; see `forcemap_math::diagnose::time_domain`).
pub type FitOptions = TimeDomainOptions;

/// The reference model tau = M q'' + Fv q' + Fc sgn(q') + offset fitted by least squares.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceFit {
    pub mass_kg: f64,
    pub fv_ns_per_m: f64,
    pub fc_n: f64,
    pub offset_n: f64,
    /// Standard deviations (least-squares, white residual assumed), same order.
    pub std: [f64; 4],
    /// 100 |tau - W theta| / |tau| on the decimated data [%].
    pub relative_error_percent: f64,
    pub equations: usize,
    pub options: FitOptions,
}

impl ReferenceFit {
    pub fn theta(&self) -> [f64; 4] {
        [self.mass_kg, self.fv_ns_per_m, self.fc_n, self.offset_n]
    }

    /// 100 |tau - W theta| / |tau| of these parameters on other data, prepared the same way.
    pub fn relative_error_on(&self, data: &EmpsData) -> Result<f64, EmpsError> {
        let fit = AxisModelFit::new(
            AxisBaseline::EmpsCoulomb,
            self.theta().to_vec(),
            &self.options,
        );
        fit.relative_error_on(&axis_record(data))
            .map_err(|e| EmpsError::Fit {
                path: data.source.clone(),
                detail: e.to_string(),
            })
    }
}

/// The record as the time-domain path takes it.
pub fn axis_record(data: &EmpsData) -> AxisRecord {
    AxisRecord {
        sample_rate_hz: data.sample_rate_hz(),
        position_m: data.position_m.clone(),
        force_n: data.force_n.clone(),
    }
}

/// Fits tau = M q'' + Fv q' + Fc sgn(q') + offset on a record (see [`FitOptions`]).
pub fn fit_reference_model(data: &EmpsData, opts: &FitOptions) -> Result<ReferenceFit, EmpsError> {
    let fit = fit_axis_model(AxisBaseline::EmpsCoulomb, &axis_record(data), opts).map_err(|e| {
        EmpsError::Fit {
            path: data.source.clone(),
            detail: e.to_string(),
        }
    })?;
    let [m, fv, fc, offset]: [f64; 4] =
        fit.theta.clone().try_into().map_err(|_| EmpsError::Fit {
            path: data.source.clone(),
            detail: format!("expected 4 parameters, got {:?}", fit.names),
        })?;
    Ok(ReferenceFit {
        mass_kg: m,
        fv_ns_per_m: fv,
        fc_n: fc,
        offset_n: offset,
        std: std::array::from_fn(|j| fit.std[j]),
        relative_error_percent: fit.relative_error_percent,
        equations: fit.equations,
        options: *opts,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn run_length_round_trip() {
        let v = [0.0, 0.0, 5.0, 5.0, 5.0, 0.1, -2.5e-7, -2.5e-7];
        let s = run_length(&v);
        assert_eq!(s, "0.0*2,5.0*3,0.1,-2.5e-7*2");
        assert_eq!(parse_run_length(&s).unwrap(), v);
        assert_eq!(parse_run_length("").unwrap(), Vec::<f64>::new());
    }
}
