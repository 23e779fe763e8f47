//! One module per `forcemap` subcommand; `dispatch` routes to them.

pub mod bag;
pub mod bench;
pub mod diagnose;
pub mod diagnose_eval;
pub mod diagnose_time_domain;
pub mod identify;
pub mod import;
pub mod reproduce;
pub mod simulate;

use crate::cli::Command;

/// Runs a parsed command.
pub fn dispatch(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Reproduce(a) => reproduce::run(&a),
        Command::Identify(a) => identify::run(&a),
        Command::Simulate(a) => simulate::run(&a),
        Command::Bag(a) => bag::run(&a),
        Command::Import(a) => import::run(&a),
        Command::Diagnose(a) => diagnose::run(&a),
        Command::DiagnoseEval(a) => diagnose_eval::run(&a),
        Command::Node(a) => forcemap_nodes::node::run(&a.kind, &a.ros_args),
        Command::Launch(a) => forcemap_nodes::launch::run(&a.file, &a.args, a.dry_run),
        Command::Bench(a) => match &a.command {
            crate::cli::BenchCommand::Graph(g) => bench::run_graph(g),
        },
        Command::Models => {
            for (name, what) in forcemap_math::model::MODEL_NAMES {
                println!("{name:<20} {what}");
            }
            Ok(())
        }
    }
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
