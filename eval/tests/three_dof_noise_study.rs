//! Measurements behind the choice of the 40 dB method of Table 1 (ignored; run with
//! `cargo test -p forcemap_eval --test three_dof_noise_study -- --ignored --nocapture NAME`):
//!
//! - `seed_scan`: parameter errors over noise seeds 0..SEEDS (default 10), with mean, std and
//!   worst. Environment: CASE=I|II (default II), SNR (dB, 0 = noise-free; default 40), NOISE=1
//!   or UNIFORM=1 for those weightings of fd-multi (default robust), OE=1 for
//!   `Method::OutputError` (default fd-multi), QUIET=x,xd,f to leave channels noise-free, and
//!   fd-multi's knobs JM, SVF, SFD, GUARD.
//! - `case_ii_crb`: the Cramer-Rao bound of k, c, F_d, S from the settled samples of x, x_d
//!   (and F) with the exact model.
//! - `case_ii_noise_budget`: where the first-harmonic force noise comes from, per step.
#![allow(
    clippy::unwrap_used,
    reason = "test and bench helpers outside #[test] fns: a panic is how they report failure"
)]
use forcemap_eval::paper::TABLE1_TRUTH;
use forcemap_eval::reproduce::phasor_options;
use forcemap_math::frf::LinearSubstructure;
use forcemap_math::identify::{FdMultiOptions, Method};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::pipeline::identify_records;
use forcemap_math::recipe::Setup;
use forcemap_math::sim::excitation::derive_seed;
use forcemap_math::sim::noise::add_noise;
use forcemap_math::sim::{RunSpec, RunSystem, ThreeDofCase, ThreeDofParams};

#[test]
#[ignore]
fn seed_scan() {
    let run = if std::env::var("CASE").as_deref() == Ok("I") {
        RunSpec::three_dof(ThreeDofCase::I, None, 0)
    } else {
        RunSpec::three_dof(ThreeDofCase::Ii, None, 0)
    };
    let snr: Option<f64> = std::env::var("SNR")
        .ok()
        .and_then(|v| v.parse().ok())
        .or(Some(40.0))
        .filter(|v| *v > 0.0);
    let clean = run.simulate().unwrap();
    let setup = Setup::DrivePoint {
        substructure: LinearSubstructure::paper_three_dof_substructure_i(),
    };
    let model = Model::by_name("coulomb-cubic", &ModelOptions::default()).unwrap();
    let (k, c, fd, s) = TABLE1_TRUTH;
    let truth = [k, c, fd, s];
    let n: u64 = std::env::var("SEEDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10);
    let env = |k: &str, d: f64| {
        std::env::var(k)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(d)
    };
    let mut opts = FdMultiOptions::default();
    opts.jump_margin_harmonic_periods = env("JM", opts.jump_margin_harmonic_periods);
    opts.stick_velocity_fraction = env("SVF", opts.stick_velocity_fraction);
    opts.stick_force_degree = env("SFD", opts.stick_force_degree as f64) as usize;
    opts.guard_harmonic_periods = env("GUARD", opts.guard_harmonic_periods);
    if env("UNIFORM", 0.0) > 0.0 {
        opts.weighting = forcemap_math::identify::Weighting::Uniform;
    }
    if env("NOISE", 0.0) > 0.0 {
        opts.weighting = forcemap_math::identify::Weighting::Noise;
    }
    let mut errs = vec![];
    for seed in 0..n {
        let mut rec = clean.clone();
        add_noise(&mut rec, snr, derive_seed(seed, 1));
        let quiet = std::env::var("QUIET").unwrap_or_default();
        for (name, ch) in [
            ("x", forcemap_math::record::Channel::RelativeDisplacementM),
            (
                "xd",
                forcemap_math::record::Channel::DrivePointDisplacementM,
            ),
            ("f", forcemap_math::record::Channel::ForceN),
        ] {
            if quiet.split(',').any(|q| q == name) {
                for (r, c0) in rec.iter_mut().zip(&clean) {
                    r.channel_mut(ch)
                        .unwrap()
                        .copy_from_slice(c0.channel(ch).unwrap());
                }
            }
        }
        let method = if env("OE", 0.0) > 0.0 {
            Method::OutputError
        } else {
            Method::FdMulti
        };
        let id = identify_records(&model, &setup, method, &rec, &phasor_options(), &opts).unwrap();
        let e: Vec<f64> = id
            .theta()
            .iter()
            .zip(truth)
            .map(|(v, t)| 100.0 * (v / t - 1.0))
            .collect();
        let sd: Vec<f64> = id
            .parameters
            .iter()
            .zip(truth)
            .map(|(p, t)| 100.0 * p.std / t)
            .collect();
        println!(
            "seed {seed}: err% {:?} std% {:?}",
            e.iter().map(|v| format!("{v:+.2}")).collect::<Vec<_>>(),
            sd.iter().map(|v| format!("{v:.2}")).collect::<Vec<_>>()
        );
        errs.push(e);
    }
    for (j, name) in ["k", "c", "fd", "s"].iter().enumerate() {
        let v: Vec<f64> = errs.iter().map(|e| e[j]).collect();
        let m = v.iter().sum::<f64>() / v.len() as f64;
        let sd = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt();
        let w = v.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        println!("{name}: mean {m:+.2} % std {sd:.2} % worst {w:.2} %");
    }
}

/// Cramer-Rao bound of (k, c, F_d, S) from the settled samples of x and x_d with the input force
/// known and the 3-DOF model exact: with substructure II known (4 parameters), and with its
/// m3, k33, c33 unknown too (7 parameters).
#[test]
#[ignore]
fn case_ii_crb() {
    use forcemap_math::element::Friction;
    use forcemap_math::record::Channel;
    use forcemap_math::sim::TruthElement;
    use forcemap_math::sim::noise::run_rms;
    let run = RunSpec::three_dof(ThreeDofCase::Ii, None, 0);
    let clean = run.simulate().unwrap();
    let chans = [
        Channel::RelativeDisplacementM,
        Channel::DrivePointDisplacementM,
        Channel::ForceN,
    ];
    let sig: Vec<f64> = chans
        .iter()
        .map(|c| run_rms(&clean, *c).unwrap() / 100.0)
        .collect();
    let (k, c, fd, s) = TABLE1_TRUTH;
    let p0 = ThreeDofParams::paper();
    let nch = chans.len();
    let truth = [k, c, fd, s, p0.m3_kg, p0.k33_n_per_m, p0.c33_n_s_per_m];
    let tail = std::env::var("TAIL")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(5000usize);
    let spec = |th: [f64; 7], ascale: f64| {
        let mut params = p0;
        params.m3_kg = th[4];
        params.k33_n_per_m = th[5];
        params.c33_n_s_per_m = th[6];
        RunSpec {
            system: RunSystem::ThreeDof { params },
            element: TruthElement {
                stiffness_n_per_m: th[0],
                damping_n_s_per_m: th[1],
                friction: Some(Friction::coulomb(th[2])),
                cubic_stiffness_n_per_m3: th[3],
                ..TruthElement::three_dof_element()
            },
            steps: forcemap_math::sim::excitation::three_dof_steps(
                &forcemap_math::sim::excitation::THREE_DOF_CASE_II_N.map(|a| a * ascale),
            ),
            ..run.clone()
        }
    };
    let collect = |r: &[forcemap_math::record::Record]| {
        let mut out = vec![];
        for rr in r {
            for (ci, ch) in chans.iter().enumerate() {
                let v = rr.channel(*ch).unwrap();
                out.extend(v[v.len() - tail..].iter().map(|x| x / sig[ci]));
            }
        }
        out
    };
    let mut sens: Vec<Vec<f64>> = vec![];
    for j in 0..7 {
        let h = truth[j] * 1e-3;
        let mut rec = [vec![], vec![]];
        for (si, sgn) in [1.0, -1.0].iter().enumerate() {
            let mut th = truth;
            th[j] += sgn * h;
            rec[si] = collect(&spec(th, 1.0).simulate().unwrap());
        }
        sens.push(
            rec[0]
                .iter()
                .zip(&rec[1])
                .map(|(a, b)| (a - b) / (2.0 * h) * truth[j])
                .collect(),
        );
    }
    // Nuisance: each step's force amplitude (relative) and phase (rad), seen in every channel.
    let h = 1e-4;
    let up = collect(&spec(truth, 1.0 + h).simulate().unwrap());
    let dn = collect(&spec(truth, 1.0 - h).simulate().unwrap());
    let base = collect(&clean);
    let blk = nch * tail;
    let w = std::f64::consts::TAU * 5.0;
    for st in 0..5 {
        let mut sa = vec![0.0; base.len()];
        let mut sp = vec![0.0; base.len()];
        for i in st * blk..(st + 1) * blk {
            sa[i] = (up[i] - dn[i]) / (2.0 * h);
            // a phase lead phi of the force shifts the steady state by phi / w in time
            let j = (i - st * blk) % tail;
            if j > 0 && j + 1 < tail {
                sp[i] = (base[i + 1] - base[i - 1]) / 2e-3 / w;
            }
        }
        sens.push(sa);
        sens.push(sp);
    }
    let with_force = |np: usize| -> Vec<usize> { (0..np).chain(7..17).collect() };
    for (label, idx, chs) in [
        (
            "4 unknowns, force known",
            (0..4).collect::<Vec<_>>(),
            2usize,
        ),
        ("7 unknowns, force known", (0..7).collect(), 2),
        (
            "4 unknowns + force amplitude/phase per step, F channel noisy",
            with_force(4),
            3,
        ),
        (
            "7 unknowns + force amplitude/phase per step, F channel noisy",
            with_force(7),
            3,
        ),
    ] {
        let np = idx.len();
        let use_sample = |t: usize| (t / tail) % nch < chs;
        let mut jm = nalgebra::DMatrix::zeros(np, np);
        for (a, &i) in idx.iter().enumerate() {
            for (b, &j) in idx.iter().enumerate() {
                jm[(a, b)] = (0..sens[i].len())
                    .filter(|t| use_sample(*t))
                    .map(|t| sens[i][t] * sens[j][t])
                    .sum::<f64>();
            }
        }
        let cov = jm.try_inverse().unwrap();
        let sd: Vec<String> = (0..4)
            .map(|i| format!("{:.3}", 100.0 * cov[(i, i)].sqrt()))
            .collect();
        println!("CRB std % of k, c, fd, s, {label} (tail {tail}): {sd:?}");
    }
}
#[test]
#[ignore]
fn case_ii_noise_budget() {
    use forcemap_math::identify::element_harmonics;
    use forcemap_math::pipeline::analyse_sine_steps;
    use forcemap_math::record::Channel;
    let clean = RunSpec::three_dof(ThreeDofCase::Ii, None, 0)
        .simulate()
        .unwrap();
    let mut rec = clean.clone();
    add_noise(&mut rec, Some(40.0), derive_seed(1, 1));
    let sub = LinearSubstructure::paper_three_dof_substructure_i();
    let setup = Setup::DrivePoint {
        substructure: sub.clone(),
    };
    let (ans, _) = analyse_sine_steps(&rec, &phasor_options()).unwrap();
    for an in &ans {
        let eh = element_harmonics(&setup, an, false).unwrap();
        let w = eh.omega_rad_s;
        let f = an.channel(Channel::ForceN).unwrap();
        let xd = an.channel(Channel::DrivePointDisplacementM).unwrap();
        let z1 = 1.0 / sub.drive_point_receptance(w);
        let z3 = 1.0 / sub.drive_point_receptance(3.0 * w);
        println!(
            "step {} periods {}: |X1| {:.3e} sX1 {:.2e} |Xd1| {:.3e} sXd1 {:.2e} Z_I(w) {:.1} Z_I(3w) {:.1} |G1| {:.2} sG1 {:.4} sF1 {:.4} sXd1*|Z| {:.4} k*sX1 {:.4} c w|X1| {:.3} nx {}",
            an.step,
            an.periods_used,
            eh.displacement[1].norm(),
            eh.displacement_noise[1],
            xd.phasors[1].norm(),
            xd.noise_std[1],
            z1,
            z3,
            eh.force[1].norm(),
            eh.force_noise[1],
            f.noise_std[1],
            xd.noise_std[1] * z1.norm(),
            8000.0 * eh.displacement_noise[1],
            20.0 * w * eh.displacement[1].norm(),
            (1..eh.displacement.len())
                .rev()
                .find(|&n| eh.displacement[n].norm() > 3.0 * eh.displacement_noise[n])
                .unwrap_or(1)
        );
        let gn: Vec<String> = (0..8)
            .map(|n| format!("{n}:{:.3}/{:.4}", eh.force[n].norm(), eh.force_noise[n]))
            .collect();
        println!("   G harmonics |G_n|/noise: {gn:?}");
    }
}

/// Table 1 as `forcemap reproduce --tables 1` computes it (seed 1, 40 dB), one line per row.
#[test]
#[ignore]
fn table1_rows() {
    let rows =
        forcemap_eval::reproduce::table1(&forcemap_eval::reproduce::Settings::default(), |_| {})
            .unwrap();
    for r in rows {
        println!(
            "{} {} {:?} {} {:?} snr {:?}: k {:?} c {:?} fd {:?} s {:?}",
            r.case.unwrap_or_default(),
            r.model,
            r.atan_m,
            r.source,
            r.method,
            r.snr_db,
            r.k,
            r.c,
            r.fd,
            r.s
        );
    }
}
