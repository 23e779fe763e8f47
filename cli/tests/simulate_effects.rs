//! `forcemap simulate` with the planted asymmetric damping, free-play and Bouc-Wen flags: the
//! output against the truth simulator, closed forms of what `identify` must then find, the
//! validation of the flags, and the planted values recorded on the bag's /rig/parameters.
//! (The older effect flags are tested in tests/cli.rs.)
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use std::path::{Path, PathBuf};

use common::{forcemap, stderr};
use forcemap_io::csv_export::write_csv;
use forcemap_io::rig_bag::read_rig_bag;
use forcemap_math::recipe::SetupKind;
use forcemap_math::sim::{AsymmetricDamping, BoucWen, FreePlay, RunSpec, TruthElement};

/// `forcemap simulate --no-random ARGS --csv DIR/NAME.csv`; panics unless it succeeds.
fn simulate(dir: &Path, name: &str, args: &[&str]) -> PathBuf {
    let csv = dir.join(format!("{name}.csv"));
    let mut all = vec!["simulate", "--no-random"];
    all.extend_from_slice(args);
    all.extend_from_slice(&["--csv", csv.to_str().unwrap()]);
    let o = forcemap(&all);
    assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    csv
}

/// k, c, F_d of the Coulomb model, fitted with the nominal 36 kg.
fn coulomb(csv: &Path) -> [f64; 3] {
    let v = common::identified_values(csv, &["--model", "coulomb", "--mass-kg", "36"]);
    [v[0], v[1], v[2]]
}

fn relative_displacements(csv: &Path) -> Vec<f64> {
    let mut r = csv::Reader::from_path(csv).unwrap();
    let col = r
        .headers()
        .unwrap()
        .iter()
        .position(|h| h == "relative_displacement_m")
        .unwrap();
    r.records()
        .map(|row| row.unwrap()[col].parse().unwrap())
        .collect()
}

#[test]
fn the_flags_plant_exactly_the_truth_elements_terms() {
    // Every parameter differs from the others (and beta from gamma, rebound from compression),
    // so a flag wired to the wrong field gives a different record.
    let dir = tempfile::tempdir().unwrap();
    let cli = simulate(
        dir.path(),
        "cli",
        &[
            "--rebound-damping-n-s-per-m",
            "90",
            "--compression-damping-n-s-per-m",
            "-30",
            "--free-play-gap-m",
            "0.003",
            "--free-play-stiffness-n-per-m",
            "1500",
            "--bouc-wen-alpha-n-per-m",
            "20000",
            "--bouc-wen-a",
            "1.5",
            "--bouc-wen-beta-per-m-pow-n",
            "900",
            "--bouc-wen-gamma-per-m-pow-n",
            "-300",
            "--bouc-wen-n",
            "1.2",
        ],
    );
    let element = TruthElement {
        asymmetric_damping: Some(AsymmetricDamping {
            rebound_n_s_per_m: 90.0,
            compression_n_s_per_m: -30.0,
        }),
        free_play: Some(FreePlay {
            gap_m: 0.003,
            stiffness_n_per_m: 1500.0,
        }),
        bouc_wen: Some(BoucWen {
            alpha_n_per_m: 20000.0,
            a: 1.5,
            beta: 900.0,
            gamma: -300.0,
            n: 1.2,
        }),
        ..TruthElement::rig_coulomb()
    };
    let run = RunSpec::paper_rig_sine(None, 1).with_element(element.clone());
    let truth = dir.path().join("truth.csv");
    write_csv(&truth, &run.simulate().unwrap(), SetupKind::BaseExcited).unwrap();
    let cli_text = std::fs::read_to_string(&cli).unwrap();
    assert!(
        cli_text == std::fs::read_to_string(&truth).unwrap(),
        "the CLI's record differs from the truth simulator's with the same element"
    );
    // ... and the planted terms matter: without them the record is another one.
    let plain = simulate(dir.path(), "plain", &[]);
    assert_ne!(cli_text, std::fs::read_to_string(plain).unwrap());
}

#[test]
fn asymmetric_damping_adds_the_mean_of_both_sides_to_the_fitted_damping() {
    // c v + dr v (v > 0) + dc v (v < 0) = (c + (dr + dc)/2) v + (dr - dc)/2 |v|; |v| of a
    // sine is even (DC and even harmonics), orthogonal to the Coulomb model's odd regressors,
    // so the fit sees c + (dr + dc)/2 and the same k and F_d.
    let dir = tempfile::tempdir().unwrap();
    let base = coulomb(&simulate(dir.path(), "base", &[]));
    let asym = coulomb(&simulate(
        dir.path(),
        "asym",
        &[
            "--rebound-damping-n-s-per-m",
            "100",
            "--compression-damping-n-s-per-m",
            "20",
        ],
    ));
    assert!(
        (asym[1] - (base[1] + 60.0)).abs() < 0.01 * 60.0,
        "c {} (base {})",
        asym[1],
        base[1]
    );
    assert!((asym[0] / base[0] - 1.0).abs() < 0.01, "{asym:?} {base:?}");
    assert!((asym[2] / base[2] - 1.0).abs() < 0.01, "{asym:?} {base:?}");
}

#[test]
fn free_play_is_a_spring_without_gap_and_nothing_when_the_gap_is_never_closed() {
    let dir = tempfile::tempdir().unwrap();
    let base_csv = simulate(dir.path(), "base", &[]);
    let base = coulomb(&base_csv);
    // gap 0: k (x - sgn(x) 0) is a linear spring: the fitted k grows by exactly it
    let fp = coulomb(&simulate(
        dir.path(),
        "gap0",
        &[
            "--free-play-gap-m",
            "0",
            "--free-play-stiffness-n-per-m",
            "2000",
        ],
    ));
    assert!((fp[0] - (base[0] + 2000.0)).abs() < 2.0, "{fp:?} {base:?}");
    assert!((fp[1] / base[1] - 1.0).abs() < 0.001 && (fp[2] / base[2] - 1.0).abs() < 0.001);

    // The gap is the total width: the spring engages at |x| = gap/2. With gap/2 just above the
    // largest |x| of the run it never does (the record is the plain one, to round-off: the
    // plain linear element is stepped by the simulator's linear fast path, the free-play one by
    // the general RK4, the same step in another order of operations); just below, it does.
    // (2 % above: between the 100 Hz samples |x| peaks up to (w h)^2/8 = 0.3 % higher than the
    // largest sample at the step of the largest amplitude, 2.6 Hz.)
    let base_x = relative_displacements(&base_csv);
    let peak = base_x.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    assert!(peak > 1e-3, "peak |x| {peak}");
    for (factor, engaged) in [(1.02, false), (0.98, true)] {
        let gap = format!("{}", 2.0 * peak * factor);
        let csv = simulate(
            dir.path(),
            &format!("gap{factor}"),
            &[
                "--free-play-gap-m",
                &gap,
                "--free-play-stiffness-n-per-m",
                "50000",
            ],
        );
        let x = relative_displacements(&csv);
        let largest_difference = x
            .iter()
            .zip(&base_x)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        let same = largest_difference < 1e-9 * peak;
        assert_eq!(
            same, !engaged,
            "gap {gap} m, peak |x| {peak} m, largest difference {largest_difference:e} m"
        );
        if engaged {
            assert!(largest_difference > 1e-6 * peak, "{largest_difference:e}");
        }
    }
}

#[test]
fn bouc_wen_far_below_its_yield_is_a_spring_of_alpha_times_a() {
    // beta = gamma = 1 /m: z yields at a/(beta + gamma) = 1 m, 100 times the largest |x| of the
    // run; below it z' = a x' (1 - O(z)) and the force alpha z = alpha a x.
    let dir = tempfile::tempdir().unwrap();
    let base = coulomb(&simulate(dir.path(), "base", &[]));
    let bw = coulomb(&simulate(
        dir.path(),
        "bw",
        &[
            "--bouc-wen-alpha-n-per-m",
            "1000",
            "--bouc-wen-a",
            "2",
            "--bouc-wen-beta-per-m-pow-n",
            "1",
            "--bouc-wen-gamma-per-m-pow-n",
            "1",
        ],
    ));
    assert!(
        (bw[0] - (base[0] + 2000.0)).abs() < 0.01 * 2000.0,
        "{bw:?} {base:?}"
    );
    assert!((bw[1] / base[1] - 1.0).abs() < 0.01 && (bw[2] / base[2] - 1.0).abs() < 0.02);
}

#[test]
fn bad_effect_values_are_refused_with_the_flag_named() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("x.csv");
    let cases: &[(&[&str], &str)] = &[
        (
            &["--rebound-damping-n-s-per-m", "NaN"],
            "--rebound-damping-n-s-per-m = NaN",
        ),
        // the rig's element has c = 184 N s/m: -200 would make the total negative
        (&["--compression-damping-n-s-per-m", "-200"], "negative"),
        (
            &["--free-play-gap-m", "0.001"],
            "both --free-play-gap-m and --free-play-stiffness",
        ),
        (
            &[
                "--free-play-gap-m",
                "-0.001",
                "--free-play-stiffness-n-per-m",
                "100",
            ],
            "--free-play-gap-m = -0.001",
        ),
        (
            &[
                "--free-play-gap-m",
                "0.001",
                "--free-play-stiffness-n-per-m",
                "inf",
            ],
            "--free-play-stiffness-n-per-m = inf",
        ),
        (
            &["--bouc-wen-beta-per-m-pow-n", "10"],
            "needs --bouc-wen-alpha-n-per-m",
        ),
        (
            &[
                "--bouc-wen-alpha-n-per-m",
                "1000",
                "--bouc-wen-beta-per-m-pow-n",
                "10",
            ],
            "needs --bouc-wen-beta-per-m-pow-n and --bouc-wen-gamma-per-m-pow-n",
        ),
        (
            &[
                "--bouc-wen-alpha-n-per-m",
                "1000",
                "--bouc-wen-beta-per-m-pow-n",
                "10",
                "--bouc-wen-gamma-per-m-pow-n",
                "20",
            ],
            "beta >= gamma",
        ),
        (
            &[
                "--bouc-wen-alpha-n-per-m",
                "1000",
                "--bouc-wen-beta-per-m-pow-n",
                "10",
                "--bouc-wen-gamma-per-m-pow-n",
                "5",
                "--bouc-wen-n",
                "0",
            ],
            "--bouc-wen-n = 0",
        ),
        (
            &[
                "--bouc-wen-alpha-n-per-m",
                "-1000",
                "--bouc-wen-beta-per-m-pow-n",
                "10",
                "--bouc-wen-gamma-per-m-pow-n",
                "5",
            ],
            "--bouc-wen-alpha-n-per-m = -1000",
        ),
    ];
    for (flags, expected) in cases {
        let mut args = vec!["simulate", "--no-random"];
        args.extend_from_slice(flags);
        args.extend_from_slice(&["--csv", csv.to_str().unwrap()]);
        let o = forcemap(&args);
        assert_eq!(o.status.code(), Some(1), "{flags:?} was accepted");
        assert!(stderr(&o).contains(expected), "{flags:?}: {}", stderr(&o));
        assert!(!csv.exists(), "{flags:?} left a file");
    }
}

#[test]
fn the_bag_records_the_planted_effects_on_rig_parameters() {
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("rig");
    let o = forcemap(&[
        "simulate",
        "--no-random",
        "--free-play-gap-m",
        "0.002",
        "--free-play-stiffness-n-per-m",
        "1500",
        "--bouc-wen-alpha-n-per-m",
        "1000",
        "--bouc-wen-beta-per-m-pow-n",
        "30",
        "--bouc-wen-gamma-per-m-pow-n",
        "10",
        "--rebound-damping-n-s-per-m",
        "40",
        "--mass-factor",
        "1.05",
        "--bag",
        bag.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let p = read_rig_bag(&bag).unwrap().parameters;
    let expected = [
        ("mass_kg", 36.0),
        ("planted.free_play_gap_m", 0.002),
        ("planted.free_play_stiffness_n_per_m", 1500.0),
        ("planted.bouc_wen_alpha_n_per_m", 1000.0),
        ("planted.bouc_wen_a", 1.0),
        ("planted.bouc_wen_beta_per_m_pow_n", 30.0),
        ("planted.bouc_wen_gamma_per_m_pow_n", 10.0),
        ("planted.bouc_wen_n", 1.0),
        ("planted.rebound_damping_n_s_per_m", 40.0),
        ("planted.mass_factor", 1.05),
    ];
    let got: Vec<(&str, f64)> = p.iter().map(|(k, v)| (k.as_str(), *v)).collect();
    let mut want = expected.to_vec();
    want.sort_by(|a, b| a.0.cmp(b.0));
    assert_eq!(got, want);

    // 3-DOF: no rig constants, but the planted effects are recorded.
    let bag = dir.path().join("three_dof");
    let o = forcemap(&[
        "simulate",
        "--system",
        "three-dof",
        "--compression-damping-n-s-per-m",
        "5",
        "--bag",
        bag.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let p = read_rig_bag(&bag).unwrap().parameters;
    assert_eq!(
        p.into_iter().collect::<Vec<_>>(),
        [("planted.compression_damping_n_s_per_m".to_string(), 5.0)]
    );
}
