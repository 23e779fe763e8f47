//! `forcemap bench graph --trace`: the latency from a step's last sample to its theta, stage by
//! stage, from the marks the nodes write when traced ([`forcemap_nodes::latency_trace`]) and
//! the bench's own two (the last sample's publish returned, theta arrived).

use std::collections::BTreeMap;

use forcemap_nodes::latency_trace::TraceMark;
use serde_json::json;

/// The bench's mark: the publish of a step's last sample returned.
pub const LAST_SAMPLE_PUBLISHED: &str = "bench.last_sample_published";
/// The bench's mark: the theta that includes the step arrived.
pub const THETA_IN: &str = "bench.theta_in";

/// The stages in path order, each with what happens between the previous mark and it.
pub const STAGES: [(&str, &str); 11] = [
    (LAST_SAMPLE_PUBLISHED, ""),
    (
        "harmonic.sample_in",
        "samples over DDS: bench publish -> harmonic node's loop",
    ),
    (
        "harmonic.step_complete",
        "harmonic: last sample handled, step assembled and checked",
    ),
    (
        "harmonic.analysis_start",
        "harmonic: queue to the analysis task",
    ),
    (
        "harmonic.analysis_done",
        "harmonic: analysis (stream finish; inline when analysed ahead)",
    ),
    ("harmonic.message_built", "harmonic: phasors message built"),
    (
        "harmonic.phasors_published",
        "harmonic: phasors publish (serialise, admit)",
    ),
    (
        "identifier.phasors_in",
        "phasors over DDS: harmonic -> identifier's loop",
    ),
    (
        "identifier.solved",
        "identifier: equations added, theta solved",
    ),
    ("identifier.theta_published", "identifier: theta publish"),
    (THETA_IN, "theta over DDS: identifier -> bench"),
];

/// One step's intervals, in [`STAGES`] order from the second stage.
#[derive(Debug, Clone, PartialEq)]
pub struct StepStages {
    pub rig: usize,
    pub step: u32,
    /// Wall time from the previous stage's mark [ms].
    pub wall_ms: Vec<f64>,
    /// CPU time of the stage's own work [ms], where it is measured.
    pub cpu_ms: Vec<Option<f64>>,
}

/// The intervals of every (rig, step) whose marks are all there, in rig and step order.
/// `marks` are (rig, mark).
pub fn per_step(marks: &[(usize, TraceMark)]) -> Vec<StepStages> {
    let mut by_step: BTreeMap<(usize, u32), BTreeMap<&str, &TraceMark>> = BTreeMap::new();
    for (rig, m) in marks {
        by_step
            .entry((*rig, m.step))
            .or_default()
            .insert(m.stage.as_str(), m);
    }
    by_step
        .into_iter()
        .filter(|(_, s)| STAGES.iter().all(|(name, _)| s.contains_key(name)))
        .map(|((rig, step), s)| {
            let (wall_ms, cpu_ms) = STAGES
                .windows(2)
                .map(|w| {
                    let (previous, stage) = (s[w[0].0], s[w[1].0]);
                    (
                        (stage.wall_ns - previous.wall_ns) as f64 / 1e6,
                        stage.cpu_ns.map(|c| c as f64 / 1e6),
                    )
                })
                .unzip();
            StepStages {
                rig,
                step,
                wall_ms,
                cpu_ms,
            }
        })
        .collect()
}

/// One stage's interval over the steps.
#[derive(Debug, Clone, PartialEq)]
pub struct StageRow {
    pub stage: &'static str,
    pub what: &'static str,
    /// Wall time from the previous stage's mark [ms], sorted.
    pub wall_ms: Vec<f64>,
    /// CPU time of the stage's own work [ms], sorted (empty where not measured).
    pub cpu_ms: Vec<f64>,
}

/// Each stage's intervals over `steps`, sorted.
pub fn breakdown(steps: &[StepStages]) -> Vec<StageRow> {
    STAGES[1..]
        .iter()
        .enumerate()
        .map(|(k, (stage, what))| {
            let mut wall_ms: Vec<f64> = steps.iter().map(|s| s.wall_ms[k]).collect();
            let mut cpu_ms: Vec<f64> = steps.iter().filter_map(|s| s.cpu_ms[k]).collect();
            wall_ms.sort_by(f64::total_cmp);
            cpu_ms.sort_by(f64::total_cmp);
            StageRow {
                stage,
                what,
                wall_ms,
                cpu_ms,
            }
        })
        .collect()
}

/// The breakdown as printed lines.
pub fn lines(rows: &[StageRow], steps: usize) -> Vec<String> {
    let mut out = vec![format!(
        "stages over {steps} steps (wall ms p50 / max; CPU ms of the stage's own work p50 / max where measured):"
    )];
    for r in rows {
        let cpu = if r.cpu_ms.is_empty() {
            String::new()
        } else {
            format!(
                "  CPU {:.3} / {:.3}",
                super::bench::percentile(&r.cpu_ms, 50.0),
                r.cpu_ms.last().copied().unwrap_or(f64::NAN)
            )
        };
        out.push(format!(
            "  {:<66} {:>8.3} / {:>8.3}{cpu}",
            r.what,
            super::bench::percentile(&r.wall_ms, 50.0),
            r.wall_ms.last().copied().unwrap_or(f64::NAN)
        ));
    }
    out
}

/// The breakdown and each step's intervals for the JSON report.
pub fn json(rows: &[StageRow], steps: &[StepStages]) -> serde_json::Value {
    let stages: Vec<serde_json::Value> = rows
        .iter()
        .map(|r| {
            json!({
                "stage": r.stage, "what": r.what,
                "wall_ms_p50": super::bench::percentile(&r.wall_ms, 50.0),
                "wall_ms_max": r.wall_ms.last(),
                "cpu_ms_p50": (!r.cpu_ms.is_empty()).then(|| super::bench::percentile(&r.cpu_ms, 50.0)),
                "cpu_ms_max": r.cpu_ms.last(),
            })
        })
        .collect();
    let per_step: Vec<serde_json::Value> = steps
        .iter()
        .map(|s| json!({ "rig": s.rig, "step": s.step, "wall_ms": s.wall_ms, "cpu_ms": s.cpu_ms }))
        .collect();
    json!({ "steps": steps.len(), "stages": stages, "per_step": per_step })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mark(stage: &str, step: u32, wall_ns: i64, cpu_ns: Option<i64>) -> TraceMark {
        TraceMark {
            stage: stage.into(),
            step,
            wall_ns,
            cpu_ns,
        }
    }

    /// Two steps with every mark 1 ms (step 0) or 2 ms (step 1) apart, and a third step missing
    /// a mark: every stage's interval is 1 and 2 ms, the CPU where given, the third left out.
    #[test]
    fn intervals_between_consecutive_marks_of_complete_steps() {
        let mut marks = Vec::new();
        for (step, gap_ns) in [(0u32, 1_000_000i64), (1, 2_000_000)] {
            for (k, (stage, _)) in STAGES.iter().enumerate() {
                let cpu = (*stage == "identifier.solved").then_some(250_000 * (step as i64 + 1));
                marks.push((
                    0,
                    mark(stage, step, 10_000_000_000 + k as i64 * gap_ns, cpu),
                ));
            }
        }
        for (stage, _) in &STAGES[..5] {
            marks.push((0, mark(stage, 2, 0, None)));
        }
        let steps = per_step(&marks);
        assert_eq!(
            steps.iter().map(|s| (s.rig, s.step)).collect::<Vec<_>>(),
            vec![(0, 0), (0, 1)]
        );
        let rows = breakdown(&steps);
        assert_eq!(rows.len(), STAGES.len() - 1);
        for r in &rows {
            assert_eq!(r.wall_ms, vec![1.0, 2.0], "{}", r.stage);
            if r.stage == "identifier.solved" {
                assert_eq!(r.cpu_ms, vec![0.25, 0.5]);
            } else {
                assert!(r.cpu_ms.is_empty(), "{}", r.stage);
            }
        }
        // The same steps of another rig are other steps.
        let other_rig: Vec<(usize, TraceMark)> =
            marks.iter().map(|(_, m)| (1, m.clone())).collect();
        marks.extend(other_rig);
        assert_eq!(per_step(&marks).len(), 4);
    }
}
