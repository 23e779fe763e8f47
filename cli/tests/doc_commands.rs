//! Every `forcemap` command the documentation shows parses with the command line as it is, and
//! every repository path it names exists: a renamed option, a removed subcommand or a moved file
//! fails here. The commands are those of code blocks (indented or fenced, a trailing `\`
//! continuing the line) and of inline code spans that start with `forcemap `, in the README,
//! `docs/`, `examples/` and the READMEs of the crates and the committed data. A span that
//! elides arguments (`...`) is counted, not parsed. Every command of a code block is also run
//! as written and must exit 0 ([`every_documented_command_runs`]). What the commands print is
//! checked elsewhere: the README's by
//! `readme_tour`, the examples' by `examples_run`, the figures quoted in the docs by the tests
//! named beside them.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::path::{Path, PathBuf};

use clap::Parser as _;
use forcemap_cli::cli::Cli;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The Markdown files whose commands are checked.
fn documents() -> Vec<PathBuf> {
    let root = repo();
    let mut files = vec![root.join("README.md"), root.join("examples/README.md")];
    for dir in ["docs", "data/real"] {
        for entry in walk(&root.join(dir)) {
            if entry.extension().is_some_and(|e| e == "md") {
                files.push(entry);
            }
        }
    }
    for krate in ["math", "eval", "msgs", "io", "nodes", "cli"] {
        files.push(root.join(krate).join("README.md"));
    }
    files.retain(|f| f.exists());
    files.sort();
    files
}

fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return out;
    };
    for e in entries {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(walk(&p));
        } else {
            out.push(p);
        }
    }
    out
}

/// A command found in a document: where, its text (continuations joined), and whether it
/// stands in a code block (a command to copy) or in a sentence (a name, often without its
/// arguments).
struct Found {
    place: String,
    text: String,
    code: bool,
}

/// The `forcemap` commands of one Markdown text.
fn commands(name: &str, text: &str) -> Vec<Found> {
    let mut out = Vec::new();
    let lines: Vec<&str> = text.lines().collect();
    let mut fenced = false;
    // The prose paragraph so far (its inline spans may break across lines) and its first line.
    let mut paragraph = String::new();
    let mut paragraph_start = 0;
    let flush = |paragraph: &mut String, start: usize, out: &mut Vec<Found>| {
        let mut offset = 0;
        for (k, part) in paragraph.split('`').enumerate() {
            if k % 2 == 1 && part.starts_with("forcemap ") {
                let line = start + paragraph[..offset].matches('\n').count();
                out.push(Found {
                    place: format!("{name}:{}", line + 1),
                    text: part.replace('\n', " "),
                    code: false,
                });
            }
            offset += part.len() + 1;
        }
        paragraph.clear();
    };
    let mut i = 0;
    while i < lines.len() {
        let line = lines[i];
        let fence = line.trim_start().starts_with("```");
        let code = fenced || fence || line.starts_with("    ");
        if code || line.trim().is_empty() {
            flush(&mut paragraph, paragraph_start, &mut out);
        }
        if fence {
            fenced = !fenced;
        } else if code {
            let body = line.trim_start().trim_start_matches("$ ");
            // A repository script a page runs before its commands (it makes their input).
            if body.starts_with("forcemap ") || body.starts_with("python3 benches/") {
                let start = i;
                let mut text = body.to_string();
                while text.ends_with('\\') && i + 1 < lines.len() {
                    text.pop();
                    i += 1;
                    text.push(' ');
                    text.push_str(lines[i].trim());
                }
                out.push(Found {
                    place: format!("{name}:{}", start + 1),
                    text,
                    code: true,
                });
            }
        } else if !line.trim().is_empty() {
            if paragraph.is_empty() {
                paragraph_start = i;
            } else {
                paragraph.push('\n');
            }
            paragraph.push_str(line);
        }
        i += 1;
    }
    flush(&mut paragraph, paragraph_start, &mut out);
    out
}

/// The words of a command as a shell passes them, up to a pipe, a redirection or a second
/// command; None when the shell would not split it (an unclosed quote).
fn words(text: &str) -> Option<Vec<String>> {
    let mut words = shlex::split(text)?;
    if let Some(end) = words
        .iter()
        .position(|w| ["|", ">", "2>", "&&", ";", "2>&1", "&"].contains(&w.as_str()))
    {
        words.truncate(end);
    }
    Some(words)
}

/// Repository paths a command names (a word under one of the committed directories), with the
/// shell's braces and globs left to the shell: the directory part before them must exist; a
/// record selection after `#` is not part of the path.
fn missing_paths(words: &[String]) -> Vec<String> {
    const ROOTS: [&str; 6] = [
        "data/",
        "bags/",
        "launch_configs/",
        "examples/",
        "benches/",
        "docs/",
    ];
    let mut missing = Vec::new();
    for w in words {
        let w = w.split_once('=').map_or(w.as_str(), |(_, v)| v);
        // `FILE#NAMES` picks records of FILE (named in its map): FILE must exist.
        let w = w.split_once('#').map_or(w, |(file, _)| file);
        if !ROOTS.iter().any(|r| w.starts_with(r)) {
            continue;
        }
        let cut = w.find(['{', '*', '?', '[']).unwrap_or(w.len());
        let fixed = &w[..cut];
        let path = if cut < w.len() {
            // The part before a brace or glob: its directory.
            fixed.rsplit_once('/').map_or("", |(d, _)| d)
        } else {
            fixed
        };
        if !path.is_empty() && !repo().join(path).exists() {
            missing.push(w.to_string());
        }
    }
    missing
}

/// A placeholder word of a synopsis (`FILE`, `N`, `DATA_EMPS.mat` is not one).
fn placeholder(w: &str) -> bool {
    w.chars().any(|c| c.is_ascii_uppercase())
        && w.chars()
            .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || "_.-".contains(c))
}

/// Whether a command is a synopsis (`[--json]`, `bash|zsh`, `FILE`, `N`) rather than one to run.
fn synopsis(words: &[String]) -> bool {
    words.iter().skip(1).any(|w| {
        w.contains('[') || w.contains(']') || (w.contains('|') && w.len() > 1) || placeholder(w)
    })
}

/// Whether a code-block line is a program's output that starts with the command it ran (a
/// word ending in `:` before more text: `forcemap diagnose-eval --seed 1,2,3: 600 cases`).
fn output_line(words: &[String]) -> bool {
    words
        .iter()
        .rev()
        .skip(1)
        .any(|w| w.ends_with(':') && !w.ends_with(":="))
}

/// The subcommands and option names of `words` against the command line's definition: every
/// subcommand (each of `a|b` alternatives) exists, and every `--option` (brackets and `=value`
/// aside) is one of the subcommand's; values and required arguments are not checked. Err says
/// what is not there.
fn names_exist(words: &[String]) -> Result<(), String> {
    use clap::CommandFactory as _;
    let mut root = Cli::command();
    root.build();
    let mut cur = &root;
    let mut rest = words.iter().skip(1).peekable();
    while cur.has_subcommands() {
        let Some(w) = rest.next() else {
            return Ok(());
        };
        if w.starts_with('-') {
            break;
        }
        if placeholder(w) {
            // `forcemap COMMAND --help`: nothing further to check.
            return Ok(());
        }
        let first = w.split('|').next().unwrap_or_default();
        for a in w.split('|') {
            if cur.find_subcommand(a).is_none() {
                return Err(format!("no subcommand '{a}' of '{}'", cur.get_name()));
            }
        }
        cur = cur.find_subcommand(first).unwrap();
    }
    // Arguments passed on as they are (a node's ROS arguments) are not this command's options.
    if cur
        .get_arguments()
        .any(|a| a.is_trailing_var_arg_set() || a.is_allow_hyphen_values_set())
    {
        return Ok(());
    }
    for w in rest {
        let w = w.trim_start_matches('[').trim_end_matches(']');
        let name = w.split('=').next().unwrap_or_default();
        let known = if let Some(long) = name.strip_prefix("--") {
            long.is_empty()
                || cur.get_arguments().any(|a| {
                    a.get_long() == Some(long)
                        || a.get_all_aliases().is_some_and(|al| al.contains(&long))
                })
        } else if let Some(short) = name.strip_prefix('-').filter(|s| s.len() == 1) {
            let c = short.chars().next().unwrap_or_default();
            !c.is_ascii_alphabetic() || cur.get_arguments().any(|a| a.get_short() == Some(c))
        } else {
            true
        };
        if !known {
            return Err(format!("no option {name} of '{}'", cur.get_name()));
        }
    }
    Ok(())
}

#[test]
fn every_documented_command_parses_and_its_paths_exist() {
    let (mut parsed, mut named, mut elided) = (0, 0, 0);
    let mut failures = Vec::new();
    for doc in documents() {
        let name = doc
            .strip_prefix(repo())
            .unwrap_or(&doc)
            .display()
            .to_string();
        let text = std::fs::read_to_string(&doc).unwrap();
        for found in commands(&name, &text) {
            if !found.text.starts_with("forcemap ") {
                continue;
            }
            if found.text.contains("...") {
                elided += 1;
                continue;
            }
            let Some(words) = words(&found.text) else {
                failures.push(format!(
                    "{}: not a shell command: {}",
                    found.place, found.text
                ));
                continue;
            };
            if found.code && output_line(&words) {
                continue;
            }
            if let Err(e) = names_exist(&words) {
                failures.push(format!("{}: `{}`: {e}", found.place, found.text));
                continue;
            }
            for p in missing_paths(&words) {
                failures.push(format!(
                    "{}: `{}`: no such path {p}",
                    found.place, found.text
                ));
            }
            // A command in a code block is one to copy: it parses as written.
            if !found.code || synopsis(&words) {
                named += 1;
                continue;
            }
            match Cli::try_parse_from(&words) {
                Ok(_) => parsed += 1,
                Err(e)
                    if matches!(
                        e.kind(),
                        clap::error::ErrorKind::DisplayHelp
                            | clap::error::ErrorKind::DisplayVersion
                    ) =>
                {
                    parsed += 1;
                }
                Err(e) => {
                    let first = e.to_string();
                    let first = first.lines().next().unwrap_or_default().to_string();
                    failures.push(format!("{}: `{}`: {first}", found.place, found.text));
                }
            }
        }
    }
    println!(
        "documented commands: {parsed} in code blocks parsed as written, {named} names and synopses checked for their subcommands and options, {elided} elided (`...`)"
    );
    assert!(
        parsed > 30 && named > 100,
        "only {parsed} + {named} commands found: the extraction broke"
    );
    assert!(
        failures.is_empty(),
        "{} documented commands do not hold:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// The extraction itself: code-block lines with continuations, inline spans, pipes cut, and
/// an unknown option caught.
#[test]
fn the_extraction_finds_what_a_reader_would_type() {
    let md = "Run\n\n    forcemap identify a.csv \\\n        --model coulomb | head\n\nor `forcemap info b.csv` and\n`forcemap bogus --x`.\n";
    let found = commands("t.md", md);
    let texts: Vec<&str> = found.iter().map(|f| f.text.as_str()).collect();
    assert_eq!(texts.len(), 3, "{texts:?}");
    assert_eq!(texts[1..], ["forcemap info b.csv", "forcemap bogus --x"]);
    assert_eq!(found[0].place, "t.md:3");
    assert_eq!(found[2].place, "t.md:7");
    assert_eq!(
        words(texts[0]).unwrap(),
        ["forcemap", "identify", "a.csv", "--model", "coulomb"]
    );
    assert!(Cli::try_parse_from(words(texts[0]).unwrap()).is_ok());
    assert!(names_exist(&words(texts[2]).unwrap()).is_err());
    let synopsis_line = words("forcemap bag info BAG [--json] [--nope]").unwrap();
    assert!(synopsis(&synopsis_line));
    assert_eq!(
        names_exist(&synopsis_line),
        Err("no option --nope of 'info'".to_string())
    );
    assert!(
        names_exist(&words("forcemap node harmonic|identifier --ros-args -p a:=1").unwrap())
            .is_ok()
    );
    assert!(names_exist(&words("forcemap bag info|recover BAG").unwrap()).is_ok());
    assert!(names_exist(&words("forcemap bag info|nothing BAG").unwrap()).is_err());
    assert_eq!(
        missing_paths(&["data/real/nowhere.csv".into(), "data/real/{a,b}.txt".into()]),
        ["data/real/nowhere.csv"]
    );
}

/// How long a documented node runs before it is stopped: a node serves until it is stopped, so it
/// passes when it is still up then and has printed no error.
const NODE_RUN_S: &str = "3";

/// A scratch directory for one page's commands, holding what they name where they name it: the
/// repository's committed directories linked under `repo/`, `../shared` beside it, a
/// `forcemap` on the PATH that is the test build's. Returns (the directory to run in, PATH).
fn scratch_for(tmp: &Path, page: &str) -> (PathBuf, String) {
    let root = repo().canonicalize().unwrap();
    let bin = tmp.join("bin");
    if !bin.exists() {
        std::fs::create_dir(&bin).unwrap();
        std::os::unix::fs::symlink(env!("CARGO_BIN_EXE_forcemap"), bin.join("forcemap")).unwrap();
    }
    let dir = tmp.join(page.replace('/', "_")).join("repo");
    std::fs::create_dir_all(&dir).unwrap();
    for d in [
        "data",
        "bags",
        "launch_configs",
        "examples",
        "benches",
        "docs",
    ] {
        std::os::unix::fs::symlink(root.join(d), dir.join(d)).unwrap();
    }
    std::os::unix::fs::symlink(root.join("../shared"), dir.join("../shared")).unwrap();
    // `--python python3` in a command is the Python with numpy the tests are given.
    let python_bin = std::env::var("FORCEMAP_PYTHON")
        .ok()
        .and_then(|p| Path::new(&p).parent().map(|d| format!("{}:", d.display())))
        .unwrap_or_default();
    let path = format!(
        "{}:{python_bin}{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    (dir, path)
}

/// Every command of a code block in the README, `docs/`, `examples/` and the data READMEs runs
/// as written and exits 0, page by page in the order the page gives them (a command that reads
/// what an earlier one wrote finds it, a repository script that makes it, `python3 benches/...`,
/// among them), in a scratch directory where the repository's paths resolve; a node is run for
/// [`NODE_RUN_S`] seconds. A command's limit ([`COMMAND_LIMIT_S`]) guards against a hang, not
/// a slow machine. The evaluations of [`EVALUATIONS_PARSED_ONLY`] are parsed, not run.
/// How long a documented command (not a node) may run before it counts as hung [s].
const COMMAND_LIMIT_S: &str = "1800";

/// Documented evaluations parsed but not run here (the command, its comment left out): each takes
/// minutes on CI's two cores (the wide one's 900 cases some 8 of this test's 11), exits 0
/// whatever its figures, and runs the code of the shorter documented evaluation named beside
/// it, which does run. Their figures are measurements, each quoted with its command.
const EVALUATIONS_PARSED_ONLY: [(&str, &str); 2] = [
    (
        "forcemap diagnose-eval --forms wide --cases 300 --seed 1,2,3 --json-file eval.json",
        "forcemap diagnose-eval --cases 60 --forms wide --seed 1 --threads 1 --json",
    ),
    (
        "forcemap diagnose-eval --cases 200 --seed 1",
        "forcemap diagnose-eval --cases 10 --seed 1 --threads 1 --json",
    ),
];

#[test]
fn every_documented_command_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let python = std::env::var_os("FORCEMAP_PYTHON").is_some();
    assert!(
        python || std::env::var_os("CI").is_none(),
        "CI is set but FORCEMAP_PYTHON is not: the documented benches with --python cannot run"
    );
    let (mut ran, mut skipped) = (0, 0);
    let mut failures = Vec::new();
    let mut parsed_only = [false; EVALUATIONS_PARSED_ONLY.len()];
    let mut stand_ins = [false; EVALUATIONS_PARSED_ONLY.len()];
    for doc in documents() {
        let page = doc
            .strip_prefix(repo())
            .unwrap_or(&doc)
            .display()
            .to_string();
        let text = std::fs::read_to_string(&doc).unwrap();
        let mut scratch = None;
        for found in commands(&page, &text) {
            let Some(words) = words(&found.text) else {
                continue;
            };
            if !found.code || found.text.contains("...") || output_line(&words) || synopsis(&words)
            {
                continue;
            }
            let command = found.text.split('#').next().unwrap_or_default().trim();
            for (k, (_, stand_in)) in EVALUATIONS_PARSED_ONLY.iter().enumerate() {
                stand_ins[k] |= command == *stand_in;
            }
            let long = EVALUATIONS_PARSED_ONLY
                .iter()
                .position(|(long, _)| command == *long);
            if let Some(k) = long {
                println!("parsed, not run (a long evaluation): {}", found.place);
                parsed_only[k] = true;
                continue;
            }
            if words.iter().any(|w| w == "--python") && !python {
                println!(
                    "skipped (set FORCEMAP_PYTHON to a Python with numpy): {}",
                    found.place
                );
                skipped += 1;
                continue;
            }
            let (dir, path) = scratch.get_or_insert_with(|| scratch_for(tmp.path(), &page));
            let node = words.get(1).is_some_and(|w| w == "node");
            let limit = if node { NODE_RUN_S } else { COMMAND_LIMIT_S };
            let started = std::time::Instant::now();
            let out = std::process::Command::new("timeout")
                .args([limit, "bash", "-c", &found.text])
                .current_dir(&*dir)
                .env("PATH", &*path)
                .env("ROS_DOMAIN_ID", "93")
                .output()
                .unwrap();
            let stderr = String::from_utf8_lossy(&out.stderr);
            let code = out.status.code();
            let passed = if node {
                code == Some(124) && !stderr.contains("error")
            } else {
                code == Some(0)
            };
            println!(
                "{:>6.1} s {:?} {}: {}",
                started.elapsed().as_secs_f64(),
                code,
                found.place,
                found.text
            );
            ran += 1;
            if !passed {
                let tail: Vec<&str> = stderr.lines().rev().take(3).collect();
                failures.push(format!(
                    "{}: `{}` exited {code:?}: {}",
                    found.place,
                    found.text,
                    tail.into_iter().rev().collect::<Vec<_>>().join(" / ")
                ));
            }
        }
    }
    println!("documented commands: {ran} run, {skipped} skipped");
    for (k, (long, stand_in)) in EVALUATIONS_PARSED_ONLY.iter().enumerate() {
        assert!(parsed_only[k], "no documented command `{long}`");
        assert!(
            stand_ins[k],
            "no documented command `{stand_in}` runs in its place"
        );
    }
    assert!(ran > 35, "only {ran} commands run: the extraction broke");
    assert!(
        failures.is_empty(),
        "{} documented commands fail:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
