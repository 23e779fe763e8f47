//! `forcemap bag info|recover`: summarise a bag; rebuild one whose recorder died.

use forcemap_io::bag::{BagReader, recover};
use forcemap_io::topics::RIG_EXCITATION as EXCITATION_TOPIC;
use forcemap_msgs::RosMessage;
use forcemap_msgs::msg::ExcitationState;

/// The excitation steps of a rig bag, from `/rig/excitation` (empty when the bag has none).
fn steps(reader: &BagReader) -> anyhow::Result<Vec<ExcitationState>> {
    if reader.topic(EXCITATION_TOPIC).is_err() {
        return Ok(Vec::new());
    }
    let mut out = Vec::new();
    for (i, m) in reader.messages_on(&[EXCITATION_TOPIC])?.enumerate() {
        let m = m?;
        let s = ExcitationState::from_cdr(&m.data)
            .map_err(|e| anyhow::anyhow!("{EXCITATION_TOPIC}, message {i}: {e}"))?;
        out.push(s);
    }
    Ok(out)
}

/// The name of an excitation kind in `bag info`.
fn kind_name(kind: u8) -> &'static str {
    match kind {
        ExcitationState::SINE => "sine",
        ExcitationState::SWEEP_LINEAR => "sweep_linear",
        ExcitationState::SWEEP_LOG => "sweep_log",
        ExcitationState::MULTISINE => "multisine",
        _ => "random",
    }
}

fn describe_step(s: &ExcitationState) -> String {
    match s.kind {
        ExcitationState::SINE => format!(
            "sine {:.3} Hz, amplitude {:.4e} ({})",
            s.frequency_hz, s.amplitude, s.driven_channel
        ),
        ExcitationState::SWEEP_LINEAR | ExcitationState::SWEEP_LOG => format!(
            "{} {:.3} -> {:.3} Hz, amplitude {:.4e} ({})",
            kind_name(s.kind),
            s.band_low_hz,
            s.band_high_hz,
            s.amplitude,
            s.driven_channel
        ),
        ExcitationState::MULTISINE => format!(
            "multisine, lines of {:.4} Hz over {:.3}-{:.3} Hz, RMS {:.4e} ({})",
            s.frequency_hz, s.band_low_hz, s.band_high_hz, s.amplitude, s.driven_channel
        ),
        _ if s.band_low_hz.is_nan() => {
            format!("random, RMS {:.4e} ({})", s.amplitude, s.driven_channel)
        }
        _ => format!(
            "random {:.2}-{:.2} Hz, RMS {:.4e} ({})",
            s.band_low_hz, s.band_high_hz, s.amplitude, s.driven_channel
        ),
    }
}
use crate::cli::{BagArgs, BagCommand};

pub fn run(args: &BagArgs) -> anyhow::Result<()> {
    match &args.command {
        BagCommand::Info { bag, json } => {
            let reader = BagReader::open(bag)?;
            let s = reader.summary();
            let steps = steps(&reader)?;
            if *json {
                let topics: Vec<_> = s
                    .topics
                    .iter()
                    .map(|t| serde_json::json!({"name": t.name, "type": t.type_name, "count": t.message_count}))
                    .collect();
                println!(
                    "{}",
                    serde_json::json!({
                        "path": bag.display().to_string(),
                        "messages": s.message_count,
                        "start_ns": s.start_ns,
                        "end_ns": s.end_ns,
                        "duration_s": s.duration_ns as f64 * 1e-9,
                        "ros_distro": s.ros_distro,
                        "topics": topics,
                        "steps": steps.iter().map(|st| serde_json::json!({
                            "step": st.step,
                            "kind": kind_name(st.kind),
                            "frequency_hz": st.frequency_hz,
                            "amplitude": st.amplitude,
                            "driven_channel": st.driven_channel,
                            "start_time_s": st.start_time.as_secs_f64(),
                        })).collect::<Vec<_>>(),
                    })
                );
            } else {
                println!("bag:       {}", bag.display());
                println!("storage:   mcap ({})", reader.mcap_path().display());
                println!("duration:  {:.3} s", s.duration_ns as f64 * 1e-9);
                println!(
                    "start:     {:.9} s since the epoch",
                    s.start_ns as f64 * 1e-9
                );
                println!("messages:  {}", s.message_count);
                if let Some(d) = s.ros_distro.as_deref().filter(|d| !d.is_empty()) {
                    println!("ros_distro: {d}");
                }
                println!("topics:");
                for t in &s.topics {
                    println!(
                        "  {:<32} {:<40} {:>8} msgs",
                        t.name, t.type_name, t.message_count
                    );
                }
                if let Some(first) = steps.first() {
                    println!("steps:");
                    for st in &steps {
                        let at = st.start_time.secs_since(first.start_time);
                        println!("  {:>4}  at {at:>9.3} s  {}", st.step, describe_step(st));
                    }
                }
            }
            Ok(())
        }
        BagCommand::Recover { input, output } => {
            let r = recover(input, output)?;
            println!(
                "recovered {} messages into {} ({} whole chunks{}{})",
                r.messages,
                r.output.display(),
                r.complete_chunks,
                if r.partial_chunk_messages > 0 {
                    format!(
                        ", {} messages from the cut-off chunk",
                        r.partial_chunk_messages
                    )
                } else {
                    String::new()
                },
                if r.skipped_messages > 0 {
                    format!(
                        ", {} skipped: their channel or schema was lost",
                        r.skipped_messages
                    )
                } else {
                    String::new()
                }
            );
            if let (Some(off), Some(why)) = (r.cut_offset, r.cut_reason.as_deref()) {
                println!(
                    "the input was cut at byte {off} of {}: {why}",
                    r.input_bytes
                );
            }
            Ok(())
        }
    }
}
