//! The `forcemap` command. Exit codes: 0 success, 1 error, 2 usage error.

use clap::Parser;
use forcemap_cli::cli::Cli;

/// The error and its causes on one line, each cause once (some errors already quote theirs).
fn describe(e: &anyhow::Error) -> String {
    let mut text = e.to_string();
    for cause in e.chain().skip(1) {
        let c = cause.to_string();
        if !text.contains(&c) {
            text.push_str(": ");
            text.push_str(&c);
        }
    }
    text
}

fn main() {
    let cli = Cli::parse();
    if let Err(e) = forcemap_cli::commands::dispatch(cli.command) {
        eprintln!("error: {}", describe(&e));
        std::process::exit(1);
    }
}
