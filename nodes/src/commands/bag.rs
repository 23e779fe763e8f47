//! `forcemap bag info|recover`: summarise a bag; rebuild one whose recorder died.

use crate::bag::{BagReader, recover};
use crate::cli::{BagArgs, BagCommand};

pub fn run(args: &BagArgs) -> anyhow::Result<()> {
    match &args.command {
        BagCommand::Info { bag, json } => {
            let reader = BagReader::open(bag)?;
            let s = reader.summary();
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
