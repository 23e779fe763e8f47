//! Mirror of `builtin_interfaces`.

use serde::{Deserialize, Serialize};

use crate::{MsgDef, ros_message};

pub const TIME_DEF: MsgDef = MsgDef {
    name: "builtin_interfaces/Time",
    text: include_str!("../deps/builtin_interfaces/msg/Time.msg"),
    deps: &[],
};

const NANOS_PER_SEC: i64 = 1_000_000_000;

/// `builtin_interfaces/msg/Time`: ROS time, `sec + nanosec * 1e-9` seconds, `nanosec` in
/// `[0, 1e9)` (so -1.7 s is `{sec: -2, nanosec: 3e8}`).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default, Serialize, Deserialize,
)]
pub struct Time {
    pub sec: i32,
    pub nanosec: u32,
}

ros_message!(Time, "builtin_interfaces/msg/Time", TIME_DEF);

impl Time {
    pub const ZERO: Time = Time { sec: 0, nanosec: 0 };

    /// From nanoseconds; saturates at the range of `sec`.
    pub fn from_nanos(ns: i64) -> Time {
        let sec = ns.div_euclid(NANOS_PER_SEC);
        let nanosec = ns.rem_euclid(NANOS_PER_SEC) as u32;
        if sec > i32::MAX as i64 {
            Time {
                sec: i32::MAX,
                nanosec: (NANOS_PER_SEC - 1) as u32,
            }
        } else if sec < i32::MIN as i64 {
            Time {
                sec: i32::MIN,
                nanosec: 0,
            }
        } else {
            Time {
                sec: sec as i32,
                nanosec,
            }
        }
    }

    /// Nanoseconds (a `nanosec` of 1e9 or more, which is not valid, still counts as written).
    pub fn as_nanos(&self) -> i64 {
        self.sec as i64 * NANOS_PER_SEC + self.nanosec as i64
    }

    /// From seconds, rounded to the nearest nanosecond; saturates; NaN gives zero.
    pub fn from_secs_f64(s: f64) -> Time {
        if s.is_nan() {
            return Time::ZERO;
        }
        let whole = s.floor();
        let mut ns = ((s - whole) * 1e9).round() as i64;
        let mut sec = whole.clamp(i64::MIN as f64 / 2.0, i64::MAX as f64 / 2.0) as i64;
        if ns >= NANOS_PER_SEC {
            sec += 1;
            ns -= NANOS_PER_SEC;
        }
        Time::from_nanos(sec.saturating_mul(NANOS_PER_SEC).saturating_add(ns))
    }

    pub fn as_secs_f64(&self) -> f64 {
        self.sec as f64 + self.nanosec as f64 * 1e-9
    }

    /// This time shifted by `dt` seconds (rounded to the nanosecond).
    pub fn add_secs_f64(&self, dt: f64) -> Time {
        let whole = dt.trunc();
        let frac_ns = ((dt - whole) * 1e9).round() as i64;
        let whole_ns = (whole.clamp(-1e10, 1e10) as i64) * NANOS_PER_SEC;
        Time::from_nanos(self.as_nanos() + whole_ns + frac_ns)
    }

    /// `self - earlier` in seconds.
    pub fn secs_since(&self, earlier: Time) -> f64 {
        let d = self.as_nanos() - earlier.as_nanos();
        (d.div_euclid(NANOS_PER_SEC)) as f64 + d.rem_euclid(NANOS_PER_SEC) as f64 * 1e-9
    }
}
