//! The multisine diagnosis's candidates that carry a state but are linear per line, against
//! the truth of the element simulator: the shaker's force-driven single DOF (a linear spring
//! and damper behind 2 kg, three random-odd multisine realisations over 4-25 Hz at 30 dB)
//! with a planted first-order low-pass on the motion channels (displacement and acceleration,
//! the load cell as it is), or with its damper in series with a spring (a state of the
//! simulated element). Against a linear baseline the diagnosis names the planted effect and
//! finds its shape parameter (the cutoff, the relaxation time c / ks) near the truth;
//! hysteresis and drift are listed as not fitted with their reason.

use forcemap_math::diagnose::sensor::{SensorFilter, apply_samples};
use forcemap_math::diagnose::{Effect, PhasorDiagnosis, PhasorFindings, Verdict};
use forcemap_math::element::Element;
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::phasor::{MultisineOptions, analyse_multisine};
use forcemap_math::recipe::Setup;
use forcemap_math::record::{Channel, Record};
use forcemap_math::sim::{RunSpec, TruthElement};

const SNR_DB: f64 = 30.0;
const STIFFNESS_N_PER_M: f64 = 2.0e4;
const DAMPING_N_S_PER_M: f64 = 60.0;

/// The shaker's three multisine realisations (the validation record dropped).
fn spec(seed: u64) -> RunSpec {
    let mut spec = RunSpec::shaker_sdof_multisine(Some(SNR_DB), seed)
        .with_element(TruthElement::linear(STIFFNESS_N_PER_M, DAMPING_N_S_PER_M));
    spec.steps.truncate(2);
    spec.steps.push(spec.steps[0].clone());
    spec
}

fn diagnose(records: &[Record]) -> PhasorFindings {
    let model = Model::by_name("linear", &ModelOptions::default()).expect("a model");
    let mut d = PhasorDiagnosis::new(
        Setup::Element {
            moving_mass_kg: None,
            drive: None,
        },
        model,
    );
    for r in records {
        d.push_multisine(analyse_multisine(r, &MultisineOptions::default()).expect("a multisine"));
    }
    let f = d.findings().expect("findings");
    println!(
        "{} (gap {:.3} %, floor {:.3} %)",
        f.findings.headline(),
        f.findings.gap_before_percent,
        f.findings.floor_percent
    );
    for r in &f.ranked_effects {
        let p: Vec<String> = r
            .added_parameters
            .iter()
            .map(|p| format!("{} {:.5}", p.name, p.value))
            .collect();
        println!(
            "  {:<20} cv {:8.3} % score {:8.3} % {} {}",
            r.effect.name(),
            r.cv_percent,
            r.score_percent,
            r.significant,
            p.join(", ")
        );
    }
    for d in &f.dropped {
        println!("  dropped {}: {}", d.effect.name(), d.reason);
    }
    f
}

fn parameter(f: &PhasorFindings, name: &str) -> f64 {
    f.ranked_effects[0]
        .added_parameters
        .iter()
        .find(|p| p.name == name)
        .unwrap_or_else(|| panic!("{name} among {:?}", f.ranked_effects[0].added_parameters))
        .value
}

/// The effect is named, explains the gap to near its floor, and the state candidates without
/// per-line equations are listed with their reason.
fn assert_named(f: &PhasorFindings, effect: Effect) {
    assert_eq!(f.findings.verdict, Verdict::Explained);
    assert_eq!(f.findings.top_effect, Some(effect));
    assert!(f.findings.gap_before_percent > 5.0 * f.findings.floor_percent);
    assert!(
        f.ranked_effects[0].cv_percent < 1.5 * f.findings.floor_percent,
        "{} % left, floor {} %",
        f.ranked_effects[0].cv_percent,
        f.findings.floor_percent
    );
    for e in [Effect::Hysteresis, Effect::Drift] {
        assert!(
            f.dropped
                .iter()
                .any(|d| d.effect == e && d.reason.contains("per-line equations")),
            "{e:?} in {:?}",
            f.dropped
        );
    }
    assert!(f.not_fitted.is_empty(), "{:?}", f.not_fitted);
}

#[test]
fn a_motion_sensor_lowpass_is_named_with_its_cutoff() {
    let cutoff_hz = 40.0;
    let filter = SensorFilter::first_order_on_all(cutoff_hz);
    let mut records = spec(1).simulate().expect("the shaker run");
    for r in &mut records {
        let fs = r.sample_rate_hz;
        for (c, v) in &mut r.channels {
            if matches!(
                c,
                Channel::RelativeDisplacementM | Channel::MassAccelerationMps2
            ) {
                *v = apply_samples(v, fs, &filter);
            }
        }
    }
    let f = diagnose(&records);
    assert_named(&f, Effect::SensorLowpass);
    let fc = parameter(&f, "cutoff_hz");
    assert!((fc / cutoff_hz - 1.0).abs() < 0.05, "cutoff {fc} Hz");
}

/// A damper `c` in series with a spring `ks`: the damper force z relaxes to `c x'` with
/// `tau = c / ks`, `z' = (c x' - z) / tau`, beside the spring `k x`.
struct SeriesDamper {
    stiffness_n_per_m: f64,
    damping_n_s_per_m: f64,
    relaxation_s: f64,
}

impl Element for SeriesDamper {
    fn smooth_force(&self, x: f64, _v: f64, z: &[f64]) -> f64 {
        self.stiffness_n_per_m * x + z[0]
    }

    fn internal_states(&self) -> usize {
        1
    }

    fn internal_rates(&self, _x: f64, v: f64, z: &[f64], dz: &mut [f64]) {
        dz[0] = (self.damping_n_s_per_m * v - z[0]) / self.relaxation_s;
    }
}

#[test]
fn a_series_spring_on_the_damper_is_named_with_its_relaxation() {
    // ks 20 kN/m: at the top line (25 Hz) w tau = 0.47.
    let relaxation_s = DAMPING_N_S_PER_M / 2.0e4;
    let element = SeriesDamper {
        stiffness_n_per_m: STIFFNESS_N_PER_M,
        damping_n_s_per_m: DAMPING_N_S_PER_M,
        relaxation_s,
    };
    let records = spec(2)
        .simulate_with_element(&element)
        .expect("the shaker run")
        .records;
    let f = diagnose(&records);
    assert_named(&f, Effect::SeriesCompliance);
    let tau = parameter(&f, "relaxation_s");
    assert!((tau / relaxation_s - 1.0).abs() < 0.05, "tau {tau} s");
    let ks = parameter(&f, "ks");
    assert!((ks / 2.0e4 - 1.0).abs() < 0.05, "ks {ks} N/m");
}
