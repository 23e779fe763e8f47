//! The README's tour, run as a reader would run it: every `forcemap ...` command the README
//! shows (inline or as an indented block, backslash continuations joined) is run by bash in a
//! scratch directory that sees the repository's `bags/`, `data/` and `launch_configs/`, with
//! this build's `forcemap` on the path, and must succeed; what the README quotes of an output
//! (`verdict: ...`) must be in it. Commands that need what another step left behind (the
//! graph's bag, written by the main job) or that elide their arguments (`...`) are listed and
//! skipped; `forcemap launch` runs with `--dry-run` (the main job is its own test) and a bare
//! subcommand named in the prose with `--help`.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The `forcemap` commands of `text` (Markdown): indented lines that start with `forcemap `
/// (continuation lines, `\`, joined), then inline code spans that do (a span may break across
/// lines).
fn commands(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut lines = text.lines();
    while let Some(line) = lines.next() {
        let trimmed = line.trim_start();
        if line.starts_with("    ") && trimmed.starts_with("forcemap ") {
            let mut cmd = trimmed.trim_end().to_string();
            while cmd.ends_with('\\') {
                cmd.pop();
                match lines.next() {
                    Some(next) => cmd.push_str(next.trim()),
                    None => break,
                }
            }
            out.push(cmd);
        }
    }
    for (k, span) in text.split('`').enumerate() {
        let span = span.split_whitespace().collect::<Vec<_>>().join(" ");
        if k % 2 == 1 && span.starts_with("forcemap ") {
            out.push(span);
        }
    }
    out
}

/// How a README command is run: a bare subcommand named in the prose (`forcemap identify`) by
/// its `--help` (it exists), `forcemap launch` with `--dry-run`, the others as written.
fn as_run(cmd: &str) -> String {
    if cmd.split_whitespace().count() == 2 {
        format!("{cmd} --help")
    } else if cmd.starts_with("forcemap launch ") {
        format!("{cmd} --dry-run")
    } else {
        cmd.to_string()
    }
}

/// Why a README command is not run here, if it is not.
fn skipped(cmd: &str) -> Option<&'static str> {
    if cmd.contains("...") {
        Some("its arguments are elided")
    } else if cmd.contains("forcemap_rig_run/") {
        Some("it reads the bag the main job writes")
    } else if cmd
        .split_whitespace()
        .any(|w| w.chars().all(char::is_uppercase) && w.len() > 2)
    {
        Some("it names a placeholder (FILE, DIR, ...)")
    } else {
        None
    }
}

#[test]
fn the_readme_tour_runs_as_written() {
    let readme = std::fs::read_to_string(repo().join("README.md")).unwrap();
    let all = commands(&readme);
    assert!(all.len() >= 8, "README commands found: {all:#?}");
    let scratch = tempfile::tempdir().unwrap();
    for dir in ["bags", "data", "launch_configs"] {
        std::os::unix::fs::symlink(
            repo().join(dir).canonicalize().unwrap(),
            scratch.path().join(dir),
        )
        .unwrap();
    }
    let bin = Path::new(env!("CARGO_BIN_EXE_forcemap"))
        .parent()
        .unwrap()
        .to_path_buf();
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    // What the README quotes of an output, and the command that prints it.
    let quoted: Vec<&str> = readme
        .split('`')
        .skip(1)
        .step_by(2)
        .filter(|s| s.starts_with("verdict: "))
        .collect();
    let mut outputs = String::new();
    for cmd in &all {
        if let Some(why) = skipped(cmd) {
            println!("skipped ({why}): {cmd}");
            continue;
        }
        let run = as_run(cmd);
        println!("running: {run}");
        let o = Command::new("bash")
            .arg("-c")
            .arg(&run)
            .current_dir(scratch.path())
            .env("PATH", &path)
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "README command failed: {run}\n{}",
            String::from_utf8_lossy(&o.stderr)
        );
        outputs.push_str(&String::from_utf8_lossy(&o.stdout));
    }
    for q in quoted {
        assert!(
            outputs.contains(q),
            "the README quotes `{q}`, no command printed it"
        );
    }
}

#[test]
fn commands_are_found_inline_and_in_blocks() {
    let text = "Run `forcemap models` and `forcemap\n   info x.txt`:\n\n    forcemap identify a.txt \\\n        --model linear\n\n`cargo test`";
    assert_eq!(
        commands(text),
        [
            "forcemap identify a.txt --model linear",
            "forcemap models",
            "forcemap info x.txt"
        ]
    );
    assert_eq!(as_run("forcemap models"), "forcemap models --help");
    assert_eq!(
        as_run("forcemap launch x.yaml"),
        "forcemap launch x.yaml --dry-run"
    );
    assert_eq!(
        skipped("forcemap diagnose FILE... --model linear"),
        Some("its arguments are elided")
    );
    assert_eq!(skipped("forcemap models"), None);
}
