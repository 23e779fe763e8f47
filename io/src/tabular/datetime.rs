//! Date-time cells of a time column: ISO 8601 (`2024-03-01T12:00:00.125`, with `T` or a space,
//! with or without a zone such as `Z` or `+01:00`, any fraction of a second) or a format the
//! map gives (a chrono format such as `%m/%d/%Y %I:%M:%S%.f %p`), turned into seconds since the
//! first sample.

use chrono::{DateTime, NaiveDateTime};

/// An instant as nanoseconds on one time line: UTC for cells with a zone, the local wall clock
/// of the file for cells without (the two kinds are not mixed in one column).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Instant {
    pub nanos: i128,
    pub zoned: bool,
}

const NAIVE_FORMATS: [&str; 2] = ["%Y-%m-%dT%H:%M:%S%.f", "%Y-%m-%d %H:%M:%S%.f"];

/// Parses one cell; `format` is the map's, else ISO 8601.
pub fn parse_instant(cell: &str, format: Option<&str>) -> Option<Instant> {
    let cell = cell.trim();
    let zoned = |d: DateTime<chrono::FixedOffset>| Instant {
        nanos: nanos_of(d.naive_utc()),
        zoned: true,
    };
    let naive = |d: NaiveDateTime| Instant {
        nanos: nanos_of(d),
        zoned: false,
    };
    match format {
        Some(f) => DateTime::parse_from_str(cell, f)
            .map(zoned)
            .or_else(|_| NaiveDateTime::parse_from_str(cell, f).map(naive))
            .ok(),
        None => {
            if let Ok(d) = DateTime::parse_from_rfc3339(cell) {
                return Some(zoned(d));
            }
            // A zone without the rfc3339 form: `+0100` or a space before it.
            for f in ["%Y-%m-%dT%H:%M:%S%.f%z", "%Y-%m-%d %H:%M:%S%.f%z"] {
                if let Ok(d) = DateTime::parse_from_str(cell, f) {
                    return Some(zoned(d));
                }
            }
            NAIVE_FORMATS
                .iter()
                .find_map(|f| NaiveDateTime::parse_from_str(cell, f).ok())
                .map(naive)
        }
    }
}

fn nanos_of(d: NaiveDateTime) -> i128 {
    let u = d.and_utc();
    i128::from(u.timestamp()) * 1_000_000_000 + i128::from(u.timestamp_subsec_nanos())
}

/// Seconds from `first` to `instant`.
pub fn seconds_since(first: Instant, instant: Instant) -> f64 {
    (instant.nanos - first.nanos) as f64 * 1e-9
}

#[cfg(test)]
mod tests {
    use super::*;

    fn secs(cells: &[&str], format: Option<&str>) -> Vec<f64> {
        let i: Vec<Instant> = cells
            .iter()
            .map(|c| parse_instant(c, format).unwrap())
            .collect();
        i.iter().map(|&x| seconds_since(i[0], x)).collect()
    }

    #[test]
    fn iso_forms_give_seconds_since_the_first() {
        assert_eq!(
            secs(&["2024-03-01T12:00:00", "2024-03-01T12:00:00.005"], None),
            [0.0, 0.005]
        );
        assert_eq!(
            secs(
                &["2024-03-01 23:59:59.999", "2024-03-02 00:00:00.000"],
                None
            ),
            [0.0, 0.001]
        );
        // Zones: the same instant written in two zones is no time apart.
        assert_eq!(
            secs(
                &["2024-03-01T12:00:00Z", "2024-03-01T13:00:00.25+01:00"],
                None
            ),
            [0.0, 0.25]
        );
        assert_eq!(
            secs(
                &["2024-03-01T12:00:00+0100", "2024-03-01T12:00:01+0100"],
                None
            ),
            [0.0, 1.0]
        );
        // Nanoseconds survive a day's offset.
        let s = secs(
            &[
                "2024-03-01T00:00:00.000000001",
                "2024-03-01T00:00:00.000000002",
            ],
            None,
        );
        assert!((s[1] - 1e-9).abs() < 1e-18, "{s:?}");
    }

    #[test]
    fn a_lab_format_is_read_with_the_maps_format() {
        let f = Some("%m/%d/%Y %I:%M:%S%.f %p");
        assert_eq!(
            secs(
                &["03/01/2024 01:59:59.500 PM", "03/01/2024 02:00:00.000 PM"],
                f
            ),
            [0.0, 0.5]
        );
        assert!(parse_instant("03/01/2024 01:59:59.500 PM", None).is_none());
    }

    #[test]
    fn numbers_and_text_are_not_date_times() {
        assert!(parse_instant("0.25", None).is_none());
        assert!(parse_instant("Timestamp", None).is_none());
        assert!(parse_instant("2024-13-01T00:00:00", None).is_none());
    }
}
