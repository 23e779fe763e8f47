//! What the identifier persists after every step, and which steps it admits.

use std::path::Path;

use std::collections::BTreeMap;

use anyhow::{Context as _, bail};
use forcemap_math::identify::{
    EquationAccumulator, FdMultiOptions, Identification, IdentifyError, IdentifyWarning, Method,
    Weighting, accumulate_multisines, moving_mass_hint, step_equations,
};
use forcemap_math::model::Model;
use forcemap_math::phasor::{HarmonicAnalysis, MultisineAnalysis};
use forcemap_math::recipe::{Setup, SetupSpec};
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::msg::HarmonicPhasors;
use serde::{Deserialize, Serialize};

/// What the identifier persists.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IdentifierState {
    pub version: u32,
    pub weighting: Weighting,
    /// The setup the equations were made with (e.g. `base-excited, mass 36 kg`).
    pub setup: String,
    pub accumulator: EquationAccumulator,
    /// The last step added and its phasors' reference time, to skip steps already added
    /// (replayed history after a restart) and to notice a new run.
    pub last_step: Option<u32>,
    pub last_t_ref: Option<Time>,
    /// The setup itself, to rebuild the equations for another model, method or weighting
    /// (absent in version-1 files).
    #[serde(default)]
    pub setup_spec: Option<SetupSpec>,
    /// The phasors of every step admitted since the state began, in order (absent in version-1
    /// files): a few kilobytes a step, kept so that a new model, method or weighting can be
    /// solved from the same steps without the samples.
    #[serde(default)]
    pub phasors: Vec<HarmonicPhasors>,
    /// The excited lines of each periodic multisine step among `phasors`, by step (absent
    /// before version 3): their equations are not accumulated but solved with the accumulated
    /// ones, in two passes, whenever theta is ([`IdentifierState::solve_with_flags`]).
    #[serde(default)]
    pub multisine_lines: BTreeMap<u32, Vec<usize>>,
    /// The moving mass the accumulated fd-multi equations were weighted with
    /// ([`FdMultiOptions::moving_mass_hint_kg`]: an element test whose mass is identified and
    /// whose acceleration is not measured), the first-harmonic fit of the kept sine steps
    /// ([`IdentifierState::moving_mass_hint`]); absent in older files (none).
    #[serde(default)]
    pub moving_mass_hint_kg: Option<f64>,
}

/// Version 2 added `setup_spec` and `phasors`. A version-1 file still resumes (its equations
/// are whole) but keeps the version, which says its phasors are incomplete: such a state
/// cannot be re-solved for another model. Version 3 added `multisine_lines` (an older
/// identifier would take a multisine step's kept phasors for a sine step's).
const STATE_VERSION: u32 = 3;
const OLDEST_READABLE_VERSION: u32 = 1;

impl IdentifierState {
    /// A fresh state for `model` by `method` on `setup` (described as `setup_text`).
    pub fn new(
        model: &Model,
        method: Method,
        weighting: Weighting,
        setup: &Setup,
        spec: &SetupSpec,
    ) -> Self {
        IdentifierState {
            version: STATE_VERSION,
            weighting,
            setup: spec.to_string(),
            accumulator: EquationAccumulator::new(model, setup, method),
            last_step: None,
            last_t_ref: None,
            setup_spec: Some(spec.clone()),
            phasors: Vec::new(),
            multisine_lines: BTreeMap::new(),
            moving_mass_hint_kg: None,
        }
    }

    /// The kept sine steps' analyses, in the order they were added (a step whose phasors do
    /// not convert is left out: it gave no equations either).
    pub fn sine_analyses(&self) -> Vec<HarmonicAnalysis> {
        self.phasors
            .iter()
            .filter(|ph| ph.harmonic_cap != HarmonicPhasors::MULTISINE_CAP)
            .filter_map(|ph| ph.to_analysis(Time::ZERO).ok())
            .collect()
    }

    /// The moving mass fd-multi's equations of the kept steps are to be weighted with, as
    /// `forcemap identify` weights the same steps (`identify::moving_mass_hint`): for fd-multi
    /// on sine steps alone, converged (a tracking identifier's steps are weighed by their age,
    /// which one fit over them all would not respect), with every step's phasors kept.
    pub fn moving_mass_hint(
        &self,
        model: &Model,
        setup: &Setup,
        method: Method,
        forgetting: f64,
        options: &FdMultiOptions,
    ) -> Option<f64> {
        if method != Method::FdMulti
            || forgetting < 1.0
            || !self.multisine_lines.is_empty()
            || !self.keeps_all_phasors()
        {
            return None;
        }
        moving_mass_hint(model, setup, &self.sine_analyses(), options)
    }

    /// The accumulated equations written afresh from the kept sine steps with `options` (a new
    /// moving-mass hint changes every step's weights); a step that gives no equations is
    /// skipped, as when it arrived.
    pub fn rebuild_sine_equations(
        &mut self,
        model: &Model,
        setup: &Setup,
        method: Method,
        options: &FdMultiOptions,
    ) {
        let mut acc = EquationAccumulator::new(model, setup, method);
        for an in self.sine_analyses() {
            if let Ok(blk) = step_equations(model, setup, method, &an, options) {
                // A block of the right shape always adds.
                let _ = acc.add(&blk);
            }
        }
        self.accumulator = acc;
        self.moving_mass_hint_kg = options.moving_mass_hint_kg;
    }

    /// Steps added so far: the accumulated ones and the multisine steps.
    pub fn steps_added(&self) -> usize {
        self.accumulator.steps_added() + self.multisine_lines.len()
    }

    /// The kept multisine steps' analyses, in the order they were added.
    pub fn multisine_analyses(&self) -> Result<Vec<MultisineAnalysis>, IdentifyError> {
        self.phasors
            .iter()
            .filter(|ph| ph.harmonic_cap == HarmonicPhasors::MULTISINE_CAP)
            .map(|ph| {
                let step = ph.step as usize;
                let fail = |problem: String| IdentifyError::Step { step, problem };
                let lines = self.multisine_lines.get(&ph.step).ok_or_else(|| {
                    fail("the state keeps no excited lines of this multisine".into())
                })?;
                let an = ph
                    .to_analysis(Time::ZERO)
                    .map_err(|e| fail(e.to_string()))?;
                MultisineAnalysis::from_harmonic_analysis(&an, lines.clone())
                    .map_err(|e| fail(e.to_string()))
            })
            .collect()
    }

    /// Theta of `sines` (this state's accumulated equations, or them with a provisional step)
    /// and this state's multisine steps, whose equations are added in two passes as `forcemap
    /// identify` adds them ([`accumulate_multisines`]), with the flags of
    /// [`EquationAccumulator::solve_with_flags`].
    pub fn solve_with_flags(
        &self,
        sines: &EquationAccumulator,
        model: &Model,
        options: &FdMultiOptions,
    ) -> Result<(Identification, Vec<IdentifyWarning>), IdentifyError> {
        if self.multisine_lines.is_empty() {
            return sines.solve_with_flags();
        }
        let setup = self
            .setup_spec
            .as_ref()
            .ok_or_else(|| IdentifyError::Step {
                step: self.last_step.unwrap_or(0) as usize,
                problem: "the state keeps no setup to write the multisine equations with".into(),
            })?
            .setup()
            .map_err(|e| IdentifyError::Step {
                step: self.last_step.unwrap_or(0) as usize,
                problem: e.to_string(),
            })?;
        let multisines = self.multisine_analyses()?;
        accumulate_multisines(sines, model, &setup, &multisines, options)?.solve_with_flags()
    }

    /// Whether the state holds the phasors of every step in its equations (not so for a state
    /// resumed from a version-1 file).
    pub fn keeps_all_phasors(&self) -> bool {
        self.version >= 2 && self.setup_spec.is_some()
    }

    /// Reads a persisted state; `None` when there is no file.
    pub fn load(path: &Path) -> anyhow::Result<Option<IdentifierState>> {
        let text = match std::fs::read_to_string(path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
        };
        let s: IdentifierState = serde_json::from_str(&text)
            .with_context(|| format!("{}: not an identifier state file", path.display()))?;
        if !(OLDEST_READABLE_VERSION..=STATE_VERSION).contains(&s.version) {
            bail!(
                "{}: state version {} (this identifier reads versions {OLDEST_READABLE_VERSION} to {STATE_VERSION})",
                path.display(),
                s.version
            );
        }
        Ok(Some(s))
    }

    /// Writes the state atomically (temporary file, fsync, rename), so a crash leaves either
    /// the old or the new state, never a torn one.
    pub fn save(&self, path: &Path) -> anyhow::Result<()> {
        use std::io::Write as _;
        let dir = path.parent().filter(|d| !d.as_os_str().is_empty());
        if let Some(d) = dir {
            std::fs::create_dir_all(d).with_context(|| format!("creating {}", d.display()))?;
        }
        let tmp = path.with_extension("json.partial");
        let text = serde_json::to_string(self).context("serialising the identifier state")?;
        let mut f =
            std::fs::File::create(&tmp).with_context(|| format!("creating {}", tmp.display()))?;
        f.write_all(text.as_bytes())
            .and_then(|()| f.sync_all())
            .with_context(|| format!("writing {}", tmp.display()))?;
        std::fs::rename(&tmp, path)
            .with_context(|| format!("renaming {} to {}", tmp.display(), path.display()))?;
        Ok(())
    }
}

/// What to do with a step's phasors given the state.
#[derive(Debug, PartialEq)]
pub enum Admit {
    Add,
    /// Already added (history replayed to a restarted identifier).
    Duplicate,
    /// An earlier step number with a later time: a new run; start over.
    NewRun,
}

pub fn admit(state: &IdentifierState, step: u32, t_ref: Time) -> Admit {
    match (state.last_step, state.last_t_ref) {
        (Some(ls), Some(lt)) => {
            if t_ref <= lt {
                Admit::Duplicate
            } else if step <= ls {
                Admit::NewRun
            } else {
                Admit::Add
            }
        }
        _ => Admit::Add,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use forcemap_math::model::ModelOptions;

    const RIG: Setup = Setup::BaseExcited { mass_kg: 36.0 };
    const RIG_SPEC: SetupSpec = SetupSpec::BaseExcited { mass_kg: 36.0 };

    #[test]
    fn steps_are_added_once_and_a_new_run_starts_over() {
        let model = Model::by_name("linear", &ModelOptions::default()).unwrap();
        let mut s =
            IdentifierState::new(&model, Method::FdMulti, Weighting::Noise, &RIG, &RIG_SPEC);
        let t = |s: i64| Time::from_nanos(s * 1_000_000_000);
        assert_eq!(admit(&s, 0, t(10)), Admit::Add);
        s.last_step = Some(3);
        s.last_t_ref = Some(t(50));
        assert_eq!(admit(&s, 2, t(40)), Admit::Duplicate);
        assert_eq!(admit(&s, 3, t(50)), Admit::Duplicate);
        assert_eq!(admit(&s, 4, t(60)), Admit::Add);
        assert_eq!(admit(&s, 0, t(100)), Admit::NewRun);
    }

    #[test]
    fn state_round_trips_through_its_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sub/state.json");
        let model = Model::by_name("coulomb", &ModelOptions::default()).unwrap();
        let mut s =
            IdentifierState::new(&model, Method::FdMulti, Weighting::Uniform, &RIG, &RIG_SPEC);
        s.last_step = Some(7);
        s.last_t_ref = Some(Time::from_nanos(123_456_789));
        s.save(&path).unwrap();
        assert_eq!(IdentifierState::load(&path).unwrap(), Some(s));
        assert!(!path.with_extension("json.partial").exists());
        std::fs::write(&path, "{not json").unwrap();
        let e = IdentifierState::load(&path).unwrap_err();
        assert!(
            format!("{e:#}").contains("not an identifier state file"),
            "{e:#}"
        );
        assert_eq!(
            IdentifierState::load(&dir.path().join("none.json")).unwrap(),
            None
        );
    }

    /// A version-1 file (before the phasors were kept) still resumes, but says it cannot be
    /// re-solved; a version from the future is refused by name.
    #[test]
    fn version_one_files_resume_without_phasors_and_newer_ones_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("state.json");
        let model = Model::by_name("linear", &ModelOptions::default()).unwrap();
        let s = IdentifierState::new(&model, Method::FdMulti, Weighting::Noise, &RIG, &RIG_SPEC);
        assert!(s.keeps_all_phasors());
        let mut v: serde_json::Value = serde_json::to_value(&s).unwrap();
        let obj = v.as_object_mut().unwrap();
        obj.remove("phasors");
        obj.remove("setup_spec");
        obj.insert("version".into(), 1.into());
        std::fs::write(&path, v.to_string()).unwrap();
        let old = IdentifierState::load(&path).unwrap().unwrap();
        assert_eq!(old.version, 1);
        assert!(old.phasors.is_empty());
        assert!(!old.keeps_all_phasors());
        assert_eq!(old.accumulator, s.accumulator);
        v["version"] = 4.into();
        std::fs::write(&path, v.to_string()).unwrap();
        let e = IdentifierState::load(&path).unwrap_err();
        assert!(format!("{e:#}").contains("state version 4"), "{e:#}");
    }
}
