//! `forcemap import csv|emps FILE --out BAG`.

use forcemap_math::recipe::check_mass_kg;
use forcemap_math::record::Record;

use crate::cli::{ImportArgs, ImportCommand};
use forcemap_io::csv_export::read_csv;
use forcemap_io::params::read_params;
use forcemap_io::rig_bag::{DEFAULT_RUN_START, write_rig_bag};

pub fn run(args: &ImportArgs) -> anyhow::Result<()> {
    match &args.command {
        ImportCommand::Csv {
            file,
            out,
            mass_kg,
            params,
        } => {
            let csv = read_csv(file)?;
            for w in &csv.warnings {
                eprintln!("warning: {}: {w}", file.display());
            }
            for notice in &csv.notices {
                eprintln!("notice: {notice}");
            }
            if !csv.ignored_columns.is_empty() {
                eprintln!(
                    "notice: {}: ignored columns not in the contract: {}",
                    file.display(),
                    csv.ignored_columns.join(", ")
                );
            }
            let from_params = match params {
                Some(p) => read_params(p, None)?.opt_f64("mass_kg")?,
                None => None,
            };
            let mass = mass_kg.or(from_params);
            if let Some(m) = mass {
                check_mass_kg(m)?;
            }
            let parameters: Vec<(&str, f64)> = mass.map(|m| ("mass_kg", m)).into_iter().collect();
            let dir = write_rig_bag(
                out,
                &csv.records,
                csv.kind.driven_channel(),
                &parameters,
                DEFAULT_RUN_START,
            )?;
            eprintln!(
                "wrote {} ({} records, {} samples{})",
                dir.display(),
                csv.records.len(),
                csv.records.iter().map(Record::len).sum::<usize>(),
                if parameters.is_empty() {
                    ", no rig constants: give --mass-kg to store them"
                } else {
                    ""
                }
            );
            Ok(())
        }
        ImportCommand::Emps { file, out } => {
            let s = forcemap_io::emps::import_emps(file, out)?;
            eprintln!(
                "wrote {} ({} samples at {:.1} Hz over {:.2} s; gains gtau {} N/V, kp {}, kv {} on /emps/parameters{})",
                s.bag.display(),
                s.samples,
                s.sample_rate_hz,
                s.duration_s,
                s.gtau,
                s.kp,
                s.kv,
                if s.extra_variables.is_empty() {
                    String::new()
                } else {
                    format!(", with {}", s.extra_variables.join(", "))
                }
            );
            Ok(())
        }
    }
}
