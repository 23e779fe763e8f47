//! Phasors held until their setup is known: what the identifier and the diagnoser both do
//! with a step whose rig mass has not arrived yet (it comes from a parameter or, later, on the
//! rig's `parameters` topic), in one place. A periodic multisine step's phasors (its averaged
//! period's bins, `harmonic_cap` [`HarmonicPhasors::MULTISINE_CAP`]) are also held until the
//! `ExcitationState` of their step names the driven channel, on which their excited lines are
//! found ([`excited_lines_of`], as a bag's reader finds them on the samples).

use std::collections::VecDeque;

use forcemap_math::phasor::{HarmonicAnalysis, MultisineAnalysis, excited_lines_of};
use forcemap_math::recipe::{RecipeError, SetupConstants, SetupKind, SetupSpec};
use forcemap_math::record::Channel;
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::msg::{ExcitationState, HarmonicPhasors};

/// What reaches a node that consumes phasors.
#[derive(Debug, Clone)]
pub enum Input {
    Phasors(Box<HarmonicPhasors>),
    /// The rig's mass from its `parameters` topic.
    RigMass(f64),
    /// A step's excitation state: a multisine's names the channel its lines are found on.
    Excitation(Box<ExcitationState>),
}

/// A step whose setup is known.
#[derive(Debug, Clone)]
pub struct Ready {
    pub phasors: HarmonicPhasors,
    pub analysis: HarmonicAnalysis,
    pub setup: SetupSpec,
    /// A periodic multisine step: its averaged period with the lines found.
    pub multisine: Option<MultisineAnalysis>,
}

/// The multisine steps whose driven channel a node remembers (the excitation topic's depth).
const KEEP_MULTISINE_PLANS: usize = 64;

/// What a MULTISINE `ExcitationState` says about its step's phasors.
#[derive(Debug, Clone)]
struct MultisinePlan {
    step: u32,
    start_time: Time,
    base_frequency_hz: f64,
    driven: Channel,
}

/// Holds phasors until their setup resolves.
#[derive(Debug, Clone)]
pub struct SetupGate {
    /// The node's own parameters: they win over the topic.
    given: SetupConstants,
    /// What the rig's parameters topic said.
    carried: SetupConstants,
    /// Phasors held, in the order they arrived (a step after a held one is held too, so that
    /// steps are let through in order).
    waiting: Vec<HarmonicPhasors>,
    /// The latest MULTISINE excitation states, newest last.
    multisine_plans: VecDeque<MultisinePlan>,
}

impl SetupGate {
    /// A gate that lets multisine phasors through with their excited lines, once the
    /// `ExcitationState` of their step ([`Input::Excitation`]) names the driven channel.
    pub fn new(given: SetupConstants) -> SetupGate {
        SetupGate {
            given,
            carried: SetupConstants::default(),
            waiting: Vec::new(),
            multisine_plans: VecDeque::new(),
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
            Input::Excitation(state) => {
                self.note_excitation(&state);
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
        let last = batch.len().saturating_sub(1);
        for (i, ph) in batch.into_iter().enumerate() {
            if !self.waiting.is_empty() {
                self.waiting.push(ph);
                continue;
            }
            let step = ph.step;
            let multisine = ph.harmonic_cap == HarmonicPhasors::MULTISINE_CAP;
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
            let Some(setup) = setup_of(kind, &constants)? else {
                log.push(format!(
                    "step {step}: waiting for the rig's mass (parameter mass_kg or the rig's parameters topic)"
                ));
                self.waiting.push(ph);
                continue;
            };
            let multisine = if multisine {
                let Some(driven) = self.driven_of(&ph) else {
                    if i < last {
                        // Phasors of a later step have arrived: the state of this one
                        // (published when it started, on a latched topic) is not coming.
                        log.push(format!(
                            "step {step}: multisine phasors refused: no MULTISINE ExcitationState of this step arrived to name the driven channel its lines are found on"
                        ));
                    } else {
                        log.push(format!(
                            "step {step}: multisine phasors waiting for the ExcitationState of their step (it names the driven channel their lines are found on)"
                        ));
                        self.waiting.push(ph);
                    }
                    continue;
                };
                match excited_lines_of(&analysis, driven)
                    .and_then(|lines| MultisineAnalysis::from_harmonic_analysis(&analysis, lines))
                {
                    Ok(ms) => Some(ms),
                    Err(e) => {
                        log.push(format!("step {step}: phasors refused: {e}"));
                        continue;
                    }
                }
            } else {
                None
            };
            ready.push(Ready {
                phasors: ph,
                analysis,
                setup,
                multisine,
            });
        }
        Ok(ready)
    }

    /// Remembers the driven channel of a MULTISINE state (others are not needed).
    fn note_excitation(&mut self, state: &ExcitationState) {
        if state.kind != ExcitationState::MULTISINE {
            return;
        }
        let Ok(driven) = state.driven() else {
            return;
        };
        self.multisine_plans.push_back(MultisinePlan {
            step: state.step,
            start_time: state.start_time,
            base_frequency_hz: state.frequency_hz,
            driven,
        });
        while self.multisine_plans.len() > KEEP_MULTISINE_PLANS {
            self.multisine_plans.pop_front();
        }
    }

    /// The driven channel of the multisine whose phasors `ph` are: the newest MULTISINE state
    /// of their step, base frequency and run (it started before their first used period).
    fn driven_of(&self, ph: &HarmonicPhasors) -> Option<Channel> {
        self.multisine_plans
            .iter()
            .rev()
            .find(|p| {
                p.step == ph.step
                    && p.base_frequency_hz == ph.frequency_hz
                    && p.start_time <= ph.t_ref
            })
            .map(|p| p.driven)
    }
}

impl SetupGate {
    /// The analysis and setup of phasors that are not to be held (a step in progress, whose
    /// next phasors replace these): `None` when they are refused or their setup is not known
    /// yet (nothing is logged; the step's final phasors say why).
    pub fn resolve_now(&self, ph: &HarmonicPhasors) -> Option<(HarmonicAnalysis, SetupSpec)> {
        if ph.harmonic_cap == HarmonicPhasors::MULTISINE_CAP {
            return None;
        }
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
