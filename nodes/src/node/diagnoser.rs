//! The diagnoser node: the gap diagnosis of `forcemap diagnose`, live from the phasor stream.
//! After every step it refits the baseline and each candidate effect on the steps so far
//! (cross-validated by leaving each step out; a periodic multisine step's lines are found on
//! the driven channel its `ExcitationState` names, as the identifier finds them, and every step
//! is then fitted through the identification's equations) and publishes its findings as a
//! `forcemap_msgs/msg/GapDiagnosis` on `diagnosis` and as a status on /diagnostics (OK when the
//! baseline is adequate, WARN with the named effect or "unexplained" otherwise).
//!
//! Parameters: `baseline` (the model the rig model uses; `linear` by default), `atan_m`,
//! `mass_kg` (else the rig's parameters topic), `substructure...` (drive-point setups).

use std::time::Duration;

use anyhow::Context as _;
use forcemap_math::diagnose::{PhasorDiagnosis, PhasorFindings, Verdict};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::recipe::check_mass_kg;
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus};
use forcemap_msgs::msg::{ExcitationState, GapDiagnosis, HarmonicPhasors};
use forcemap_msgs::std_msgs::Header;
use tokio::sync::mpsc;

use crate::log_line;
use crate::node::setup_gate::{Input, SetupGate};
use crate::ros::{NodeSetup, OnTakeError, RosNode, forward, now_time, qos, rig_mass_kg};
use forcemap_io::params::Params;
use forcemap_io::rig_constants;
use forcemap_io::topics;

/// The message of a set of findings.
pub fn diagnosis_message(baseline: &str, f: &PhasorFindings, header: Header) -> GapDiagnosis {
    GapDiagnosis {
        header,
        baseline_model: baseline.to_string(),
        steps: f.steps as u32,
        verdict: f.findings.verdict.name().to_string(),
        top_effect: f
            .findings
            .top_effect
            .map_or(String::new(), |e| e.name().to_string()),
        gap_before_percent: f.findings.gap_before_percent,
        gap_after_percent: f.findings.gap_after_percent,
        noise_floor_percent: f.findings.floor_percent,
        ranked_effects: f
            .ranked_effects
            .iter()
            .map(|e| e.effect.name().to_string())
            .collect(),
        ranked_gap_after_percent: f.ranked_effects.iter().map(|e| e.cv_percent).collect(),
        ranked_significant: f.ranked_effects.iter().map(|e| e.significant).collect(),
    }
}

/// What the diagnoser does about an input.
#[derive(Debug, Clone, PartialEq)]
pub enum Output {
    Log(String),
    Diagnosis(GapDiagnosis),
    /// The verdict for /diagnostics: OK when the baseline is adequate, WARN otherwise.
    Status(DiagnosticStatus),
}

/// The diagnoser's logic without the middleware.
pub struct DiagnoserCore {
    baseline_name: String,
    baseline: Model,
    gate: SetupGate,
    live: Option<PhasorDiagnosis>,
    status_name: String,
}

impl DiagnoserCore {
    /// Reads `baseline` (`linear`), `atan_m`, `mass_kg` and `substructure...`.
    pub fn from_params(p: &Params, status_name: &str) -> anyhow::Result<DiagnoserCore> {
        let baseline_name = p.opt_str("baseline")?.unwrap_or("linear").to_string();
        let baseline = Model::by_name(
            &baseline_name,
            &ModelOptions {
                atan_slope_s_per_m: p.opt_f64("atan_m")?,
                polynomial_order: None,
            },
        )
        .with_context(|| format!("baseline = '{baseline_name}'"))?;
        let given = rig_constants::from_params(p)?;
        if let Some(m) = given.mass_kg {
            check_mass_kg(m)?;
        }
        Ok(DiagnoserCore {
            baseline_name,
            baseline,
            gate: SetupGate::new(given),
            live: None,
            status_name: status_name.to_string(),
        })
    }

    pub fn baseline_name(&self) -> &str {
        &self.baseline_name
    }

    /// Handles one input at wall-clock time `now`; refits every candidate on the steps so far
    /// (seconds of CPU on a long run).
    pub fn handle(&mut self, input: Input, now: Time) -> anyhow::Result<Vec<Output>> {
        let mut log = Vec::new();
        let ready = self.gate.admit(input, &mut log)?;
        let mut out: Vec<Output> = log.into_iter().map(Output::Log).collect();
        for r in ready {
            let setup = r.setup.setup()?;
            let baseline = &self.baseline;
            let d = self
                .live
                .get_or_insert_with(|| PhasorDiagnosis::new(setup, baseline.clone()));
            match r.multisine {
                Some(ms) => d.push_multisine(ms),
                None => d.push(r.analysis),
            }
            if d.steps() < d.min_steps() {
                out.push(Output::Log(format!(
                    "after {} steps: waiting for {} steps (the diagnosis leaves one step out at a time)",
                    d.steps(),
                    d.min_steps()
                )));
                continue;
            }
            let findings = match d.findings() {
                Ok(f) => f,
                Err(e) => {
                    out.push(Output::Log(format!(
                        "after {} steps: no diagnosis yet: {e}",
                        d.steps()
                    )));
                    continue;
                }
            };
            out.push(Output::Log(format!(
                "after {} steps: {} ({}; floor {:.2} %)",
                findings.steps,
                findings.findings.headline(),
                findings.findings.evidence.measure(),
                findings.findings.floor_percent
            )));
            out.push(Output::Diagnosis(diagnosis_message(
                &self.baseline_name,
                &findings,
                Header::new(now, &r.phasors.header.frame_id),
            )));
            out.push(Output::Status(self.status(&findings)));
        }
        Ok(out)
    }

    fn status(&self, found: &PhasorFindings) -> DiagnosticStatus {
        let findings = &found.findings;
        let level = match findings.verdict {
            Verdict::Adequate => DiagnosticStatus::OK,
            _ => DiagnosticStatus::WARN,
        };
        let message = findings.status(&self.baseline_name);
        let mut status = DiagnosticStatus::new(level, &self.status_name, message, "diagnoser")
            .with_value("verdict", findings.verdict.name())
            .with_value("steps", found.steps)
            .with_value("gap_before_percent", findings.gap_before_percent)
            .with_value("gap_after_percent", findings.gap_after_percent);
        if let Some(e) = findings.top_effect {
            status = status.with_value("top_effect", e.name());
        }
        status
    }
}

/// The node: [`DiagnoserCore`] behind its subscriptions and publishers.
pub async fn run(setup: NodeSetup) -> anyhow::Result<()> {
    let fq = setup.fully_qualified_name();
    let mut core = DiagnoserCore::from_params(&setup.params, &format!("{fq}: gap diagnosis"))?;

    let mut ros = RosNode::start(setup.clone())?;
    let phasors = ros.subscription::<HarmonicPhasors>(topics::PHASORS, qos::phasors())?;
    let rig = ros.subscription::<DiagnosticStatus>(topics::PARAMETERS, qos::parameters())?;
    // A multisine step's state names the driven channel its lines are found on.
    let excitation = ros.subscription::<ExcitationState>(topics::EXCITATION, qos::excitation())?;
    let diagnosis_pub = ros.publisher::<GapDiagnosis>(topics::DIAGNOSIS, qos::theta())?;
    let diag_pub = ros.publisher::<DiagnosticArray>(topics::DIAGNOSTICS, qos::diagnostics())?;

    let (tx, mut rx) = mpsc::unbounded_channel::<Input>();
    forward(phasors, tx.clone(), OnTakeError::Stop, |m, _| {
        Some(Input::Phasors(Box::new(m)))
    });
    forward(excitation, tx.clone(), OnTakeError::Stop, |m, _| {
        Some(Input::Excitation(Box::new(m)))
    });
    forward(rig, tx, OnTakeError::Stop, |m, _| {
        rig_mass_kg(&m).map(Input::RigMass)
    });

    log_line!(
        "diagnosing the gap of baseline '{}' from {}",
        core.baseline_name(),
        setup.absolute_topic(topics::PHASORS)
    );
    loop {
        let input = tokio::select! {
            i = rx.recv() => match i { Some(i) => i, None => break },
            () = crate::ros::shutdown_signal() => break,
        };
        // The refits take seconds: keep the runtime's other tasks going meanwhile.
        let outputs = tokio::task::block_in_place(|| core.handle(input, now_time()))?;
        for o in outputs {
            match o {
                Output::Log(line) => log_line!("{line}"),
                Output::Diagnosis(msg) => {
                    if let Err(e) = diagnosis_pub.async_publish(msg).await {
                        log_line!("error: publishing the diagnosis: {e:?}");
                    }
                }
                Output::Status(status) => {
                    let _ = diag_pub
                        .async_publish(DiagnosticArray {
                            header: Header::new(now_time(), ""),
                            status: vec![status],
                        })
                        .await;
                }
            }
        }
    }
    tokio::time::sleep(Duration::from_millis(200)).await;
    Ok(())
}
