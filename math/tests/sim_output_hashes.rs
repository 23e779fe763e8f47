//! The rig simulator's outputs, bit for bit: a hash of every sample (channels, trace, stuck time
//! and events) of the runs its speed work must not change, against the hash the simulator gave
//! before that work (commit c43da81). A change of the integration that moves any output
//! in its last bit fails here; a change meant to move them must say so, measure the difference
//! against the channels' RMS, and update the hash with the reason.
//!
//! The 156 s paper run at 10 kHz is ignored in the default (debug) test run for its time:
//! `cargo test -p forcemap_math --release --test sim_output_hashes -- --include-ignored`.
#![allow(clippy::unwrap_used, reason = "tests")]

use forcemap_math::element::Friction;
use forcemap_math::sim::excitation::{PAPER_RIG_SINE_AMPLITUDE_M, sine_steps};
use forcemap_math::sim::{
    ReplayOptions, RigEffects, RunSpec, SimOutput, ThreeDofCase, TruthElement,
    simulate_on_sampled_base,
};

/// FNV-1a over 64-bit words.
struct Fnv(u64);

impl Fnv {
    fn new() -> Fnv {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    fn word(&mut self, w: u64) {
        for b in w.to_le_bytes() {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    fn f64(&mut self, x: f64) {
        self.word(x.to_bits());
    }
}

/// Hash of every output of a run: each record's channels in order, then its trace.
fn hash_of(out: &SimOutput) -> u64 {
    let mut h = Fnv::new();
    for (record, trace) in out.records.iter().zip(&out.traces) {
        for (channel, values) in &record.channels {
            h.word(*channel as u64);
            values.iter().for_each(|&v| h.f64(v));
        }
        for s in &trace.samples {
            h.f64(s.relative_velocity_mps);
            h.word(u64::from(s.stuck));
            h.f64(s.friction_force_n);
        }
        trace.stick_time_s.iter().for_each(|&s| h.f64(s));
        h.word(trace.events as u64);
    }
    h.0
}

/// The bench's 10 kHz rig run (`rig_10kHz_sine`: three stepped-sine steps of 2 s).
fn rig_10khz_sine() -> RunSpec {
    RunSpec {
        sample_rate_hz: 10_000.0,
        samples_per_record: 20_000,
        steps: sine_steps(&[1.6, 2.4, 3.4], PAPER_RIG_SINE_AMPLITUDE_M),
        ..RunSpec::paper_rig(None, 0)
    }
}

/// The runs whose hash is not the expected one (all of them printed).
#[derive(Default)]
struct Changed(Vec<String>);

impl Changed {
    fn compare(&mut self, name: &str, got: u64, expected: u64, note: &str) {
        eprintln!("{name}: {got:#018x}{note}");
        if got != expected {
            self.0
                .push(format!("{name}: {got:#018x}, expected {expected:#018x}"));
        }
    }

    fn run(&mut self, name: &str, spec: &RunSpec, expected: u64) {
        let out = spec.simulate_detailed().unwrap();
        let events: usize = out.traces.iter().map(|t| t.events).sum();
        self.compare(
            name,
            hash_of(&out),
            expected,
            &format!(" ({events} events)"),
        );
    }

    fn assert_none(self) {
        assert!(self.0.is_empty(), "outputs changed:\n{}", self.0.join("\n"));
    }
}

#[test]
fn the_10khz_rig_runs_are_unchanged() {
    let mut c = Changed::default();
    let sine = rig_10khz_sine();
    c.run("rig_10kHz_sine", &sine, 0x6ab4_51c4_76aa_755c);
    // An exciter delay: the measured base is its own signal (the linear path still).
    let delayed = sine.clone().with_effects(RigEffects {
        exciter_delay_s: 0.0123,
        ..RigEffects::default()
    });
    c.run(
        "rig_10kHz_sine, exciter delay",
        &delayed,
        0x4a79_b63c_0650_8f42,
    );
    // A delay of no whole number of samples: the true base's breakpoints fall between samples.
    let between = sine.clone().with_effects(RigEffects {
        exciter_delay_s: 0.012_345_67,
        ..RigEffects::default()
    });
    c.run(
        "rig_10kHz_sine, delay between samples",
        &between,
        0x5d6c_f79a_2ee4_b632,
    );
    // A sensor low-pass: extra states, every sub-step through the RK4 stages.
    let filtered = sine.clone().with_effects(RigEffects {
        sensor_lowpass_hz: Some(30.0),
        ..RigEffects::default()
    });
    c.run(
        "rig_10kHz_sine, sensor low-pass",
        &filtered,
        0x18b8_338f_ec57_2475,
    );
    // Stribeck friction: slip is not of constant level, RK4 stages.
    let stribeck = sine.clone().with_element(TruthElement {
        friction: Some(Friction {
            breakaway_n: 18.0,
            stribeck_velocity_mps: 0.01,
            stribeck_exponent: 2.0,
            ..Friction::coulomb(12.3)
        }),
        ..TruthElement::rig_coulomb()
    });
    c.run("rig_10kHz_sine, Stribeck", &stribeck, 0xebba_040e_c440_db78);
    // A band-random record at 10 kHz (Taylor windows of a multisine, its RMS scaling).
    let random = RunSpec {
        steps: vec![forcemap_math::sim::StepSpec::Random {
            low_hz: 1.5,
            high_hz: 2.5,
            rms: 0.004,
            components: 64,
        }],
        ..rig_10khz_sine()
    };
    c.run(
        "rig_10kHz_random, 40 dB",
        &RunSpec {
            snr_db: Some(40.0),
            seed: 3,
            ..random
        },
        0xc5b5_3145_b8e6_b6a4,
    );
    c.assert_none();
}

#[test]
fn the_100hz_rig_runs_are_unchanged() {
    let mut c = Changed::default();
    let sine = RunSpec {
        sample_rate_hz: 100.0,
        samples_per_record: 200,
        ..rig_10khz_sine()
    };
    c.run("rig_100Hz_sine", &sine, 0x8ffb_84bc_e635_85b3);
    // The committed bag `bags/rig_40db`'s run.
    c.run(
        "paper_rig 40 dB seed 1",
        &RunSpec::paper_rig(Some(40.0), 1),
        0x21d2_454f_d51b_2c75,
    );
    // A replay of sampled base motion (spline pieces, the exact step per interval).
    let base = RunSpec::paper_rig(None, 0).simulate().unwrap();
    let b = base[10]
        .channel(forcemap_math::record::Channel::BaseDisplacementM)
        .unwrap();
    let replay = simulate_on_sampled_base(
        &TruthElement::rig_coulomb(),
        36.0,
        b,
        100.0,
        &ReplayOptions::default(),
    )
    .unwrap();
    let mut h = Fnv::new();
    for column in [
        &replay.mass_acceleration_mps2,
        &replay.relative_displacement_m,
        &replay.mass_displacement_m,
    ] {
        column.iter().for_each(|&v| h.f64(v));
    }
    for s in &replay.trace {
        h.f64(s.relative_velocity_mps);
        h.f64(s.friction_force_n);
    }
    c.compare(
        "replay of paper_rig record 10",
        h.0,
        0x8417_2d1f_526d_f40f,
        "",
    );
    c.assert_none();
}

/// The other systems share the integrator's loop (nonlinear elements: the RK4 stages).
#[test]
fn the_3dof_and_element_runs_are_unchanged() {
    let mut c = Changed::default();
    c.run(
        "three_dof CASE I",
        &RunSpec::three_dof(ThreeDofCase::I, None, 0),
        0x7c89_74b0_1014_4909,
    );
    c.run(
        "damper_dyno 40 dB",
        &RunSpec::damper_dyno(Some(40.0), 2),
        0xb0cd_00e8_1d22_24c9,
    );
    c.assert_none();
}

#[test]
#[ignore = "156 s at 10 kHz: run in release with --include-ignored"]
fn the_paper_run_at_10khz_is_unchanged() {
    let spec = RunSpec {
        sample_rate_hz: 10_000.0,
        samples_per_record: 130_000,
        ..RunSpec::paper_rig(None, 0)
    };
    let mut c = Changed::default();
    c.run(
        "paper_rig at 10 kHz, noise-free",
        &spec,
        0x7e07_6343_9d23_f8d9,
    );
    c.assert_none();
}
