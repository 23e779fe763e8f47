//! The cells of an export are the numbers `str::parse` makes of them, however they are written:
//! the reader parses bytes with a fast parser and trims ASCII whitespace itself, and hands
//! what the fast parser refuses (a cell padded with Unicode whitespace) to `str::parse`.
#![allow(clippy::unwrap_used, reason = "tests")]

use std::f64::consts::PI;

use forcemap_io::csv_export::{read_csv, write_csv};
use forcemap_math::recipe::SetupKind;
use forcemap_math::record::{Channel, Excitation, Record};

const RIG: [Channel; 5] = [
    Channel::BaseDisplacementM,
    Channel::RelativeDisplacementM,
    Channel::MassAccelerationMps2,
    Channel::MassDisplacementM,
    Channel::BaseAccelerationMps2,
];

fn sine_record(step: usize, f: f64, start: f64) -> Record {
    let fs = 200.0;
    let channels = RIG
        .iter()
        .enumerate()
        .map(|(k, &c)| {
            let x = (0..400)
                .map(|i| {
                    let t = i as f64 / fs;
                    0.002 * (k as f64 + 1.0) * (2.0 * PI * f * t + 0.3 * k as f64).sin()
                })
                .collect();
            (c, x)
        })
        .collect();
    Record {
        step,
        excitation: Excitation::Sine {
            frequency_hz: f,
            amplitude: 0.002,
        },
        sample_rate_hz: fs,
        start_time_s: start,
        channels,
    }
}

/// `cell` (a number) written another way, chosen by `k`.
fn rewrite(cell: &str, k: usize) -> String {
    let v: f64 = cell.parse().unwrap();
    match k % 6 {
        0 => format!("  {v:e}\t"),
        1 => format!("{v:E}"),
        2 if v >= 0.0 => format!("+{v}"),
        3 => format!("\u{a0}{cell}\u{a0}"),
        4 => format!("{v:.17e}"),
        _ => format!(" {cell} "),
    }
}

#[test]
fn cells_written_any_way_read_as_str_parse_reads_them() {
    let dir = tempfile::tempdir().unwrap();
    let plain = dir.path().join("plain.csv");
    let records = vec![sine_record(0, 5.0, 0.0), sine_record(1, 7.5, 2.0)];
    write_csv(&plain, &records, SetupKind::BaseExcited).unwrap();
    let text = std::fs::read_to_string(&plain).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let mut out = vec![header.join(",")];
    for (i, line) in lines.enumerate() {
        let cells: Vec<String> = line
            .split(',')
            .zip(&header)
            .enumerate()
            .map(|(j, (cell, name))| {
                // Times, steps and frequencies padded only (their written form carries the
                // time resolution); the channels rewritten.
                if ["time_s", "step", "frequency_hz"].contains(name) {
                    format!(" {cell}")
                } else {
                    rewrite(cell, i + j)
                }
            })
            .collect();
        out.push(cells.join(","));
    }
    let rewritten = dir.path().join("rewritten.csv");
    std::fs::write(&rewritten, out.join("\n") + "\n").unwrap();

    let a = read_csv(&plain).unwrap();
    let b = read_csv(&rewritten).unwrap();
    assert_eq!(a.records.len(), b.records.len());
    for (ra, rb) in a.records.iter().zip(&b.records) {
        assert_eq!(ra.sample_rate_hz.to_bits(), rb.sample_rate_hz.to_bits());
        assert_eq!(ra.start_time_s.to_bits(), rb.start_time_s.to_bits());
        for ((ca, xa), (cb, xb)) in ra.channels.iter().zip(&rb.channels) {
            assert_eq!(ca, cb);
            for (u, v) in xa.iter().zip(xb) {
                assert_eq!(u.to_bits(), v.to_bits(), "{}: {u:e} vs {v:e}", ca.name());
            }
        }
    }
}

#[test]
fn a_cell_of_whitespace_is_empty_and_text_is_not_a_number() {
    let dir = tempfile::tempdir().unwrap();
    let plain = dir.path().join("plain.csv");
    write_csv(&plain, &[sine_record(0, 5.0, 0.0)], SetupKind::BaseExcited).unwrap();
    let text = std::fs::read_to_string(&plain).unwrap();
    let header = text.lines().next().unwrap();
    let col = header
        .split(',')
        .position(|c| c == "mass_acceleration_mps2")
        .unwrap();
    for (cell, want) in [("  \u{a0} ", "empty"), ("1.2.3", "1.2.3"), ("0x10", "0x10")] {
        let broken: Vec<String> = text
            .lines()
            .enumerate()
            .map(|(i, l)| {
                if i != 5 {
                    return l.to_string();
                }
                let mut cells: Vec<&str> = l.split(',').collect();
                cells[col] = cell;
                cells.join(",")
            })
            .collect();
        let path = dir.path().join("broken.csv");
        std::fs::write(&path, broken.join("\n") + "\n").unwrap();
        let e = read_csv(&path).unwrap_err().to_string();
        assert!(e.contains("line 6"), "{e}");
        assert!(e.contains("mass_acceleration_mps2"), "{e}");
        assert!(e.contains(want), "{cell:?}: {e}");
    }
}
