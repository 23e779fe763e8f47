//! The monitor node: a consumer of live theta, as a control node would be. It prints theta as
//! it converges and, once the exciter is idle and theta has stopped changing, a summary (with
//! the truth when the rig's parameters topic carries it, as the simulated rig's does), writes it
//! as JSON if asked, and exits. A run that ends before any identifier has matched its theta
//! (discovery is slow on a loaded host) is not taken for a run without theta: the monitor waits
//! for an identifier, whose latched theta then arrives at once.
//!
//! Parameters: `quiet_s` (how long theta must stay unchanged after the run ends; 3),
//! `timeout_s` (give up after this long without a run end; 0 = never), `summary_json` (path;
//! empty: none).

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use forcemap_msgs::diagnostic_msgs::DiagnosticStatus;
use forcemap_msgs::msg::{ExcitationState, IdentifiedParameters};
use serde_json::json;
use tokio::sync::mpsc;

use crate::log_line;
use crate::ros::{NodeSetup, OnTakeError, RosNode, forward, forward_shared, qos};
use forcemap_io::topics;

enum Input {
    Theta(IdentifiedParameters, Instant),
    Excitation(ExcitationState),
    Rig(DiagnosticStatus),
}

pub async fn run(setup: NodeSetup) -> anyhow::Result<()> {
    let p = setup.params.clone();
    let quiet = Duration::from_secs_f64(p.opt_f64("quiet_s")?.unwrap_or(3.0).max(0.0));
    let timeout_s = p.opt_f64("timeout_s")?.unwrap_or(0.0);
    let summary_json = p
        .opt_str("summary_json")?
        .filter(|s| !s.is_empty())
        .map(std::path::PathBuf::from);

    let mut ros = RosNode::start(setup.clone())?;
    let theta =
        std::sync::Arc::new(ros.subscription::<IdentifiedParameters>(topics::THETA, qos::theta())?);
    let excitation = ros.subscription::<ExcitationState>(topics::EXCITATION, qos::excitation())?;
    let rig = ros.subscription::<DiagnosticStatus>(topics::PARAMETERS, qos::parameters())?;
    let (tx, mut rx) = mpsc::unbounded_channel::<Input>();
    forward_shared(theta.clone(), tx.clone(), OnTakeError::Stop, |m, _| {
        Some(Input::Theta(m, Instant::now()))
    });
    forward(excitation, tx.clone(), OnTakeError::Stop, |m, _| {
        Some(Input::Excitation(m))
    });
    forward(rig, tx, OnTakeError::Stop, |m, _| Some(Input::Rig(m)));

    let started = Instant::now();
    let mut truth: BTreeMap<String, f64> = BTreeMap::new();
    let mut latest: Option<IdentifiedParameters> = None;
    let mut last_change = Instant::now();
    let mut idle_since: Option<Instant> = None;
    let mut sine_steps = 0usize;
    let mut multisine_steps = 0usize;
    let mut updates = 0usize;
    // Since when an identifier has been matched on theta (its latched theta follows at once).
    let mut theta_matched_since: Option<Instant> = None;
    let mut told_waiting_for_identifier = false;
    log_line!("watching {}", setup.absolute_topic(topics::THETA));
    loop {
        let input = tokio::select! {
            i = rx.recv() => i,
            () = tokio::time::sleep(Duration::from_millis(200)) => None,
            () = crate::ros::shutdown_signal() => break,
        };
        match input {
            Some(Input::Theta(t, at)) => {
                updates += 1;
                last_change = at;
                let cells: Vec<String> = t
                    .parameter_names
                    .iter()
                    .zip(&t.values)
                    .zip(&t.standard_deviations)
                    .map(|((n, v), s)| format!("{n} {v:>10.4} ±{s:>8.4}"))
                    .collect();
                log_line!(
                    "theta after {:>2} steps | {} | cond {:.1e}",
                    t.steps_used.len(),
                    cells.join(" | "),
                    t.condition_number
                );
                latest = Some(t);
            }
            Some(Input::Excitation(e)) => {
                if e.is_idle() {
                    idle_since.get_or_insert_with(Instant::now);
                } else if e.kind == ExcitationState::SINE {
                    sine_steps += 1;
                } else if e.kind == ExcitationState::MULTISINE {
                    multisine_steps += 1;
                }
            }
            Some(Input::Rig(s)) => {
                for kv in s.values {
                    if let (Some(sym), Ok(v)) = (kv.key.strip_prefix("truth."), kv.value.parse()) {
                        truth.insert(sym.to_string(), v);
                    }
                }
            }
            None => {}
        }
        if theta_matched_since.is_none() && theta.get_publisher_count(&ros.node) > 0 {
            theta_matched_since = Some(Instant::now());
        }
        if let Some(idle) = idle_since
            && idle.elapsed() >= quiet
            && last_change.elapsed() >= quiet
        {
            match theta_matched_since {
                _ if latest.is_some() => break,
                Some(matched) if matched.elapsed() >= quiet => break,
                Some(_) => {}
                None if !told_waiting_for_identifier => {
                    log_line!(
                        "the exciter is idle and no identifier is matched on {} yet: waiting for one",
                        setup.absolute_topic(topics::THETA)
                    );
                    told_waiting_for_identifier = true;
                }
                None => {}
            }
        }
        if timeout_s > 0.0 && started.elapsed().as_secs_f64() > timeout_s {
            bail!("no end of run within timeout_s = {timeout_s} s ({updates} theta updates seen)");
        }
    }

    let Some(t) = latest else {
        log_line!("no theta was published");
        return Ok(());
    };
    log_line!("");
    let planned = match (sine_steps, multisine_steps) {
        (s, 0) => format!("{s} sine steps"),
        (0, m) => format!("{m} multisine steps"),
        (s, m) => format!("{s} sine and {m} multisine steps"),
    };
    log_line!(
        "summary: model '{}' by {}, {} of {planned} used, {} equations, condition number {:.2e}, {} live updates",
        t.model,
        t.method,
        t.steps_used.len(),
        t.equations,
        t.condition_number,
        updates
    );
    let mut rows = Vec::new();
    for ((n, v), s) in t
        .parameter_names
        .iter()
        .zip(&t.values)
        .zip(&t.standard_deviations)
    {
        let tr = truth.get(n).copied();
        let err = tr.map(|tr| 100.0 * (v - tr) / tr);
        log_line!(
            "  {n:<8} {v:>12.4} ± {s:<10.4}{}",
            match (tr, err) {
                (Some(tr), Some(e)) => format!(" truth {tr:>10.4}  error {e:+.2} %"),
                _ => String::new(),
            }
        );
        rows.push(json!({"name": n, "value": v, "std": s, "truth": tr, "error_percent": err}));
    }
    for w in &t.warnings {
        log_line!("  warning: {w}");
    }
    if let Some(path) = summary_json {
        let doc = json!({
            "model": t.model,
            "method": t.method,
            "steps_used": t.steps_used,
            "sine_steps": sine_steps,
            "multisine_steps": multisine_steps,
            "equations": t.equations,
            "condition_number": t.condition_number,
            "live_updates": updates,
            "parameters": rows,
        });
        forcemap_io::atomic::write_atomically(&path, &serde_json::to_string_pretty(&doc)?)
            .with_context(|| format!("writing {}", path.display()))?;
        log_line!("summary written to {}", path.display());
    }
    Ok(())
}
