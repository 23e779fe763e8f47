//! The wide forms' world (`diagnose-eval --forms wide`): each form against a closed form or
//! the limiting case where it is the library's own form, and the draws seeded.

use std::f64::consts::TAU;

use forcemap_eval::diagnose_eval::world::draw::{LIBRARY_FAMILIES, NEW_NAMES, OUT_OF_LIBRARY};
use forcemap_eval::diagnose_eval::world::{
    Exciter, SensorDynamics, Term, World, WorldElement, simulate,
};
use forcemap_eval::diagnose_eval::{
    CompressibleOilDamper, Planted, generate_cases, generate_wide_cases, wide_group,
};
use forcemap_math::element::{Element, Friction};
use forcemap_math::record::Channel;
use forcemap_math::sim::{BoucWen, FreePlay, RunSpec, TruthElement};

fn world(terms: Vec<Term>) -> WorldElement {
    WorldElement {
        base: TruthElement::rig_coulomb(),
        terms,
    }
}

/// Slip force of an element at velocity v: the friction law plus the smooth part.
fn slip(e: &dyn Element, x: f64, v: f64) -> f64 {
    e.friction().map_or(0.0, |f| f.slip_force_n(v)) + e.smooth_force(x, v, &[0.0; 8])
}

#[test]
fn stribeck_with_exponent_two_is_the_gaussian_form() {
    let (excess, vs) = (8.0, 0.015);
    let w = world(vec![Term::Stribeck {
        excess_n: excess,
        velocity_mps: vs,
        exponent: 2.0,
    }]);
    let lib = TruthElement {
        friction: Some(Friction {
            breakaway_n: 12.3 + excess,
            kinetic_n: 12.3,
            stribeck_velocity_mps: vs,
            stribeck_exponent: 2.0,
            asymmetry: 0.0,
        }),
        ..TruthElement::rig_coulomb()
    };
    assert_eq!(w.friction().unwrap().breakaway_n, 12.3 + excess);
    for i in -50..=50 {
        let v = i as f64 * 0.002;
        if v == 0.0 {
            continue;
        }
        let (a, b) = (slip(&w, 0.001, v), slip(&lib, 0.001, v));
        assert!((a - b).abs() < 1e-9, "v {v}: {a} vs {b}");
    }
    // Another exponent: the excess decays as exp(-|v/vs|^delta).
    let w = world(vec![Term::Stribeck {
        excess_n: excess,
        velocity_mps: vs,
        exponent: 0.5,
    }]);
    let v = 0.03;
    let want = 12.3 + 184.0 * v + excess * (-(2.0f64).sqrt()).exp();
    assert!((slip(&w, 0.0, v) - want).abs() < 1e-9);
}

#[test]
fn equal_gaps_are_the_symmetric_free_play() {
    let w = WorldElement {
        base: TruthElement::linear(6380.0, 184.0),
        terms: vec![Term::FreePlay {
            gap_neg_m: 0.002,
            gap_pos_m: 0.002,
            stiffness_n_per_m: 4000.0,
        }],
    };
    let lib = TruthElement {
        free_play: Some(FreePlay {
            gap_m: 0.004,
            stiffness_n_per_m: 4000.0,
        }),
        ..TruthElement::linear(6380.0, 184.0)
    };
    for i in -40..=40 {
        let x = i as f64 * 0.00025;
        let (a, b) = (w.smooth_force(x, 0.05, &[]), lib.smooth_force(x, 0.05, &[]));
        assert!((a - b).abs() < 1e-9, "x {x}: {a} vs {b}");
    }
    // Unequal: the contact starts at +3 mm and at -1 mm.
    let w = world(vec![Term::FreePlay {
        gap_neg_m: 0.001,
        gap_pos_m: 0.003,
        stiffness_n_per_m: 4000.0,
    }]);
    let extra = |x: f64| w.smooth_force(x, 0.0, &[]) - 6380.0 * x;
    assert!(extra(0.0029).abs() < 1e-9 && (extra(0.004) - 4.0).abs() < 1e-9);
    assert!(extra(-0.0009).abs() < 1e-9 && (extra(-0.002) + 4.0).abs() < 1e-9);
}

#[test]
fn bouc_wen_with_the_candidate_shape_is_the_library_law() {
    let zy = 0.001;
    let w = world(vec![Term::BoucWen {
        alpha_n_per_m: 12000.0,
        beta: 0.5 / zy,
        gamma: 0.5 / zy,
        n: 1.0,
    }]);
    let lib = BoucWen {
        alpha_n_per_m: 12000.0,
        a: 1.0,
        beta: 0.5 / zy,
        gamma: 0.5 / zy,
        n: 1.0,
    };
    let mut dz = [0.0];
    for &(z, v) in &[(0.0, 0.1), (0.0005, -0.05), (-0.0009, 0.2), (0.0012, 0.01)] {
        w.internal_rates(0.0, v, &[z], &mut dz);
        assert!((dz[0] - lib.rate(z, v)).abs() < 1e-12);
    }
    // n = 2, beta : gamma = 0.8 : 0.2 (z saturates at zy): at z = zy, v > 0 the rate is 0.
    let w = world(vec![Term::BoucWen {
        alpha_n_per_m: 1.0,
        beta: 0.8 / (zy * zy),
        gamma: 0.2 / (zy * zy),
        n: 2.0,
    }]);
    w.internal_rates(0.0, 0.1, &[zy], &mut dz);
    assert!(dz[0].abs() < 1e-12);
}

/// A noise-free band-random record of the paper's rig for `element`.
fn rig_record(element: &dyn Element) -> Vec<f64> {
    let spec = RunSpec::paper_rig_random([1.5, 2.5], None, 3);
    let out = spec
        .simulate_with_element(element)
        .expect("the rig simulates");
    out.records[0]
        .channel(Channel::MassAccelerationMps2)
        .expect("a rig record has the mass acceleration")
        .to_vec()
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

#[test]
fn drift_without_fade_is_the_plain_damper_and_series_compliance_is_the_oil_damper() {
    let plain = rig_record(&TruthElement::rig_coulomb());
    let drift = rig_record(&world(vec![Term::Drift {
        damping_n_s_per_m: 184.0,
        fade_per_j: 0.0,
        energy_at_start_j: 0.0,
    }]));
    assert!(max_abs_diff(&plain, &drift) < 1e-9);
    // With fade, the damping falls over the record and the response differs.
    let fading = rig_record(&world(vec![Term::Drift {
        damping_n_s_per_m: 184.0,
        fade_per_j: 0.02,
        energy_at_start_j: 0.0,
    }]));
    assert!(max_abs_diff(&plain, &fading) > 1e-2);
    // The series spring with the damper against the independent oil damper of the exact forms.
    let series = rig_record(&world(vec![Term::SeriesCompliance {
        damping_n_s_per_m: 184.0,
        stiffness_n_per_m: 6000.0,
    }]));
    let oil = rig_record(&CompressibleOilDamper {
        rest: TruthElement {
            damping_n_s_per_m: 0.0,
            ..TruthElement::rig_coulomb()
        },
        damping_n_s_per_m: 184.0,
        oil_stiffness_n_per_m: 6000.0,
    });
    assert!(max_abs_diff(&series, &oil) < 1e-9);
    assert!(max_abs_diff(&series, &plain) > 1e-2);
}

#[test]
fn drift_rates_follow_the_fading_damper() {
    // E' = c0 (1 - a E) v^2 and the force loses c0 a E v.
    let w = world(vec![Term::Drift {
        damping_n_s_per_m: 184.0,
        fade_per_j: 0.01,
        energy_at_start_j: 0.0,
    }]);
    let mut dz = [0.0];
    w.internal_rates(0.0, 0.1, &[20.0], &mut dz);
    assert!((dz[0] - 184.0 * 0.8 * 0.01).abs() < 1e-12);
    let extra = w.smooth_force(0.0, 0.1, &[20.0]) - w.base.smooth_force(0.0, 0.1, &[]);
    assert!((extra + 184.0 * 0.2 * 0.1).abs() < 1e-12);
}

#[test]
fn sensor_dynamics_match_their_frequency_response() {
    let fs = 100.0;
    let f = 2.5;
    let u: Vec<f64> = (0..2000).map(|i| (TAU * f * i as f64 / fs).sin()).collect();
    for (order, zeta, delay) in [
        (1u8, 0.0, 0.0),
        (2, 0.7, 0.0),
        (2, 0.5, 0.004),
        (1, 0.0, 0.003),
    ] {
        let fc = 6.0;
        let s = SensorDynamics {
            mask: 0b100,
            order,
            cutoff_hz: fc,
            damping_ratio: zeta,
            delay_s: delay,
        };
        let y = s.filter(&u, fs);
        let r = f / fc;
        let (gain, phase) = if order == 1 {
            (1.0 / (1.0 + r * r).sqrt(), -r.atan())
        } else {
            let (re, im) = (1.0 - r * r, 2.0 * zeta * r);
            (1.0 / re.hypot(im), -im.atan2(re))
        };
        let phase = phase - TAU * f * delay;
        // (the last samples lack the cubic's right neighbour)
        for (i, yi) in y.iter().enumerate().take(1997).skip(500) {
            let want = gain * (TAU * f * i as f64 / fs + phase).sin();
            assert!(
                (yi - want).abs() < 2e-4,
                "order {order}, delay {delay}: sample {i}: {yi} vs {want}"
            );
        }
        assert!(s.applies_to(Channel::MassAccelerationMps2));
        assert!(!s.applies_to(Channel::BaseAccelerationMps2));
    }
}

#[test]
fn the_exciter_command_lagged_is_the_received_base() {
    let spec = RunSpec::paper_rig_random([1.5, 2.5], None, 3);
    let received = spec.simulate().unwrap();
    let base = |r: &[forcemap_math::record::Record]| {
        r[0].channel(Channel::BaseDisplacementM).unwrap().to_vec()
    };
    // No delay and no lag: the channels are the program's.
    let mut same = received.clone();
    Exciter {
        delay_s: 0.0,
        lag_s: 0.0,
        resonance_hz: None,
        resonance_damping: 0.0,
    }
    .apply(&mut same, &spec.program());
    assert!(max_abs_diff(&base(&same), &base(&received)) < 1e-12);
    let acc = |r: &[forcemap_math::record::Record]| {
        r[0].channel(Channel::BaseAccelerationMps2)
            .unwrap()
            .to_vec()
    };
    assert!(max_abs_diff(&acc(&same), &acc(&received)) < 1e-6);
    // A lag: the command through the same first-order lag gives back the received base.
    let tau = 0.02;
    let mut command = received.clone();
    Exciter {
        delay_s: 0.0,
        lag_s: tau,
        resonance_hz: None,
        resonance_damping: 0.0,
    }
    .apply(&mut command, &spec.program());
    let lag = SensorDynamics {
        mask: 1,
        order: 1,
        cutoff_hz: 1.0 / (TAU * tau),
        damping_ratio: 0.0,
        delay_s: 0.0,
    };
    let back = lag.filter(&base(&command), 100.0);
    let rms = (base(&received).iter().map(|x| x * x).sum::<f64>() / 1300.0).sqrt();
    assert!(max_abs_diff(&back[100..], &base(&received)[100..]) < 0.01 * rms);
    assert!(max_abs_diff(&base(&command), &base(&received)) > 0.05 * rms);
}

#[test]
fn a_world_without_effects_is_the_paper_run() {
    let run = simulate(&World::of(&[]), 30.0, 5).unwrap();
    let spec = RunSpec::paper_rig(Some(30.0), 5).simulate().unwrap();
    assert_eq!(run.records.len(), spec.len());
    for (a, b) in run.records.iter().zip(&spec) {
        for (c, v) in &b.channels {
            assert!(max_abs_diff(a.channel(*c).unwrap(), v) < 1e-9);
        }
    }
    assert!(run.truth_nmse_percent > 0.0 && run.truth_nmse_percent < 1.0);
}

#[test]
fn the_wide_draws_are_seeded_and_cover_every_family() {
    let a = generate_wide_cases(300, 7);
    assert_eq!(a, generate_wide_cases(300, 7));
    assert_ne!(a, generate_wide_cases(300, 8));
    let labels: Vec<String> = a.iter().map(|c| c.planted.label()).collect();
    for name in LIBRARY_FAMILIES.iter().chain(&NEW_NAMES) {
        assert!(labels.iter().any(|l| l == name), "{name} never drawn");
    }
    for name in OUT_OF_LIBRARY {
        assert!(labels.contains(&format!("out_of_library:{name}")));
    }
    let groups: Vec<String> = a.iter().map(wide_group).collect();
    for g in [
        "single effects at 20 dB",
        "single effects at 30 dB",
        "single effects at 40 dB",
        "pairs",
        "out of library",
        "new names",
        "no effect",
    ] {
        assert!(groups.iter().any(|x| x == g), "no case in {g}");
    }
    // The exact forms' cases are not touched by the wide ones.
    assert!(
        generate_cases(200, 1, 30.0)
            .iter()
            .all(|c| c.planted.world_effects().is_empty())
    );
    assert!(matches!(
        generate_cases(200, 1, 30.0)[73].planted,
        Planted::One { .. }
    ));
}

#[test]
fn a_drift_replay_starts_with_the_energy_dissipated_before_it() {
    // E' = c0 (1 - fade E) v^2 integrated at constant v for 60 s against the closed form the
    // replay of a later record starts from.
    let drift = Term::Drift {
        damping_n_s_per_m: 184.0,
        fade_per_j: 0.002,
        energy_at_start_j: 0.0,
    };
    let w = world(vec![drift]);
    let (v, dt) = (0.08, 1e-3);
    let mut e = [0.0];
    let mut de = [0.0];
    for _ in 0..60_000 {
        w.internal_rates(0.0, v, &e, &mut de);
        e[0] += dt * de[0];
    }
    let Term::Drift {
        energy_at_start_j, ..
    } = drift.at_dissipation(v * v * 60.0)
    else {
        panic!("a drift stays a drift")
    };
    assert!(
        (energy_at_start_j - e[0]).abs() < 1e-3 * e[0],
        "{energy_at_start_j} vs {}",
        e[0]
    );
    // The replay from there continues the fading: its force is that of the run at 60 s.
    let later = world(vec![drift.at_dissipation(v * v * 60.0)]);
    let (a, b) = (
        later.smooth_force(0.0, v, &[0.0]),
        w.smooth_force(0.0, v, &e),
    );
    assert!((a - b).abs() < 1e-3 * b.abs());
    assert!(e[0] > 50.0 && e[0] < 70.0 / 0.9, "{}", e[0]);
}

#[test]
fn the_elastomer_branches_are_maxwell_elements() {
    // Each branch f' = k v - f / tau under v = cos(w t): steady amplitude k tau / sqrt(1 + (w
    // tau)^2), against the sum of the four integrated states.
    let (stiffness, order) = (2000.0, 0.4);
    let w = world(vec![Term::Elastomer {
        stiffness_n_per_m: stiffness,
        order,
    }]);
    let omega = TAU * 2.5;
    let dt = 1e-4;
    let mut z = [0.0; 4];
    let mut dz = [0.0; 4];
    let mut peak: f64 = 0.0;
    for i in 0..200_000 {
        let t = i as f64 * dt;
        w.internal_rates(0.0, (omega * t).cos(), &z, &mut dz);
        for (zi, di) in z.iter_mut().zip(&dz) {
            *zi += dt * di;
        }
        if t > 15.0 {
            let f = w.smooth_force(0.0, 0.0, &z) - w.base.smooth_force(0.0, 0.0, &[]);
            peak = peak.max(f.abs());
        }
    }
    let (mut re, mut im) = (0.0, 0.0);
    for tau in forcemap_eval::diagnose_eval::world::element::ELASTOMER_TAUS_S {
        let k = stiffness * (tau / 0.04f64).powf(-order);
        // f / v = k tau / (1 + i w tau).
        let d = 1.0 + (omega * tau).powi(2);
        re += k * tau / d;
        im -= k * tau * omega * tau / d;
    }
    let want = re.hypot(im);
    assert!((peak - want).abs() < 2e-3 * want, "{peak} vs {want}");
}
