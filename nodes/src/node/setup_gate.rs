//! Phasors held until their setup is known: what the identifier and the diagnoser both do
//! with a step whose rig mass has not arrived yet (it comes from a parameter or, later, on the
//! rig's `parameters` topic), in one place.

use forcemap_math::phasor::HarmonicAnalysis;
use forcemap_math::recipe::{RecipeError, SetupConstants, SetupKind, SetupSpec};
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::msg::HarmonicPhasors;

/// What reaches a node that consumes phasors.
#[derive(Debug, Clone)]
pub enum Input {
    Phasors(Box<HarmonicPhasors>),
    /// The rig's mass from its `parameters` topic.
    RigMass(f64),
}

/// A step whose setup is known.
#[derive(Debug, Clone)]
pub struct Ready {
    pub phasors: HarmonicPhasors,
    pub analysis: HarmonicAnalysis,
    pub setup: SetupSpec,
}

/// Holds phasors until their setup resolves.
#[derive(Debug, Clone)]
pub struct SetupGate {
    /// The node's own parameters: they win over the topic.
    given: SetupConstants,
    /// What the rig's parameters topic said.
    carried: SetupConstants,
    waiting: Vec<HarmonicPhasors>,
}

impl SetupGate {
    pub fn new(given: SetupConstants) -> SetupGate {
        SetupGate {
            given,
            carried: SetupConstants::default(),
            waiting: Vec::new(),
        }
    }

    /// The steps that are ready after `input`, in the order they arrived, with a log line
    /// for each thing worth saying. An error is a setup the node cannot run with (an
    /// inconsistent substructure): no later input would fix it.
    pub fn admit(&mut self, input: Input, log: &mut Vec<String>) -> anyhow::Result<Vec<Ready>> {
        let batch = match input {
            Input::RigMass(m) => {
                if self.given.mass_kg.is_none() && self.carried.mass_kg.is_none() {
                    log.push(format!("rig mass {m} kg (from the rig's parameters topic)"));
                    self.carried.mass_kg = Some(m);
                }
                std::mem::take(&mut self.waiting)
            }
            Input::Phasors(ph) => {
                let mut b = std::mem::take(&mut self.waiting);
                b.push(*ph);
                b
            }
        };
        let constants = self.given.clone().or(self.carried.clone());
        let mut ready = Vec::new();
        for ph in batch {
            let step = ph.step;
            if ph.harmonic_cap == HarmonicPhasors::MULTISINE_CAP {
                // Their equations are per line and solved twice (identify::multisine); the
                // accumulator of sine-step blocks does not do that yet.
                log.push(format!(
                    "step {step}: multisine phasors are not identified live (use forcemap identify on the bag); skipped"
                ));
                continue;
            }
            let analysis = match ph.to_analysis(Time::ZERO) {
                Ok(a) => a,
                Err(e) => {
                    log.push(format!("step {step}: phasors refused: {e}"));
                    continue;
                }
            };
            // Phasors that are no setup's (a foreign publisher's, a bad recording) are refused
            // like undecodable ones: what arrives on a topic must not stop the node.
            let kind = match SetupKind::of_channels(|c| {
                analysis.channels.iter().any(|ch| ch.channel == c)
            }) {
                Ok(k) => k,
                Err(e) => {
                    log.push(format!("step {step}: phasors refused: {e}"));
                    continue;
                }
            };
            match setup_of(kind, &constants)? {
                Some(setup) => ready.push(Ready {
                    phasors: ph,
                    analysis,
                    setup,
                }),
                None => {
                    if self.waiting.is_empty() {
                        log.push(format!(
                            "step {step}: waiting for the rig's mass (parameter mass_kg or the rig's parameters topic)"
                        ));
                    }
                    self.waiting.push(ph);
                }
            }
        }
        Ok(ready)
    }
}

impl SetupGate {
    /// The analysis and setup of phasors that are not to be held (a step in progress, whose
    /// next phasors replace these): `None` when they are refused or their setup is not known
    /// yet (nothing is logged; the step's final phasors say why).
    pub fn resolve_now(&self, ph: &HarmonicPhasors) -> Option<(HarmonicAnalysis, SetupSpec)> {
        let analysis = ph.to_analysis(Time::ZERO).ok()?;
        let kind =
            SetupKind::of_channels(|c| analysis.channels.iter().any(|ch| ch.channel == c)).ok()?;
        let constants = self.given.clone().or(self.carried.clone());
        let setup = setup_of(kind, &constants).ok()??;
        Some((analysis, setup))
    }
}

/// The setup of `kind` with the constants known; `None` while a rig's mass is unknown. An
/// error is a constant the node was given wrong (no later message fixes it).
fn setup_of(kind: SetupKind, constants: &SetupConstants) -> anyhow::Result<Option<SetupSpec>> {
    match kind.resolve(constants) {
        Ok(s) => Ok(Some(s)),
        Err(RecipeError::MissingMass) => Ok(None),
        Err(e) => Err(anyhow::anyhow!("the node's parameters: {e}")),
    }
}
