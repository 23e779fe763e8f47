//! `forcemap simulate`: a test-bench CSV export or a bag from the simulators, with effects
//! planted in the truth model if asked.

use anyhow::bail;
use forcemap_math::phasor::SweepKind;
use forcemap_math::record::Record;
use forcemap_math::sim::{
    AsymmetricDamping, BoucWen, FreePlay, RigEffects, RunSpec, ThreeDofCase, TruthElement,
};

use crate::cli::{CaseArg, EffectArgs, ExcitationArg, SimulateArgs, SweepKindArg, SystemArg};
use forcemap_io::csv_export::write_csv;
use forcemap_io::rig_bag::{DEFAULT_RUN_START, write_rig_bag};

/// The truth element with the planted element effects.
fn planted_element(mut element: TruthElement, e: &EffectArgs) -> anyhow::Result<TruthElement> {
    let finite = |name: &str, v: Option<f64>| -> anyhow::Result<Option<f64>> {
        match v {
            Some(x) if !x.is_finite() => bail!("--{name} = {x}: not a finite number"),
            other => Ok(other),
        }
    };
    if let Some(s) = finite("cubic-stiffness-n-per-m3", e.cubic_stiffness_n_per_m3)? {
        element.cubic_stiffness_n_per_m3 = s;
    }
    if let Some(k2) = finite(
        "quadratic-stiffness-n-per-m2",
        e.quadratic_stiffness_n_per_m2,
    )? {
        element.quadratic_stiffness_n_per_m2 = k2;
    }
    if let Some(c2) = finite(
        "quadratic-damping-n-s2-per-m2",
        e.quadratic_damping_n_s2_per_m2,
    )? {
        element.quadratic_damping_n_s2_per_m2 = c2;
    }
    if let Some(extra) = finite("stribeck-breakaway-n", e.stribeck_breakaway_n)? {
        let Some(f) = element.friction.as_mut() else {
            bail!(
                "--stribeck-breakaway-n: this element has no Coulomb friction to add a Stribeck peak to"
            );
        };
        if extra < 0.0 || e.stribeck_velocity_mps.is_nan() || e.stribeck_velocity_mps <= 0.0 {
            bail!("--stribeck-breakaway-n must be >= 0 and --stribeck-velocity-mps > 0");
        }
        f.breakaway_n = f.kinetic_n + extra;
        f.stribeck_velocity_mps = e.stribeck_velocity_mps;
    }
    // Planted on top of what the element has (the dyno's damper is asymmetric already).
    if let Some(a) = asymmetric_damping(element.damping_n_s_per_m, e)? {
        element.asymmetric_damping = Some(a);
    }
    if let Some(f) = free_play(e)? {
        element.free_play = Some(f);
    }
    if let Some(b) = bouc_wen(e)? {
        element.bouc_wen = Some(b);
    }
    Ok(element)
}

/// `--rebound-damping-n-s-per-m` / `--compression-damping-n-s-per-m`: extra damping on either
/// side, the other side 0 when only one is given. The total damping `c + extra` must stay >= 0
/// on both sides (a negative total would feed energy into the rig).
fn asymmetric_damping(c: f64, e: &EffectArgs) -> anyhow::Result<Option<AsymmetricDamping>> {
    let (r, k) = (e.rebound_damping_n_s_per_m, e.compression_damping_n_s_per_m);
    if r.is_none() && k.is_none() {
        return Ok(None);
    }
    let mut sides = [0.0; 2];
    for (slot, (name, v)) in sides.iter_mut().zip([
        ("rebound-damping-n-s-per-m", r),
        ("compression-damping-n-s-per-m", k),
    ]) {
        let Some(x) = v else { continue };
        if !x.is_finite() {
            bail!("--{name} = {x}: not a finite number");
        }
        if c + x < 0.0 {
            bail!(
                "--{name} = {x}: the element's damping is {c} N s/m, so the total {} N s/m would be \
                 negative (it must be >= 0)",
                c + x
            );
        }
        *slot = x;
    }
    Ok(Some(AsymmetricDamping {
        rebound_n_s_per_m: sides[0],
        compression_n_s_per_m: sides[1],
    }))
}

/// `--free-play-gap-m` with `--free-play-stiffness-n-per-m`.
fn free_play(e: &EffectArgs) -> anyhow::Result<Option<FreePlay>> {
    match (e.free_play_gap_m, e.free_play_stiffness_n_per_m) {
        (None, None) => Ok(None),
        (Some(gap), Some(k)) => {
            if !(gap.is_finite() && gap >= 0.0) {
                bail!("--free-play-gap-m = {gap}: must be a width >= 0 m");
            }
            if !(k.is_finite() && k > 0.0) {
                bail!("--free-play-stiffness-n-per-m = {k}: must be a stiffness > 0 N/m");
            }
            Ok(Some(FreePlay {
                gap_m: gap,
                stiffness_n_per_m: k,
            }))
        }
        _ => bail!("free-play needs both --free-play-gap-m and --free-play-stiffness-n-per-m"),
    }
}

/// `--bouc-wen-*`: alpha, beta and gamma are needed; a and n default to 1. Refused unless z
/// stays bounded (Ikhouane, Manosa and Rodellar 2007: a > 0, beta + gamma > 0,
/// beta - gamma >= 0) and n > 0.
fn bouc_wen(e: &EffectArgs) -> anyhow::Result<Option<BoucWen>> {
    let others = [
        ("bouc-wen-a", e.bouc_wen_a),
        ("bouc-wen-beta-per-m-pow-n", e.bouc_wen_beta_per_m_pow_n),
        ("bouc-wen-gamma-per-m-pow-n", e.bouc_wen_gamma_per_m_pow_n),
        ("bouc-wen-n", e.bouc_wen_n),
    ];
    let Some(alpha) = e.bouc_wen_alpha_n_per_m else {
        if let Some((name, _)) = others.iter().find(|(_, v)| v.is_some()) {
            bail!("--{name} needs --bouc-wen-alpha-n-per-m (the hysteretic stiffness)");
        }
        return Ok(None);
    };
    for (name, v) in [("bouc-wen-alpha-n-per-m", Some(alpha))]
        .iter()
        .chain(&others)
    {
        if let Some(x) = v
            && !x.is_finite()
        {
            bail!("--{name} = {x}: not a finite number");
        }
    }
    let (Some(beta), Some(gamma)) = (e.bouc_wen_beta_per_m_pow_n, e.bouc_wen_gamma_per_m_pow_n)
    else {
        bail!(
            "--bouc-wen-alpha-n-per-m needs --bouc-wen-beta-per-m-pow-n and \
             --bouc-wen-gamma-per-m-pow-n"
        );
    };
    let a = e.bouc_wen_a.unwrap_or(1.0);
    let n = e.bouc_wen_n.unwrap_or(1.0);
    if alpha <= 0.0 {
        bail!("--bouc-wen-alpha-n-per-m = {alpha}: must be a stiffness > 0 N/m");
    }
    if a <= 0.0 {
        bail!("--bouc-wen-a = {a}: must be > 0");
    }
    if n <= 0.0 {
        bail!("--bouc-wen-n = {n}: must be > 0");
    }
    if !(beta + gamma > 0.0 && beta - gamma >= 0.0) {
        bail!(
            "Bouc-Wen beta = {beta}, gamma = {gamma}: z stays bounded only for beta + gamma > 0 \
             and beta >= gamma"
        );
    }
    Ok(Some(BoucWen {
        alpha_n_per_m: alpha,
        a,
        beta,
        gamma,
        n,
    }))
}

/// The planted effects as `/rig/parameters` entries `planted.<flag>` (the flag's name with
/// underscores), values as simulated (Bouc-Wen a and n with their defaults filled in).
fn planted_parameters(e: &EffectArgs) -> Vec<(String, f64)> {
    let stribeck = e.stribeck_breakaway_n.map(|_| e.stribeck_velocity_mps);
    let bw = |v: Option<f64>| e.bouc_wen_alpha_n_per_m.map(|_| v.unwrap_or(1.0));
    [
        ("cubic_stiffness_n_per_m3", e.cubic_stiffness_n_per_m3),
        (
            "quadratic_stiffness_n_per_m2",
            e.quadratic_stiffness_n_per_m2,
        ),
        (
            "quadratic_damping_n_s2_per_m2",
            e.quadratic_damping_n_s2_per_m2,
        ),
        ("stribeck_breakaway_n", e.stribeck_breakaway_n),
        ("stribeck_velocity_mps", stribeck),
        ("exciter_delay_s", e.exciter_delay_s),
        ("sensor_lowpass_hz", e.sensor_lowpass_hz),
        ("mass_factor", e.mass_factor),
        ("rebound_damping_n_s_per_m", e.rebound_damping_n_s_per_m),
        (
            "compression_damping_n_s_per_m",
            e.compression_damping_n_s_per_m,
        ),
        ("free_play_gap_m", e.free_play_gap_m),
        ("free_play_stiffness_n_per_m", e.free_play_stiffness_n_per_m),
        ("bouc_wen_alpha_n_per_m", e.bouc_wen_alpha_n_per_m),
        ("bouc_wen_a", bw(e.bouc_wen_a)),
        ("bouc_wen_beta_per_m_pow_n", e.bouc_wen_beta_per_m_pow_n),
        ("bouc_wen_gamma_per_m_pow_n", e.bouc_wen_gamma_per_m_pow_n),
        ("bouc_wen_n", bw(e.bouc_wen_n)),
    ]
    .into_iter()
    .filter_map(|(k, v)| v.map(|v| (format!("planted.{k}"), v)))
    .collect()
}

/// The planted rig-level effects.
fn planted_rig_effects(e: &EffectArgs) -> anyhow::Result<RigEffects> {
    let mut fx = RigEffects::default();
    if let Some(d) = e.exciter_delay_s {
        if !(d >= 0.0 && d.is_finite()) {
            bail!("--exciter-delay-s = {d}: must be a delay >= 0 s");
        }
        fx.exciter_delay_s = d;
    }
    if let Some(fc) = e.sensor_lowpass_hz {
        if !(fc > 0.0 && fc.is_finite()) {
            bail!("--sensor-lowpass-hz = {fc}: must be a cutoff > 0 Hz");
        }
        fx.sensor_lowpass_hz = Some(fc);
    }
    if let Some(m) = e.mass_factor {
        if !(m > 0.0 && m.is_finite()) {
            bail!("--mass-factor = {m}: must be > 0");
        }
        fx.mass_factor = m;
    }
    Ok(fx)
}

/// The excitations `forcemap simulate` knows for `system`, refused by name otherwise.
fn check_excitation(args: &SimulateArgs) -> anyhow::Result<()> {
    let name = match args.excitation {
        ExcitationArg::Stepped => return Ok(()),
        ExcitationArg::Multisine => "multisine",
        ExcitationArg::Sweep => "sweep",
        ExcitationArg::Random => "random",
    };
    let systems = match args.excitation {
        ExcitationArg::Multisine => "--system shaker-sdof",
        ExcitationArg::Sweep => "--system rig, damper-dyno and shaker-sdof",
        _ => "--system rig",
    };
    let known = matches!(
        (args.excitation, args.system),
        (ExcitationArg::Multisine, SystemArg::ShakerSdof)
            | (
                ExcitationArg::Sweep,
                SystemArg::Rig | SystemArg::DamperDyno | SystemArg::ShakerSdof
            )
            | (ExcitationArg::Random, SystemArg::Rig)
    );
    if !known {
        bail!("--excitation {name} is simulated for {systems} only");
    }
    Ok(())
}

pub fn run(args: &SimulateArgs) -> anyhow::Result<()> {
    check_excitation(args)?;
    let sweep_kind = match args.sweep_kind {
        SweepKindArg::Linear => SweepKind::Linear,
        SweepKindArg::Log => SweepKind::Logarithmic,
    };
    let spec = match args.system {
        SystemArg::Rig => {
            let spec = match args.excitation {
                ExcitationArg::Sweep => {
                    RunSpec::rig_sweep(sweep_kind, !args.no_random, args.snr_db, args.seed)
                }
                ExcitationArg::Random => RunSpec::rig_random(args.snr_db, args.seed),
                _ if args.no_random => RunSpec::paper_rig_sine(args.snr_db, args.seed),
                _ => RunSpec::paper_rig(args.snr_db, args.seed),
            };
            let element = planted_element(spec.element.clone(), &args.effects)?;
            spec.with_element(element)
                .with_effects(planted_rig_effects(&args.effects)?)
        }
        system => {
            let e = &args.effects;
            if e.exciter_delay_s.is_some()
                || e.sensor_lowpass_hz.is_some()
                || e.mass_factor.is_some()
            {
                bail!(
                    "--exciter-delay-s, --sensor-lowpass-hz and --mass-factor apply to the rig (--system rig) only"
                );
            }
            let spec = match (system, args.excitation) {
                (SystemArg::DamperDyno, ExcitationArg::Sweep) => {
                    RunSpec::damper_dyno_sweep(sweep_kind, args.snr_db, args.seed)
                }
                (SystemArg::DamperDyno, _) => RunSpec::damper_dyno(args.snr_db, args.seed),
                (SystemArg::ShakerSdof, ExcitationArg::Multisine) => {
                    RunSpec::shaker_sdof_multisine(args.snr_db, args.seed)
                }
                (SystemArg::ShakerSdof, ExcitationArg::Sweep) => {
                    RunSpec::shaker_sdof_sweep(sweep_kind, args.snr_db, args.seed)
                }
                (SystemArg::ShakerSdof, _) => RunSpec::shaker_sdof(args.snr_db, args.seed),
                _ => {
                    let case = match args.case {
                        CaseArg::I => ThreeDofCase::I,
                        CaseArg::Ii => ThreeDofCase::Ii,
                    };
                    RunSpec::three_dof(case, args.snr_db, args.seed)
                }
            };
            let element = planted_element(spec.element.clone(), e)?;
            spec.with_element(element)
        }
    };
    // The shaker's mass is what its run is for identifying: its bag does not give it.
    let carried_mass_kg = match args.system {
        SystemArg::ShakerSdof => None,
        _ => spec.mass_kg(),
    };
    let profile = spec.setup_kind();
    let records = spec.simulate()?;
    let what = format!(
        "{} records, {} samples, {} profile",
        records.len(),
        records.iter().map(Record::len).sum::<usize>(),
        profile
    );
    if let Some(csv) = &args.csv {
        write_csv(csv, &records, profile)?;
        eprintln!("wrote {} ({what})", csv.display());
    }
    if let Some(bag) = &args.bag {
        let mut parameters: Vec<(String, f64)> = carried_mass_kg
            .map(|m| ("mass_kg".to_string(), m))
            .into_iter()
            .collect();
        parameters.extend(planted_parameters(&args.effects));
        let parameters: Vec<(&str, f64)> =
            parameters.iter().map(|(k, v)| (k.as_str(), *v)).collect();
        let dir = write_rig_bag(
            bag,
            &records,
            spec.driven_channel(),
            &parameters,
            DEFAULT_RUN_START,
        )?;
        eprintln!("wrote {} ({what})", dir.display());
    }
    Ok(())
}
