//! Stage marks on the path from a step's last sample to its theta, for `forcemap bench graph
//! --trace`: where the milliseconds go (DDS hops, the step's assembly, the analysis, the
//! solve, the publishes).
//!
//! Off unless the environment variable [`ENV`] is set when the node starts; then a node records
//! each stage of a step ([`mark`]: wall-clock time, which is one clock for every process of a
//! host, and optionally the CPU time of the stage's own work on its thread) into a buffer, and
//! writes the buffer to its log ([`flush`]) once the step's message is out, so that the log
//! line's write is not part of what is measured. One line per mark, parsed back by
//! [`TraceMark::parse`].

use std::sync::{Mutex, OnceLock};

/// Set (to anything) to trace a node's stages.
pub const ENV: &str = "FORCEMAP_LATENCY_TRACE";
/// What a trace line starts with.
pub const PREFIX: &str = "latency-trace";

/// One stage of one step.
#[derive(Debug, Clone, PartialEq)]
pub struct TraceMark {
    /// `node.stage`, e.g. `harmonic.step_complete`.
    pub stage: String,
    pub step: u32,
    /// When the stage ended [ns since the Unix epoch].
    pub wall_ns: i64,
    /// CPU time of the stage's own work on its thread [ns], where it is measured.
    pub cpu_ns: Option<i64>,
}

impl TraceMark {
    /// The log line of the mark.
    pub fn line(&self) -> String {
        let mut s = format!(
            "{PREFIX} stage={} step={} wall_ns={}",
            self.stage, self.step, self.wall_ns
        );
        if let Some(c) = self.cpu_ns {
            s.push_str(&format!(" cpu_ns={c}"));
        }
        s
    }

    /// The mark of a log line written by [`TraceMark::line`] (`None` for any other line).
    pub fn parse(line: &str) -> Option<TraceMark> {
        let rest = line.trim().strip_prefix(PREFIX)?;
        let mut mark = TraceMark {
            stage: String::new(),
            step: 0,
            wall_ns: 0,
            cpu_ns: None,
        };
        let (mut step, mut wall) = (None, None);
        for field in rest.split_whitespace() {
            let (key, value) = field.split_once('=')?;
            match key {
                "stage" => mark.stage = value.to_string(),
                "step" => step = value.parse().ok(),
                "wall_ns" => wall = value.parse().ok(),
                "cpu_ns" => mark.cpu_ns = Some(value.parse().ok()?),
                _ => return None,
            }
        }
        mark.step = step?;
        mark.wall_ns = wall?;
        (!mark.stage.is_empty()).then_some(mark)
    }
}

/// Whether this process traces (read once).
pub fn enabled() -> bool {
    static ON: OnceLock<bool> = OnceLock::new();
    *ON.get_or_init(|| std::env::var_os(ENV).is_some())
}

/// The wall-clock time [ns since the Unix epoch], as the marks carry it.
pub fn wall_ns() -> i64 {
    crate::ros::now_time().as_nanos()
}

/// CPU time of the calling thread [ns].
pub fn thread_cpu_ns() -> i64 {
    let mut t = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `t` is a valid timespec for the call to fill.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut t) };
    if rc != 0 {
        return 0;
    }
    t.tv_sec * 1_000_000_000 + t.tv_nsec
}

fn pending() -> &'static Mutex<Vec<TraceMark>> {
    static PENDING: OnceLock<Mutex<Vec<TraceMark>>> = OnceLock::new();
    PENDING.get_or_init(|| Mutex::new(Vec::new()))
}

/// Records that `stage` of `step` ended at `wall_ns`, its own work having taken `cpu_ns` on
/// its thread (nothing when tracing is off).
pub fn mark(stage: &str, step: u32, wall_ns: i64, cpu_ns: Option<i64>) {
    if !enabled() {
        return;
    }
    pending()
        .lock()
        .expect("trace buffer lock")
        .push(TraceMark {
            stage: stage.to_string(),
            step,
            wall_ns,
            cpu_ns,
        });
}

/// [`mark`] at the current time.
pub fn mark_now(stage: &str, step: u32, cpu_ns: Option<i64>) {
    if enabled() {
        mark(stage, step, wall_ns(), cpu_ns);
    }
}

/// Writes the recorded marks to the node's log.
pub fn flush() {
    if !enabled() {
        return;
    }
    let marks = std::mem::take(&mut *pending().lock().expect("trace buffer lock"));
    for m in marks {
        crate::log_line!("{}", m.line());
    }
}

/// Measures the CPU time `f` takes on the calling thread when tracing (`None` when not).
pub fn cpu_of<T>(f: impl FnOnce() -> T) -> (T, Option<i64>) {
    if !enabled() {
        return (f(), None);
    }
    let c0 = thread_cpu_ns();
    let out = f();
    (out, Some(thread_cpu_ns() - c0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mark_reads_back_from_its_line_and_other_lines_are_not_marks() {
        let m = TraceMark {
            stage: "identifier.solved".into(),
            step: 7,
            wall_ns: 1_764_000_000_123_456_789,
            cpu_ns: Some(52_000),
        };
        assert_eq!(TraceMark::parse(&m.line()), Some(m.clone()));
        let no_cpu = TraceMark { cpu_ns: None, ..m };
        assert_eq!(TraceMark::parse(&no_cpu.line()), Some(no_cpu.clone()));
        assert_eq!(
            TraceMark::parse("step 7: 1.600 Hz, 20 settled periods"),
            None
        );
        assert_eq!(
            TraceMark::parse("latency-trace stage=x step=seven wall_ns=1"),
            None
        );
        assert_eq!(TraceMark::parse("latency-trace stage=x wall_ns=1"), None);
    }

    #[test]
    fn thread_cpu_time_grows_with_work_on_the_thread() {
        let c0 = thread_cpu_ns();
        let mut x = 0u64;
        for i in 0..20_000_000u64 {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(i);
        }
        std::hint::black_box(x);
        assert!(thread_cpu_ns() > c0);
    }
}
