//! `forcemap completions SHELL` and `forcemap man DIR`: generated from the argument parser
//! itself (clap_complete, clap_mangen), so they cannot drift from `--help`.

use std::path::Path;

use anyhow::Context;
use clap::CommandFactory;

use crate::cli::Cli;
use forcemap_io::atomic::write_dir_atomically;

/// Prints the completion script for `shell` on standard output.
pub fn completions(shell: clap_complete::Shell) {
    let mut cmd = Cli::command();
    clap_complete::generate(shell, &mut cmd, "forcemap", &mut std::io::stdout());
}

/// Writes `forcemap.1` and a page per subcommand (`forcemap-identify.1`, ...) into `dir`,
/// which must not exist yet.
pub fn man_pages(dir: &Path) -> anyhow::Result<()> {
    write_dir_atomically(dir, |tmp| {
        clap_mangen::generate_to(Cli::command(), tmp)
            .with_context(|| format!("writing manual pages into {}", tmp.display()))
    })?;
    eprintln!("wrote the manual pages into {}", dir.display());
    Ok(())
}
