//! Reproduction of the paper's Tables 1-4: the paper's numbers, the truth, and forcemap's
//! numbers (the paper's first-harmonic method and the improved method) side by side.
//!
//! Table 1 uses the 3-DOF example simulated exactly (stick-slip included). Tables 2-4 use a
//! simulated stand-in for the paper's physical rig: its identified Coulomb values as the truth
//! plus sensor noise, so forcemap's numbers there are checked against a known truth rather
//! than against the paper's measurements.

use serde::Serialize;

use forcemap_math::frf::LinearSubstructure;
use forcemap_math::identify::{FdMultiOptions, Identification, Method};
use forcemap_math::model::{IdentifiedModel, Model, ModelOptions};
use forcemap_math::phasor::PhasorOptions;
use forcemap_math::pipeline::{self, PipelineError};
use forcemap_math::recipe::Setup;
use forcemap_math::record::Record;
use forcemap_math::sim::{self, RunSpec, SimError, ThreeDofCase, TruthElement};

use crate::paper::{self, PaperRow};

/// One row of a reproduced table.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    pub table: u8,
    pub case: Option<String>,
    pub model: String,
    pub atan_m: Option<f64>,
    pub method: Option<String>,
    /// "paper", "truth" or "forcemap".
    pub source: &'static str,
    /// Measurement SNR of forcemap's data [dB]; None = noise-free (or not forcemap's).
    pub snr_db: Option<f64>,
    pub k: Option<f64>,
    pub c: Option<f64>,
    pub fd: Option<f64>,
    pub s: Option<f64>,
    pub nmse1: Option<f64>,
    pub nmse2: Option<f64>,
    /// r values [%] (Table 2).
    pub r: Option<Vec<(String, f64)>>,
    /// Standard deviations of k, c, fd, s where forcemap estimated them.
    pub std: Option<Vec<(String, f64)>>,
}

#[derive(Debug, thiserror::Error)]
pub enum ReproduceError {
    #[error("simulating {what}: {source}")]
    Sim { what: String, source: SimError },
    #[error("{what}: {source}")]
    Pipeline { what: String, source: PipelineError },
}

/// Settings of a reproduction.
#[derive(Debug, Clone, Copy)]
pub struct Settings {
    /// SNR of the noisy 3-DOF variant (the paper's Table 1 is noise-free).
    pub three_dof_snr_db: f64,
    /// SNR of the rig stand-in's sensors.
    pub rig_snr_db: f64,
    pub seed: u64,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            three_dof_snr_db: 40.0,
            rig_snr_db: 40.0,
            seed: 1,
        }
    }
}

fn paper_row(p: &PaperRow) -> Row {
    Row {
        table: p.table,
        case: p.case.map(String::from),
        model: p.model.into(),
        atan_m: p.atan_m,
        method: Some(if p.table == 4 {
            "td-20".into()
        } else {
            "fd".into()
        }),
        source: "paper",
        snr_db: None,
        k: Some(p.k),
        c: Some(p.c),
        fd: p.fd,
        s: p.s,
        nmse1: p.nmse1,
        nmse2: p.nmse2,
        r: None,
        std: None,
    }
}

fn truth_row(
    table: u8,
    case: Option<&str>,
    model: &str,
    [k, c, fd]: [f64; 3],
    s: Option<f64>,
) -> Row {
    Row {
        table,
        case: case.map(String::from),
        model: model.into(),
        atan_m: None,
        method: None,
        source: "truth",
        snr_db: None,
        k: Some(k),
        c: Some(c),
        fd: Some(fd),
        s,
        nmse1: None,
        nmse2: None,
        r: None,
        std: None,
    }
}

fn forcemap_row(
    table: u8,
    case: Option<&str>,
    atan_m: Option<f64>,
    snr_db: Option<f64>,
    id: &Identification,
) -> Row {
    let pick = |n: &str| id.value(n);
    Row {
        table,
        case: case.map(String::from),
        model: id.model.clone(),
        atan_m,
        method: Some(id.method.clone()),
        source: "forcemap",
        snr_db,
        k: pick("k"),
        c: pick("c"),
        fd: pick("fd"),
        s: pick("s"),
        nmse1: None,
        nmse2: None,
        r: Some(id.r.clone()),
        std: Some(
            id.parameters
                .iter()
                .map(|p| (p.name.clone(), p.std))
                .collect(),
        ),
    }
}

fn simulate(spec: &RunSpec, what: &str) -> Result<Vec<Record>, ReproduceError> {
    spec.simulate().map_err(|source| ReproduceError::Sim {
        what: what.into(),
        source,
    })
}

fn model(name: &str, atan_m: Option<f64>) -> Model {
    Model::by_name(
        name,
        &ModelOptions {
            atan_slope_s_per_m: atan_m,
            polynomial_order: None,
        },
    )
    .expect("the tables use known models")
}

/// Phasor options of the reproduction: as many harmonics as the sampling allows.
pub fn phasor_options() -> PhasorOptions {
    PhasorOptions {
        max_harmonic: usize::MAX,
        ..PhasorOptions::default()
    }
}

/// Table 1: the 3-DOF example, CASE I and II, three friction models, the paper's method and the
/// improved one, noise-free and at `three_dof_snr_db`.
pub fn table1(
    settings: &Settings,
    mut progress: impl FnMut(&str),
) -> Result<Vec<Row>, ReproduceError> {
    let setup = Setup::DrivePoint {
        substructure: LinearSubstructure::paper_three_dof_substructure_i(),
    };
    let models: [(&str, Option<f64>); 3] = [
        ("coulomb-cubic", None),
        ("coulomb-atan-cubic", Some(1e5)),
        ("coulomb-atan-cubic", Some(1e3)),
    ];
    let (k, c, fd, s) = paper::TABLE1_TRUTH;
    let mut rows = Vec::new();
    for (case, which) in [("I", ThreeDofCase::I), ("II", ThreeDofCase::Ii)] {
        progress(&format!(
            "Table 1, CASE {case}: simulating the 3-DOF example"
        ));
        let clean = simulate(
            &RunSpec::three_dof(which, None, 0),
            &format!("3-DOF CASE {case}"),
        )?;
        let noisy = simulate(
            &RunSpec::three_dof(which, Some(settings.three_dof_snr_db), settings.seed),
            &format!("3-DOF CASE {case} with noise"),
        )?;
        rows.push(truth_row(
            1,
            Some(case),
            "coulomb-cubic",
            [k, c, fd],
            Some(s),
        ));
        for (name, m) in models {
            if let Some(p) = paper::TABLE1
                .iter()
                .find(|p| p.case == Some(case) && p.model == name && p.atan_m == m)
            {
                rows.push(paper_row(p));
            }
            let mdl = model(name, m);
            let mut runs = vec![
                (Method::Fd, &clean, None),
                (Method::FdMulti, &clean, None),
                (Method::FdMulti, &noisy, Some(settings.three_dof_snr_db)),
            ];
            // The output-error refinement simulates the element exactly: sgn friction only.
            if name == "coulomb-cubic" {
                runs.push((Method::OutputError, &clean, None));
                runs.push((Method::OutputError, &noisy, Some(settings.three_dof_snr_db)));
            }
            for (method, data, snr) in runs {
                progress(&format!("Table 1, CASE {case}: {name} {}", method.name()));
                let what = format!("Table 1 CASE {case} {name} {}", method.name());
                let id = pipeline::identify_records(
                    &mdl,
                    &setup,
                    method,
                    data,
                    &phasor_options(),
                    &FdMultiOptions::default(),
                )
                .map_err(|source| ReproduceError::Pipeline { what, source })?;
                rows.push(forcemap_row(1, Some(case), m, snr, &id));
            }
        }
    }
    Ok(rows)
}

/// The rig stand-in's data: the stepped-sine run and the two band-random validation runs.
pub struct RigData {
    pub sine: Vec<Record>,
    pub random: [Vec<Record>; 2],
}

/// Simulates the rig stand-in (truth: the paper's Coulomb values) at `snr_db`.
pub fn rig_data(
    truth: TruthElement,
    snr_db: Option<f64>,
    seed: u64,
) -> Result<RigData, ReproduceError> {
    let sine = simulate(
        &RunSpec::paper_rig_sine(snr_db, seed).with_element(truth.clone()),
        "rig stepped sine",
    )?;
    let mut random = [Vec::new(), Vec::new()];
    for (i, band) in sim::excitation::PAPER_RIG_RANDOM_BANDS_HZ
        .iter()
        .enumerate()
    {
        let run = RunSpec::paper_rig_random(*band, snr_db, seed + 1 + i as u64)
            .with_element(truth.clone());
        random[i] = simulate(&run, "rig band random")?;
    }
    Ok(RigData { sine, random })
}

/// Identifies on the rig's sine steps and validates on both random records.
pub fn rig_row(
    table: u8,
    data: &RigData,
    name: &str,
    atan_m: Option<f64>,
    method: Method,
    snr_db: Option<f64>,
) -> Result<Row, ReproduceError> {
    let setup = Setup::BaseExcited {
        mass_kg: sim::rig::PAPER_RIG_MASS_KG,
    };
    let mdl = model(name, atan_m);
    let what = format!("Table {table} {name} {}", method.name());
    let wrap = |source| ReproduceError::Pipeline {
        what: what.clone(),
        source,
    };
    let id = pipeline::identify_records(
        &mdl,
        &setup,
        method,
        &data.sine,
        &phasor_options(),
        &FdMultiOptions::default(),
    )
    .map_err(wrap)?;
    let fitted = IdentifiedModel::new(mdl, id.theta());
    let mut row = forcemap_row(table, None, atan_m, snr_db, &id);
    let nmse = |recs: &Vec<Record>| -> Result<f64, ReproduceError> {
        pipeline::validate_rig(&fitted, sim::rig::PAPER_RIG_MASS_KG, &recs[0])
            .map(|v| v.nmse_percent)
            .map_err(wrap)
    };
    row.nmse1 = Some(nmse(&data.random[0])?);
    row.nmse2 = Some(nmse(&data.random[1])?);
    Ok(row)
}

/// Tables 2-4 on the rig stand-in.
pub fn rig_tables(
    tables: &[u8],
    settings: &Settings,
    mut progress: impl FnMut(&str),
) -> Result<Vec<Row>, ReproduceError> {
    progress("Tables 2-4: simulating the rig stand-in (stepped sine and two band-random records)");
    let snr = Some(settings.rig_snr_db);
    let data = rig_data(TruthElement::rig_coulomb(), snr, settings.seed)?;
    let (k, c, fd) = paper::RIG_TRUTH;
    let truth = |table: u8| truth_row(table, None, "coulomb", [k, c, fd], None);
    let mut rows = Vec::new();
    if tables.contains(&2) {
        rows.push(truth(2));
        for p in &paper::TABLE2 {
            rows.push(paper_row(p));
            for method in [Method::Fd, Method::FdMulti] {
                progress(&format!("Table 2: {} {}", p.model, method.name()));
                rows.push(rig_row(2, &data, p.model, None, method, snr)?);
            }
        }
    }
    if tables.contains(&3) {
        rows.push(truth(3));
        for p in &paper::TABLE3 {
            rows.push(paper_row(p));
            for method in [Method::Fd, Method::FdMulti] {
                progress(&format!(
                    "Table 3: M = {} {}",
                    p.atan_m.unwrap_or(0.0),
                    method.name()
                ));
                rows.push(rig_row(3, &data, p.model, p.atan_m, method, snr)?);
            }
        }
    }
    if tables.contains(&4) {
        rows.push(truth(4));
        rows.push(paper_row(&paper::TABLE4[0]));
        for method in [
            Method::Td {
                points_per_step: Some(20),
            },
            Method::Td {
                points_per_step: None,
            },
            Method::Fd,
            Method::FdMulti,
        ] {
            progress(&format!("Table 4: coulomb {}", method.name()));
            rows.push(rig_row(4, &data, "coulomb", None, method, snr)?);
        }
    }
    Ok(rows)
}

/// All requested tables (1-4).
pub fn reproduce(
    tables: &[u8],
    settings: &Settings,
    mut progress: impl FnMut(&str),
) -> Result<Vec<Row>, ReproduceError> {
    let mut rows = Vec::new();
    if tables.contains(&1) {
        rows.extend(table1(settings, &mut progress)?);
    }
    if tables.iter().any(|t| (2..=4).contains(t)) {
        rows.extend(rig_tables(tables, settings, &mut progress)?);
    }
    Ok(rows)
}
