//! The check of an export's labels against its drive ([`check_labels`]) over records as the
//! timing rule gives them: the segmenter takes labelled steps one after the other at one rate,
//! so a step its timing split is joined again (named by its label), and each run of steps at
//! one rate is checked apart.

use forcemap_math::record::{Channel, Record};
use forcemap_math::segment::SegmentOptions;

use crate::steps::unlabelled::{StepWithFrequency, check_labels};

/// The warnings of the label check of `found` (record `k` of step `labels[k]`), the records
/// `checked(k)` says only.
pub(super) fn label_warnings(
    found: &[StepWithFrequency],
    labels: &[usize],
    checked: impl Fn(usize) -> bool,
    driven: Channel,
    options: &SegmentOptions,
) -> Vec<String> {
    // The check reads the driven channel only: the steps are copied with that channel alone.
    let mut steps: Vec<StepWithFrequency> = Vec::new();
    for (k, (record, frequency)) in found.iter().enumerate() {
        if !checked(k) {
            continue;
        }
        let drive = record.channel(driven).unwrap_or_default();
        match steps.last_mut() {
            Some((last, _)) if k > 0 && labels[k - 1] == labels[k] && last.step == labels[k] => {
                for (_, x) in &mut last.channels {
                    x.extend_from_slice(drive);
                }
            }
            _ => steps.push((
                Record {
                    step: labels[k],
                    excitation: record.excitation.clone(),
                    sample_rate_hz: record.sample_rate_hz,
                    start_time_s: record.start_time_s,
                    channels: record
                        .channel(driven)
                        .map(|x| vec![(driven, x.to_vec())])
                        .unwrap_or_default(),
                },
                *frequency,
            )),
        }
    }
    let mut warnings = Vec::new();
    let mut start = 0;
    for k in 1..=steps.len() {
        if k == steps.len() || steps[k - 1].0.sample_rate_hz != steps[k].0.sample_rate_hz {
            warnings.extend(check_labels(&steps[start..k], driven, options));
            start = k;
        }
    }
    warnings
}
