//! The `forcemap` command. Exit codes: 0 success, 1 error, 2 usage error.

use clap::Parser;
use forcemap_cli::cli::{Cli, Command};

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

/// A closed pipe (`forcemap identify ... | head`) ends an offline command quietly, as it does
/// any Unix filter, instead of a panic in `println!`: Rust starts with SIGPIPE ignored. The
/// nodes, the launcher and the graph benchmark keep Rust's default (they manage their pipes).
fn default_sigpipe() {
    use nix::sys::signal::{SigHandler, Signal, signal};
    // SAFETY: called first thing in main, before any thread exists, restoring the default
    // disposition (no handler function is installed).
    let _ = unsafe { signal(Signal::SIGPIPE, SigHandler::SigDfl) };
}

fn main() {
    let cli = Cli::parse();
    if !matches!(
        cli.command,
        Command::Node(_) | Command::Launch(_) | Command::Bench(_)
    ) {
        default_sigpipe();
    }
    if let Err(e) = forcemap_cli::commands::dispatch(cli.command) {
        eprintln!("error: {}", describe(&e));
        std::process::exit(1);
    }
}
