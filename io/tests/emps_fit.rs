//! Sanity check of the imported EMPS data against the published reference model
//! tau = M q'' + Fv q' + Fc sgn(q') + offset (M 95.1089 kg, Fv 203.5034 N s/m, Fc 20.3935 N,
//! offset -3.1648 N; relative force error 4.08 % on DATA_EMPS, 5.98 % on the pulses). Skips
//! with a notice where ../shared/real is absent.
use std::path::Path;

use forcemap_io::emps::{self, FitOptions};

const PUBLISHED: [(&str, f64); 4] = [
    ("M [kg]", 95.1089),
    ("Fv [N s/m]", 203.5034),
    ("Fc [N]", 20.3935),
    ("offset [N]", -3.1648),
];

#[test]
fn least_squares_fit_lands_near_the_published_parameters() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/real/emps");
    if !dir.join("DATA_EMPS.mat").is_file() {
        eprintln!("skipped: {} does not exist", dir.display());
        return;
    }
    let fit_data = emps::read_emps(dir.join("DATA_EMPS.mat")).unwrap();
    let opts = FitOptions::default();
    let fit = emps::fit_reference_model(&fit_data, &opts).unwrap();
    let theta = fit.theta();
    println!("options {opts:?}, {} equations", fit.equations);
    for (((name, published), got), std) in PUBLISHED.iter().zip(theta).zip(fit.std) {
        println!(
            "{name:>11}: {got:9.4} +- {std:.4} (published {published:9.4}, {:+.2} %)",
            100.0 * (got - published) / published
        );
    }
    println!(
        "relative force error: {:.2} % on DATA_EMPS (published 4.08 %)",
        fit.relative_error_percent
    );
    for ((name, published), got) in PUBLISHED.iter().zip(theta).take(3) {
        assert!(
            ((got - published) / published).abs() < 0.10,
            "{name}: {got} vs published {published}"
        );
    }
    assert!(
        (theta[3] - PUBLISHED[3].1).abs() < 1.0,
        "offset {}",
        theta[3]
    );
    assert!(
        fit.relative_error_percent < 5.0,
        "{}",
        fit.relative_error_percent
    );

    if let Ok(pulses) = emps::read_emps(dir.join("DATA_EMPS_PULSES.mat")) {
        let e = fit.relative_error_on(&pulses).unwrap();
        println!("relative force error: {e:.2} % on DATA_EMPS_PULSES (published 5.98 %)");
        assert!(e < 7.5, "{e}");
    }
}

#[test]
fn a_position_cutoff_below_the_decimation_band_still_gives_the_parameters() {
    // A position cutoff of 25 Hz (within 20-30 Hz): the parameters stay within 1 %, only the
    // force error grows.
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/real/emps");
    if !dir.join("DATA_EMPS.mat").is_file() {
        eprintln!("skipped: {} does not exist", dir.display());
        return;
    }
    let data = emps::read_emps(dir.join("DATA_EMPS.mat")).unwrap();
    let opts = FitOptions {
        position_cutoff_hz: 25.0,
        decimation: 10,
    };
    let fit = emps::fit_reference_model(&data, &opts).unwrap();
    println!(
        "25 Hz: {:?}, {:.2} %",
        fit.theta(),
        fit.relative_error_percent
    );
    for ((name, published), got) in PUBLISHED.iter().zip(fit.theta()) {
        assert!(
            ((got - published) / published).abs() < 0.01,
            "{name}: {got} vs published {published}"
        );
    }
}
