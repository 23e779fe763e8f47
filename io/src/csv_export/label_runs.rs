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
    let mut steps: Vec<StepWithFrequency> = Vec::new();
    for (k, (record, frequency)) in found.iter().enumerate() {
        if !checked(k) {
            continue;
        }
        match steps.last_mut() {
            Some((last, _)) if k > 0 && labels[k - 1] == labels[k] && last.step == labels[k] => {
                for ((_, x), (_, y)) in last.channels.iter_mut().zip(&record.channels) {
                    x.extend_from_slice(y);
                }
            }
            _ => steps.push((
                Record {
                    step: labels[k],
                    ..record.clone()
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
