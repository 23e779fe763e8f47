//! The `forcemap` command. Exit codes: 0 success, 1 error, 2 usage error.

use clap::Parser;
use forcemap_nodes::cli::Cli;

fn main() {
    let cli = Cli::parse();
    if let Err(e) = forcemap_nodes::commands::dispatch(cli.command) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
