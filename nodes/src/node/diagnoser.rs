//! The diagnoser node: the gap diagnosis of `forcemap diagnose`, live from the phasor stream.
//! After every step it refits the baseline and each candidate effect on the steps so far
//! (cross-validated by leaving each step out) and publishes its findings as a
//! `forcemap_msgs/msg/GapDiagnosis` on `diagnosis` and as a status on /diagnostics (OK when the
//! baseline is adequate, WARN with the named effect or "unexplained" otherwise).
//!
//! Parameters: `baseline` (the model the rig model uses; `linear` by default), `atan_m`,
//! `mass_kg` (else the rig's parameters topic), `substructure...` (drive-point setups).

use std::time::Duration;

use anyhow::Context as _;
use forcemap_math::diagnose::phasor::MIN_STEPS;
use forcemap_math::diagnose::{PhasorDiagnosis, PhasorFindings, Verdict};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus};
use forcemap_msgs::msg::{GapDiagnosis, HarmonicPhasors};
use forcemap_msgs::std_msgs::Header;
use tokio::sync::mpsc;

use crate::log_line;
use crate::node::identifier::step_setup;
use crate::ros::{NodeSetup, OnTakeError, RosNode, forward, now_time, qos, rig_mass_kg};
use forcemap_io::rig_constants;
use forcemap_io::topics;
use forcemap_math::recipe::{SetupConstants, check_mass_kg};

/// The message of a set of findings.
pub fn diagnosis_message(baseline: &str, f: &PhasorFindings, header: Header) -> GapDiagnosis {
    GapDiagnosis {
        header,
        baseline_model: baseline.to_string(),
        steps: f.steps as u32,
        verdict: f.verdict.name().to_string(),
        top_effect: f.top_effect.map_or(String::new(), |e| e.name().to_string()),
        gap_before_percent: f.gap_before_percent,
        gap_after_percent: f.gap_after_percent,
        noise_floor_percent: f.noise_floor_percent,
        ranked_effects: f
            .ranked_effects
            .iter()
            .map(|e| e.effect.name().to_string())
            .collect(),
        ranked_gap_after_percent: f.ranked_effects.iter().map(|e| e.cv_percent).collect(),
        ranked_significant: f.ranked_effects.iter().map(|e| e.significant).collect(),
    }
}

enum Input {
    Phasors(Box<HarmonicPhasors>),
    RigMass(f64),
}

pub async fn run(setup: NodeSetup) -> anyhow::Result<()> {
    let p = setup.params.clone();
    let baseline_name = p.opt_str("baseline")?.unwrap_or("linear").to_string();
    let baseline = Model::by_name(
        &baseline_name,
        &ModelOptions {
            atan_slope_s_per_m: p.opt_f64("atan_m")?,
            polynomial_order: None,
        },
    )
    .with_context(|| format!("baseline = '{baseline_name}'"))?;
    let given = rig_constants::from_params(&p)?;
    if let Some(m) = given.mass_kg {
        check_mass_kg(m)?;
    }
    // Constants from the rig's parameters topic, used where the node's parameters say nothing.
    let mut carried = SetupConstants::default();
    let fq = setup.fully_qualified_name();

    let mut ros = RosNode::start(setup.clone())?;
    let phasors = ros.subscription::<HarmonicPhasors>(topics::PHASORS, qos::phasors())?;
    let rig = ros.subscription::<DiagnosticStatus>(topics::PARAMETERS, qos::parameters())?;
    let diagnosis_pub = ros.publisher::<GapDiagnosis>(topics::DIAGNOSIS, qos::theta())?;
    let diag_pub = ros.publisher::<DiagnosticArray>(topics::DIAGNOSTICS, qos::diagnostics())?;

    let (tx, mut rx) = mpsc::unbounded_channel::<Input>();
    forward(phasors, tx.clone(), OnTakeError::Stop, |m, _| {
        Some(Input::Phasors(Box::new(m)))
    });
    forward(rig, tx, OnTakeError::Stop, |m, _| {
        rig_mass_kg(&m).map(Input::RigMass)
    });

    log_line!(
        "diagnosing the gap of baseline '{baseline_name}' from {}",
        setup.absolute_topic(topics::PHASORS)
    );
    let status_name = format!("{fq}: gap diagnosis");
    let mut live: Option<PhasorDiagnosis> = None;
    let mut waiting: Vec<HarmonicPhasors> = Vec::new();
    loop {
        let input = tokio::select! {
            i = rx.recv() => match i { Some(i) => i, None => break },
            _ = crate::ros::shutdown_signal() => break,
        };
        let batch = match input {
            Input::RigMass(m) => {
                if carried.mass_kg.is_none() {
                    carried.mass_kg = Some(m);
                }
                std::mem::take(&mut waiting)
            }
            Input::Phasors(ph) => {
                let mut b = std::mem::take(&mut waiting);
                b.push(*ph);
                b
            }
        };
        for ph in batch {
            let analysis = match ph.to_analysis(Time::ZERO) {
                Ok(a) => a,
                Err(e) => {
                    log_line!("step {}: phasors refused: {e}", ph.step);
                    continue;
                }
            };
            let Some(spec) = step_setup(&analysis, &given.clone().or(carried.clone()))? else {
                waiting.push(ph);
                continue;
            };
            let step_setup = spec.setup()?;
            let d = live.get_or_insert_with(|| PhasorDiagnosis::new(step_setup, baseline.clone()));
            d.push(analysis);
            if d.steps() < MIN_STEPS {
                log_line!(
                    "after {} steps: waiting for {MIN_STEPS} steps (the diagnosis leaves one step out at a time)",
                    d.steps()
                );
                continue;
            }
            let findings = match tokio::task::block_in_place(|| d.findings()) {
                Ok(f) => f,
                Err(e) => {
                    log_line!("after {} steps: no diagnosis yet: {e}", d.steps());
                    continue;
                }
            };
            log_line!(
                "after {} steps: {}{}; cross-validated gap {:.2} % -> {:.2} % (noise {:.2} %)",
                findings.steps,
                findings.verdict.name(),
                findings
                    .top_effect
                    .map_or(String::new(), |e| format!(" by {}", e.name())),
                findings.gap_before_percent,
                findings.gap_after_percent,
                findings.noise_floor_percent
            );
            let msg = diagnosis_message(
                &baseline_name,
                &findings,
                Header::new(now_time(), &ph.header.frame_id),
            );
            if let Err(e) = diagnosis_pub.async_publish(msg).await {
                log_line!("error: publishing the diagnosis: {e:?}");
            }
            let level = match findings.verdict {
                Verdict::Adequate => DiagnosticStatus::OK,
                _ => DiagnosticStatus::WARN,
            };
            let message = match (findings.verdict, findings.top_effect) {
                (Verdict::Explained, Some(e)) => format!(
                    "baseline '{baseline_name}' misses {}: gap {:.2} % -> {:.2} %",
                    e.name(),
                    findings.gap_before_percent,
                    findings.gap_after_percent
                ),
                (Verdict::Adequate, _) => format!("baseline '{baseline_name}' is adequate"),
                _ => format!(
                    "baseline '{baseline_name}' has a gap of {:.2} % that no candidate explains",
                    findings.gap_before_percent
                ),
            };
            let mut status = DiagnosticStatus::new(level, &status_name, message, "diagnoser")
                .with_value("verdict", findings.verdict.name())
                .with_value("steps", findings.steps)
                .with_value("gap_before_percent", findings.gap_before_percent)
                .with_value("gap_after_percent", findings.gap_after_percent);
            if let Some(e) = findings.top_effect {
                status = status.with_value("top_effect", e.name());
            }
            let _ = diag_pub
                .async_publish(DiagnosticArray {
                    header: Header::new(now_time(), ""),
                    status: vec![status],
                })
                .await;
        }
    }
    tokio::time::sleep(Duration::from_millis(200)).await;
    Ok(())
}
