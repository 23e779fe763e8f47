//! Which channel a bench controlled in records that are not sine steps (the force or the
//! displacement), read from how much of each channel's power falls off a multisine's lines.

use num_complex::Complex64;

use crate::record::{Channel, Excitation, Record};
use crate::sim::ElementDrive;

/// Share of a channel's power at the bins a periodic multisine record does not excite, over
/// the record's last whole periods; None when the record is not a multisine of whole samples
/// per period.
fn off_line_share(r: &Record, c: Channel) -> Option<f64> {
    let Excitation::Multisine {
        base_frequency_hz,
        lines,
        ..
    } = &r.excitation
    else {
        return None;
    };
    let y = r.channel(c)?;
    let per = r.sample_rate_hz / base_frequency_hz;
    if (per - per.round()).abs() > 1e-6 || per.round() < 4.0 {
        return None;
    }
    let per = per.round() as usize;
    let periods = y.len() / per;
    if periods == 0 {
        return None;
    }
    let tail = &y[y.len() - periods * per..];
    let mut buf: Vec<Complex64> = tail.iter().map(|v| Complex64::new(*v, 0.0)).collect();
    crate::signal::fft::forward(buf.len()).process(&mut buf);
    let (mut on, mut off) = (0.0, 0.0);
    for (k, b) in buf.iter().enumerate().take(buf.len() / 2).skip(1) {
        let line = k % periods == 0 && lines.binary_search(&(k / periods)).is_ok();
        if line {
            on += b.norm_sqr();
        } else {
            off += b.norm_sqr();
        }
    }
    Some(off / (on + off).max(f64::MIN_POSITIVE))
}

/// What the bench controlled in records that are not sine steps: where every record is a
/// labelled multisine, the channel of x and F with the smaller share of its power off the
/// excited lines (the other carries the element's distortion, as [`super::element_drive_of`]
/// decides for sine steps); otherwise the displacement, as element benches are (a damper dyno,
/// a mount tester).
pub fn records_drive(records: &[&Record]) -> ElementDrive {
    let share = |c: Channel| -> Option<f64> {
        records
            .iter()
            .map(|r| off_line_share(r, c))
            .sum::<Option<f64>>()
    };
    match (
        share(Channel::RelativeDisplacementM),
        share(Channel::ForceN),
    ) {
        (Some(x), Some(f)) if f < x => ElementDrive::Force,
        _ => ElementDrive::Displacement,
    }
}
