//! Force-driven axis records (a drive's position and force over time, as the EMPS benchmark
//! measures them), from whichever form holds them: the MATLAB file of the benchmark or a bag
//! with `forcemap_msgs/msg/AxisSample` messages (what `forcemap import emps` writes, or a
//! recording of a live axis). What the data are decides how they are analysed, not the name
//! of the file.

use std::path::Path;

use anyhow::{Context as _, bail};
use forcemap_math::diagnose::time_domain::AxisRecord;
use forcemap_msgs::RosMessage;
use forcemap_msgs::msg::AxisSample;

use crate::bag::BagReader;
use crate::emps::{axis_record, read_emps};

/// The first bytes of a MATLAB 5 MAT-file.
const MAT5_MAGIC: &[u8] = b"MATLAB 5.0 MAT-file";

/// True when `path` is a MATLAB 5 MAT-file (by its header, whatever its name).
pub fn is_mat_file(path: &Path) -> bool {
    use std::io::Read as _;
    let mut head = [0u8; 19];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok_and(|()| head == MAT5_MAGIC)
}

/// The axis topic of a bag: the one topic of type `AxisSample`, if there is one.
pub fn axis_topic_of(reader: &BagReader) -> anyhow::Result<Option<String>> {
    let axis: Vec<&str> = reader
        .topics()
        .filter(|t| t.type_name == AxisSample::TYPE_NAME)
        .map(|t| t.name.as_str())
        .collect();
    match axis.as_slice() {
        [] => Ok(None),
        [one] => Ok(Some(one.to_string())),
        more => bail!(
            "the bag holds {} axis topics ({}): which one to analyse is ambiguous",
            more.len(),
            more.join(", ")
        ),
    }
}

/// The axis record of a MAT file (the EMPS benchmark's variables) or of a bag's axis topic.
pub fn read_axis(path: &Path) -> anyhow::Result<AxisRecord> {
    if is_mat_file(path) {
        with_sample_rate(axis_record(&read_emps(path)?), path)
    } else {
        read_axis_bag(&BagReader::open(path)?, path)
    }
}

/// `record`, refused when it has no sample rate.
fn with_sample_rate(record: AxisRecord, path: &Path) -> anyhow::Result<AxisRecord> {
    let fs = record.sample_rate_hz;
    if !(fs.is_finite() && fs > 0.0) {
        bail!(
            "{}: no sample rate (fewer than two samples or constant time)",
            path.display()
        );
    }
    Ok(record)
}

/// The axis record on a bag's `AxisSample` topic: position and force in log-time order, the
/// sample rate from the first and last stamps (as the EMPS file's from its first and last
/// times). `reader` is the bag at `path`.
pub fn read_axis_bag(reader: &BagReader, path: &Path) -> anyhow::Result<AxisRecord> {
    let topic = axis_topic_of(reader)
        .with_context(|| path.display().to_string())?
        .with_context(|| {
            format!(
                "{}: no topic of type {} (an axis record)",
                path.display(),
                AxisSample::TYPE_NAME
            )
        })?;
    let mut position_m = Vec::new();
    let mut force_n = Vec::new();
    let mut stamps_ns: Vec<i64> = Vec::new();
    for (i, m) in reader.messages_on(&[topic.as_str()])?.enumerate() {
        let m = m?;
        let s = AxisSample::from_cdr(&m.data)
            .with_context(|| format!("{}: {topic}, message {i}", path.display()))?;
        if !(s.position_m.is_finite() && s.force_n.is_finite()) {
            bail!(
                "{}: {topic}, message {i}: position {} m, force {} N: an axis record needs both measured",
                path.display(),
                s.position_m,
                s.force_n
            );
        }
        let t = s.header.stamp.as_nanos();
        if stamps_ns.last().is_some_and(|last| t <= *last) {
            bail!(
                "{}: {topic}, message {i}: its stamp does not come after the previous one",
                path.display()
            );
        }
        stamps_ns.push(t);
        position_m.push(s.position_m);
        force_n.push(s.force_n);
    }
    let n = stamps_ns.len();
    let sample_rate_hz = if n < 2 {
        f64::NAN
    } else {
        (n - 1) as f64 / ((stamps_ns[n - 1] - stamps_ns[0]) as f64 * 1e-9)
    };
    with_sample_rate(
        AxisRecord {
            sample_rate_hz,
            position_m,
            force_n,
        },
        path,
    )
}
