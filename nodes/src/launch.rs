//! `forcemap launch FILE [name:=value ...]`: starts the nodes of a ROS 2 YAML launch file as
//! separate processes, prefixes their output with the node name, and stops them all cleanly
//! (SIGINT, then SIGKILL after a grace period) on Ctrl-C, when a node marked
//! `on_exit: shutdown` ends, or when every node has ended.
//!
//! The subset of the ROS 2 YAML launch format read here:
//!
//! ```yaml
//! launch:
//! - arg: {name: out, default: /tmp/forcemap-run, description: where results go}
//! - node:
//!     pkg: forcemap
//!     exec: identifier            # sensor, harmonic, identifier, recorder, monitor
//!     name: identifier
//!     namespace: rig
//!     on_exit: shutdown           # optional: end the launch when this node ends
//!     param:
//!     - {from: $(dirname)/rig.params.yaml}
//!     - {name: model, value: coulomb}
//!     remap:
//!     - {from: theta, to: /control/theta}
//! ```
//!
//! Substitutions: `$(var NAME)`, `$(env NAME)` / `$(env NAME DEFAULT)`, `$(dirname)` (the
//! launch file's directory).

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Write};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use serde::Deserialize;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct LaunchFile {
    launch: Vec<Entry>,
}

#[derive(Debug, Deserialize)]
#[serde(rename_all = "snake_case")]
enum Entry {
    Arg(ArgEntry),
    Node(NodeEntry),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ArgEntry {
    name: String,
    default: Option<serde_json::Value>,
    #[allow(dead_code)]
    description: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct NodeEntry {
    pkg: String,
    exec: String,
    name: Option<String>,
    namespace: Option<String>,
    #[serde(default)]
    param: Vec<ParamEntry>,
    #[serde(default)]
    remap: Vec<RemapEntry>,
    on_exit: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ParamEntry {
    name: Option<String>,
    value: Option<serde_json::Value>,
    from: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RemapEntry {
    from: String,
    to: String,
}

/// One process to start.
#[derive(Debug, Clone, PartialEq)]
pub struct LaunchNode {
    pub name: String,
    /// What its output lines and the launcher's messages call it: the name, or the name with
    /// its namespace (`front_left/monitor`) where several nodes share the name.
    pub label: String,
    pub exec: String,
    /// Arguments after `forcemap node EXEC`.
    pub args: Vec<String>,
    pub shutdown_on_exit: bool,
}

/// Replaces the substitutions in `text`.
fn substitute(
    text: &str,
    vars: &BTreeMap<String, String>,
    dir: &Path,
    file: &str,
) -> anyhow::Result<String> {
    let mut out = String::new();
    let mut rest = text;
    while let Some(i) = rest.find("$(") {
        out.push_str(&rest[..i]);
        let after = &rest[i + 2..];
        let Some(j) = after.find(')') else {
            bail!("{file}: unclosed substitution in '{text}'");
        };
        let inner: Vec<&str> = after[..j].split_whitespace().collect();
        let value = match inner.as_slice() {
            ["var", name] => vars.get(*name).cloned().with_context(|| {
                format!(
                    "{file}: $(var {name}) has no value: declare it with `- arg: {{name: {name}}}` and give {name}:=VALUE"
                )
            })?,
            ["env", name] => std::env::var(name)
                .with_context(|| format!("{file}: environment variable {name} is not set"))?,
            ["env", name, default] => std::env::var(name).unwrap_or_else(|_| default.to_string()),
            ["dirname"] => dir.display().to_string(),
            other => bail!(
                "{file}: unsupported substitution $({}) (forcemap reads $(var NAME), $(env NAME [DEFAULT]), $(dirname))",
                other.join(" ")
            ),
        };
        out.push_str(&value);
        rest = &after[j + 1..];
    }
    out.push_str(rest);
    Ok(out)
}

/// A parameter value as the text of `-p name:=value` (a YAML scalar or flow sequence).
fn value_text(
    v: &serde_json::Value,
    sub: &dyn Fn(&str) -> anyhow::Result<String>,
) -> anyhow::Result<String> {
    Ok(match v {
        serde_json::Value::String(raw) => {
            let s = sub(raw)?;
            // Keep a literal string a string when it would read as another type; the result
            // of a substitution is typed from its text, as ROS 2 launch does.
            let plain = raw.contains("$(")
                || s.parse::<f64>().is_err()
                    && !matches!(
                        s.as_str(),
                        "true" | "false" | "yes" | "no" | "on" | "off" | "null" | "~" | ""
                    )
                    && !s
                        .starts_with(['[', '{', '\'', '"', '&', '*', '!', '|', '>', '%', '@', '`'])
                    && !s.contains(": ")
                    && !s.contains(" #");
            if plain {
                s
            } else {
                format!("'{}'", s.replace('\'', "''"))
            }
        }
        serde_json::Value::Array(items) => format!(
            "[{}]",
            items
                .iter()
                .map(|i| value_text(i, sub))
                .collect::<anyhow::Result<Vec<_>>>()?
                .join(", ")
        ),
        serde_json::Value::Null => bail!("a null parameter value"),
        serde_json::Value::Object(_) => bail!("a mapping as a parameter value"),
        other => other.to_string(),
    })
}

/// Reads a launch file and resolves it with the launch arguments `name:=value`.
pub fn plan(path: &Path, args: &[String]) -> anyhow::Result<Vec<LaunchNode>> {
    let file = path.display().to_string();
    let text = std::fs::read_to_string(path).with_context(|| format!("reading {file}"))?;
    let doc: LaunchFile = serde_saphyr::from_str(&text)
        .map_err(|e| anyhow::anyhow!("{file}: not a ROS 2 YAML launch file: {e}"))?;
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let dir = dir.canonicalize().unwrap_or_else(|_| dir.to_path_buf());

    let mut given: BTreeMap<String, String> = BTreeMap::new();
    for a in args {
        let Some((k, v)) = a.split_once(":=") else {
            bail!("launch argument '{a}': expected name:=value");
        };
        given.insert(k.to_string(), v.to_string());
    }
    let mut vars: BTreeMap<String, String> = BTreeMap::new();
    let mut nodes = Vec::new();
    let mut names = std::collections::BTreeSet::new();
    for e in &doc.launch {
        match e {
            Entry::Arg(a) => {
                let v = match (given.get(&a.name), &a.default) {
                    (Some(v), _) => v.clone(),
                    (None, Some(d)) => {
                        let d = match d {
                            serde_json::Value::String(s) => s.clone(),
                            other => other.to_string(),
                        };
                        substitute(&d, &vars, &dir, &file)?
                    }
                    (None, None) => bail!(
                        "{file}: launch argument '{}' has no default: give {}:=VALUE",
                        a.name,
                        a.name
                    ),
                };
                vars.insert(a.name.clone(), v);
            }
            Entry::Node(n) => {
                let sub = |s: &str| substitute(s, &vars, &dir, &file);
                if n.pkg != "forcemap" {
                    bail!(
                        "{file}: node pkg '{}': forcemap launches its own nodes only (pkg: forcemap)",
                        n.pkg
                    );
                }
                if !crate::node::KINDS.contains(&n.exec.as_str()) {
                    bail!(
                        "{file}: exec '{}': forcemap's nodes are {}",
                        n.exec,
                        crate::node::KINDS.join(", ")
                    );
                }
                let name = match &n.name {
                    Some(s) => sub(s)?,
                    None => n.exec.clone(),
                };
                let mut args = vec![
                    "--ros-args".to_string(),
                    "-r".into(),
                    format!("__node:={name}"),
                ];
                let ns = match &n.namespace {
                    Some(s) => sub(s)?,
                    None => String::new(),
                };
                if !ns.is_empty() {
                    args.push("-r".into());
                    args.push(format!(
                        "__ns:={}",
                        if ns.starts_with('/') {
                            ns.clone()
                        } else {
                            format!("/{ns}")
                        }
                    ));
                }
                let fq = format!("{}/{name}", ns.trim_end_matches('/'));
                if !names.insert(fq.clone()) {
                    bail!("{file}: two nodes named {fq}");
                }
                for p in &n.param {
                    match (&p.name, &p.value, &p.from) {
                        (None, None, Some(from)) => {
                            let f = sub(from)?;
                            if !Path::new(&f).exists() {
                                bail!("{file}: node {name}: params file {f} does not exist");
                            }
                            args.push("--params-file".into());
                            args.push(f);
                        }
                        (Some(k), Some(v), None) => {
                            let t = value_text(v, &sub)
                                .with_context(|| format!("{file}: node {name}: param {k}"))?;
                            args.push("-p".into());
                            args.push(format!("{k}:={t}"));
                        }
                        _ => bail!(
                            "{file}: node {name}: each param is either {{name, value}} or {{from: FILE}}"
                        ),
                    }
                }
                for r in &n.remap {
                    args.push("-r".into());
                    args.push(format!("{}:={}", sub(&r.from)?, sub(&r.to)?));
                }
                let shutdown_on_exit = match n.on_exit.as_deref() {
                    None => false,
                    Some("shutdown") => true,
                    Some(other) => bail!(
                        "{file}: node {name}: on_exit '{other}': forcemap knows on_exit: shutdown"
                    ),
                };
                nodes.push(LaunchNode {
                    label: fq.trim_start_matches('/').to_string(),
                    name,
                    exec: n.exec.clone(),
                    args,
                    shutdown_on_exit,
                });
            }
        }
    }
    if let Some(unused) = given.keys().find(|k| !vars.contains_key(*k)) {
        bail!(
            "launch argument '{unused}' is not declared in {file} (declared: {})",
            vars.keys().cloned().collect::<Vec<_>>().join(", ")
        );
    }
    if nodes.is_empty() {
        bail!("{file}: no nodes to launch");
    }
    // A unique name is label enough; shared names keep their namespace.
    for i in 0..nodes.len() {
        if nodes.iter().filter(|n| n.name == nodes[i].name).count() == 1 {
            nodes[i].label = nodes[i].name.clone();
        }
    }
    Ok(nodes)
}

/// Copies a child's output line by line, prefixed with its node name.
fn forward(
    name: String,
    input: impl std::io::Read + Send + 'static,
    to_stderr: bool,
) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        for line in BufReader::new(input).lines() {
            let Ok(line) = line else { break };
            if to_stderr {
                let _ = writeln!(std::io::stderr().lock(), "[{name}] {line}");
            } else {
                let mut out = std::io::stdout().lock();
                let _ = writeln!(out, "[{name}] {line}");
                let _ = out.flush();
            }
        }
    })
}

fn signal(child: &Child, sig: nix::sys::signal::Signal) {
    let _ = nix::sys::signal::kill(nix::unistd::Pid::from_raw(child.id() as i32), sig);
}

/// Starts the nodes of the launch file `file` with launch arguments `args` (`name:=value`) as
/// children of this process (`forcemap node KIND ...`), or with `dry_run` prints their command
/// lines only.
pub fn run(file: &Path, args: &[String], dry_run: bool) -> anyhow::Result<()> {
    let nodes = plan(file, args)?;
    let exe = std::env::current_exe().context("finding the forcemap executable")?;
    if dry_run {
        for n in &nodes {
            println!("{} node {} {}", exe.display(), n.exec, n.args.join(" "));
        }
        return Ok(());
    }
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(sig, stop.clone()).context("installing the signal handler")?;
    }
    let mut children: Vec<(LaunchNode, Child, Option<std::process::ExitStatus>)> = Vec::new();
    let mut pipes = Vec::new();
    for n in nodes {
        let mut child = Command::new(&exe)
            .arg("node")
            .arg(&n.exec)
            .args(&n.args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .stdin(Stdio::null())
            .spawn()
            .with_context(|| format!("starting node {}", n.label))?;
        pipes.push(forward(
            n.label.clone(),
            child.stdout.take().expect("piped"),
            false,
        ));
        pipes.push(forward(
            n.label.clone(),
            child.stderr.take().expect("piped"),
            true,
        ));
        println!("[launch] started {} (pid {})", n.label, child.id());
        children.push((n, child, None));
    }
    // Supervise until stopped, a shutdown node ends, or all have ended.
    let mut reason = String::new();
    while reason.is_empty() {
        if stop.load(Ordering::SeqCst) {
            reason = "interrupted".into();
            break;
        }
        for (n, c, status) in &mut children {
            if status.is_none()
                && let Some(s) = c.try_wait()?
            {
                *status = Some(s);
                println!("[launch] {} exited ({s})", n.label);
                if n.shutdown_on_exit {
                    reason = format!("{} ended", n.label);
                } else if !s.success() {
                    reason = format!("{} failed", n.label);
                }
            }
        }
        if children.iter().all(|(_, _, s)| s.is_some()) && reason.is_empty() {
            reason = "all nodes ended".into();
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    // Stop the rest: SIGINT, then SIGKILL after a grace period.
    let running: Vec<String> = children
        .iter()
        .filter(|(_, _, s)| s.is_none())
        .map(|(n, _, _)| n.label.clone())
        .collect();
    if !running.is_empty() {
        println!("[launch] {reason}: stopping {}", running.join(", "));
    }
    for (_, c, s) in &children {
        if s.is_none() {
            signal(c, nix::sys::signal::Signal::SIGINT);
        }
    }
    let grace = Instant::now() + Duration::from_secs(10);
    let mut killed = Vec::new();
    for (n, c, status) in &mut children {
        while status.is_none() {
            if let Some(s) = c.try_wait()? {
                *status = Some(s);
                println!("[launch] {} exited ({s})", n.label);
            } else if Instant::now() > grace {
                signal(c, nix::sys::signal::Signal::SIGKILL);
                *status = Some(c.wait()?);
                killed.push(n.label.clone());
            } else {
                std::thread::sleep(Duration::from_millis(20));
            }
        }
    }
    for p in pipes {
        let _ = p.join();
    }
    let failed: Vec<String> = children
        .iter()
        .filter(|(_, _, s)| !s.is_some_and(|s| s.success()))
        .map(|(n, _, s)| format!("{} ({})", n.label, s.map_or("?".into(), |s| s.to_string())))
        .collect();
    if !killed.is_empty() {
        bail!(
            "{} did not stop within 10 s and were killed",
            killed.join(", ")
        );
    }
    if !failed.is_empty() && reason != "interrupted" {
        bail!("node(s) failed: {}", failed.join(", "));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn a_launch_file_becomes_node_command_lines() {
        let d = tempfile::tempdir().unwrap();
        write(
            d.path(),
            "p.yaml",
            "/**:\n  ros__parameters:\n    mass_kg: 36\n",
        );
        let f = write(
            d.path(),
            "x.launch.yaml",
            "launch:\n- arg: {name: out, default: /tmp/o}\n- arg: {name: model, default: coulomb}\n- node:\n    pkg: forcemap\n    exec: identifier\n    name: ident\n    namespace: rig\n    on_exit: shutdown\n    param:\n    - {from: $(dirname)/p.yaml}\n    - {name: model, value: $(var model)}\n    - {name: state_file, value: $(var out)/s.json}\n    - {name: tag, value: '36'}\n    - {name: poly_order, value: [3, 1]}\n    remap:\n    - {from: theta, to: /ctrl/theta}\n",
        );
        let nodes = plan(&f, &["model:=linear".to_string()]).unwrap();
        assert_eq!(nodes.len(), 1);
        let n = &nodes[0];
        assert!(n.shutdown_on_exit);
        let dir = d.path().canonicalize().unwrap();
        let expected: Vec<String> = [
            "--ros-args",
            "-r",
            "__node:=ident",
            "-r",
            "__ns:=/rig",
            "--params-file",
            &format!("{}/p.yaml", dir.display()),
            "-p",
            "model:=linear",
            "-p",
            "state_file:=/tmp/o/s.json",
            "-p",
            "tag:='36'",
            "-p",
            "poly_order:=[3, 1]",
            "-r",
            "theta:=/ctrl/theta",
        ]
        .iter()
        .map(ToString::to_string)
        .collect();
        assert_eq!(n.args, expected);
    }

    /// The shipped launch files: the main job's nodes are labelled by their names; the
    /// four-poster's, which share names across four corners, by namespace and name.
    #[test]
    fn shared_node_names_are_labelled_with_their_namespace() {
        let configs = Path::new(env!("CARGO_MANIFEST_DIR")).join("../launch_configs");
        let main_job = plan(&configs.join("rig_sim.launch.yaml"), &[]).unwrap();
        let labels: Vec<&str> = main_job.iter().map(|n| n.label.as_str()).collect();
        assert_eq!(
            labels,
            [
                "recorder",
                "harmonic",
                "identifier",
                "diagnoser",
                "monitor",
                "sensor"
            ]
        );
        let four = plan(&configs.join("four_poster.launch.yaml"), &[]).unwrap();
        assert_eq!(four.len(), 16);
        let labels: std::collections::BTreeSet<&str> =
            four.iter().map(|n| n.label.as_str()).collect();
        assert_eq!(labels.len(), 16, "{labels:?}");
        for corner in ["front_left", "front_right", "rear_left", "rear_right"] {
            for kind in ["sensor", "harmonic", "identifier", "monitor"] {
                assert!(
                    labels.contains(format!("{corner}/{kind}").as_str()),
                    "{labels:?}"
                );
            }
        }
    }

    #[test]
    fn mistakes_in_launch_files_are_named() {
        let d = tempfile::tempdir().unwrap();
        let f = write(
            d.path(),
            "a.yaml",
            "launch:\n- node: {pkg: forcemap, exec: sensr}\n",
        );
        let e = plan(&f, &[]).unwrap_err().to_string();
        assert!(e.contains("exec 'sensr'"), "{e}");
        let f = write(
            d.path(),
            "b.yaml",
            "launch:\n- node: {pkg: forcemap, exec: sensor, param: [{name: bag, value: $(var nope)}]}\n",
        );
        let e = format!("{:#}", plan(&f, &[]).unwrap_err());
        assert!(e.contains("$(var nope)"), "{e}");
        let f = write(
            d.path(),
            "c.yaml",
            "launch:\n- arg: {name: out}\n- node: {pkg: forcemap, exec: sensor}\n",
        );
        let e = plan(&f, &[]).unwrap_err().to_string();
        assert!(e.contains("'out' has no default"), "{e}");
        let e = plan(&f, &["out:=x".into(), "oops:=1".into()])
            .unwrap_err()
            .to_string();
        assert!(e.contains("'oops' is not declared"), "{e}");
        let f = write(
            d.path(),
            "d.yaml",
            "launch:\n- node: {pkg: other, exec: sensor}\n",
        );
        let e = plan(&f, &[]).unwrap_err().to_string();
        assert!(e.contains("pkg 'other'"), "{e}");
    }
}
