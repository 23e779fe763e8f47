//! One module per `forcemap` subcommand; `dispatch` routes to them.

pub mod bag;
pub mod bench;
pub mod bench_identify;
pub mod bench_trace;
pub mod diagnose;
pub mod diagnose_eval;
pub mod element_outputs;
pub mod identify;
pub mod identify_held_out;
pub mod identify_hysteresis;
pub mod identify_hysteresis_records;
mod identify_plots;
pub mod import;
pub mod info;
pub mod manual;
mod random_records;
pub mod reproduce;
pub mod simulate;

use std::collections::BTreeMap;
use std::path::Path;

use forcemap_io::params::{Params, read_params};
use forcemap_io::rig_constants;
use forcemap_math::recipe::{RecipeError, SetupConstants, SetupKind, SetupSpec};

use crate::cli::Command;

/// Runs a parsed command.
pub fn dispatch(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Reproduce(a) => reproduce::run(&a),
        Command::Identify(a) => identify::run(&a),
        Command::Simulate(a) => simulate::run(&a),
        Command::Info(a) => info::run(&a),
        Command::Bag(a) => bag::run(&a),
        Command::Import(a) => import::run(&a),
        Command::Diagnose(a) => diagnose::run(&a),
        Command::DiagnoseEval(a) => diagnose_eval::run(&a),
        Command::Node(a) => forcemap_nodes::node::run(&a.kind, &a.ros_args),
        Command::Launch(a) => forcemap_nodes::launch::run(&a.file, &a.args, a.dry_run),
        Command::Bench(a) => match &a.command {
            crate::cli::BenchCommand::Graph(g) => bench::run_graph(g),
            crate::cli::BenchCommand::Identify(i) => bench_identify::run(i),
        },
        Command::Completions(a) => {
            manual::completions(a.shell);
            Ok(())
        }
        Command::Man(a) => manual::man_pages(&a.dir),
        Command::Models => {
            for (name, what) in forcemap_math::model::MODEL_NAMES {
                println!("{name:<20} {what}");
            }
            println!(
                "{:<20} the model NAME with a constant force term offset (a load cell's zero \
                 error, a drive's DC, a preload): cubic+offset",
                format!("NAME{}", forcemap_math::model::OFFSET_SUFFIX)
            );
            println!(
                "{:<20} the model NAME with a Bouc-Wen hysteresis state alpha z beside its terms \
                 (yield and loop shape searched; element tests and a rig's sine steps, fitted \
                 as `diagnose` refits NAME with its hysteresis): damper+hysteresis",
                format!("NAME{}", forcemap_math::model::HYSTERESIS_SUFFIX)
            );
            Ok(())
        }
    }
}

/// The setup of data of `kind` in `file`, from the constants a command was given in their
/// order of priority: `--mass-kg`, then the `--params` file, then what the data carry.
pub fn resolve_setup(
    kind: SetupKind,
    mass_kg_flag: Option<f64>,
    params: &Params,
    params_file: Option<&Path>,
    carried: &BTreeMap<String, f64>,
    file: &str,
) -> anyhow::Result<SetupSpec> {
    let params_source =
        params_file.map_or("no --params file".to_string(), |p| p.display().to_string());
    let given = SetupConstants {
        mass_kg: mass_kg_flag,
        substructure: None,
    };
    let constants = given
        .or(rig_constants::from_params(params)?)
        .or(rig_constants::from_values(carried));
    kind.resolve(&constants).map_err(|e| match e {
        RecipeError::MissingMass => anyhow::anyhow!(
            "{file}: {e}: give --mass-kg 36 or mass_kg in a --params file ({params_source})"
        ),
        RecipeError::BadMass(_) => anyhow::anyhow!(e),
        e => anyhow::anyhow!("{file}: {e} ({params_source})"),
    })
}

/// [`resolve_setup`] with the `--params` file read: the setup of data of `kind` in `file`.
pub fn setup_of(
    kind: SetupKind,
    mass_kg_flag: Option<f64>,
    params_file: Option<&Path>,
    carried: &BTreeMap<String, f64>,
    file: &str,
) -> anyhow::Result<forcemap_math::recipe::Setup> {
    let params = match params_file {
        Some(p) => read_params(p, None)?,
        None => Params::new(),
    };
    Ok(resolve_setup(kind, mass_kg_flag, &params, params_file, carried, file)?.setup()?)
}

/// A spinner on stderr for long work (hidden when stderr is not a terminal).
pub fn progress_spinner() -> indicatif::ProgressBar {
    let pb = indicatif::ProgressBar::new_spinner();
    pb.enable_steady_tick(std::time::Duration::from_millis(120));
    pb
}

/// Formats an optional number with `prec` decimals, "-" when absent.
pub fn fmt_opt(v: Option<f64>, prec: usize) -> String {
    v.map_or_else(|| "-".to_string(), |x| format!("{x:.prec$}"))
}
