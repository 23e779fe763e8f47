//! `forcemap info FILE...`: what measured files hold and how forcemap reads and cuts them.

use std::path::Path;

use anyhow::Context as _;
use forcemap_io::channel_map::MapFile;
use forcemap_io::input::{FileFormat, expand_paths, is_bag, load_mapped, record_selection};
use forcemap_io::table_map::RecordMaking;
use forcemap_io::tabular::ColumnInfo;
use forcemap_math::record::{Excitation, Record};
use serde_json::{Value, json};

use crate::cli::InfoArgs;

/// A file of columns as its format lists them, with what the map (or, for MDF4 and TDMS,
/// forcemap's names) picks from each: (format, columns, picks per column).
type Listed = (String, Vec<ColumnInfo>, Vec<Vec<String>>);

/// The columns of a file of columns (`None` for a bag).
fn columns(path: &Path, map: Option<&MapFile>) -> anyhow::Result<Option<Listed>> {
    if is_bag(path) {
        return Ok(None);
    }
    let table_map = match map {
        Some(MapFile::Columns(m)) => Some(m.clone()),
        _ => None,
    };
    let format = FileFormat::of(path);
    let file = forcemap_io::tabular::open(path, table_map.as_ref())?;
    let used = match (table_map, format) {
        (Some(m), _) => Some(m),
        (None, FileFormat::Mdf | FileFormat::Tdms) => {
            Some(forcemap_io::tabular::default_map(file.as_ref(), path)?)
        }
        _ => None,
    };
    let mut picks = vec![Vec::new(); file.columns().len()];
    if let Some(m) = used {
        for (name, column, how) in forcemap_io::tabular::pick(file.as_ref(), path, &m)?.described()
        {
            picks[column].push(if how.is_empty() {
                name.to_string()
            } else {
                format!("{name} ({how})")
            });
        }
    }
    Ok(Some((
        file.format().to_string(),
        file.columns().to_vec(),
        picks,
    )))
}

/// What drove a record, for the table: kind, frequency [Hz], level (amplitude or RMS).
fn describe(e: &Excitation) -> (&'static str, Option<f64>, f64) {
    match e {
        Excitation::Sine {
            frequency_hz,
            amplitude,
        } => ("sine", Some(*frequency_hz), *amplitude),
        Excitation::Random { rms, .. } => ("random", None, *rms),
        Excitation::Multisine {
            base_frequency_hz,
            rms,
            ..
        } => ("multisine", Some(*base_frequency_hz), *rms),
        Excitation::Sweep { law } => ("sweep", None, law.amplitude),
    }
}

/// The names of the records `path` gives, in their order, when the map cuts its file into named
/// records by rows (`FILE#NAME,...`: the names picked, in the map's order); empty otherwise.
fn record_names(path: &Path, map: Option<&MapFile>) -> Vec<String> {
    let Some(MapFile::Columns(map)) = map else {
        return Vec::new();
    };
    let RecordMaking::Rows(rows) = &map.records else {
        return Vec::new();
    };
    let picked = record_selection(path).map(|(_, names)| names);
    rows.iter()
        .map(|r| r.name.clone())
        .filter(|n| picked.as_ref().is_none_or(|p| p.contains(n)))
        .collect()
}

fn record_json(r: &Record, name: Option<&String>) -> Value {
    let (kind, frequency_hz, level) = describe(&r.excitation);
    json!({
        "name": name,
        "step": r.step,
        "kind": kind,
        "frequency_hz": frequency_hz,
        "level": level,
        "sample_rate_hz": r.sample_rate_hz,
        "start_s": r.start_time_s,
        "duration_s": r.len() as f64 / r.sample_rate_hz,
        "samples": r.len(),
    })
}

pub fn run(args: &InfoArgs) -> anyhow::Result<()> {
    let files = expand_paths(&args.files)?;
    let map = args.channels.as_deref().map(MapFile::read).transpose()?;
    if let Some(dir) = &args.plot {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("creating the plot directory {}", dir.display()))?;
    }
    let mut out = Vec::new();
    for (i, path) in files.iter().enumerate() {
        let file = record_selection(path).map_or_else(|| path.clone(), |(file, _)| file);
        let listed = columns(&file, map.as_ref())?;
        let names = record_names(path, map.as_ref());
        let loaded = load_mapped(path, args.channels.as_deref())?;
        let driven = loaded.kind.driven_channel();
        if let Some(dir) = &args.plot {
            let svg = crate::plot::records_svg(
                &format!(
                    "{}: {} and the records found",
                    path.display(),
                    driven.name()
                ),
                &loaded.records,
                driven,
            )?;
            forcemap_io::atomic::write_atomically(&dir.join(format!("drive_{i}.svg")), &svg)?;
        }
        if args.json {
            out.push(json!({
                "path": path.display().to_string(),
                "format": listed.as_ref().map_or("bag", |(f, _, _)| f.as_str()),
                "columns": listed.as_ref().map(|(_, c, picks)| c.iter().zip(picks).map(|(c, p)| json!({
                    "position": c.position,
                    "name": c.name,
                    "group": c.group,
                    "matrix_column": c.matrix_column,
                    "unit": c.unit,
                    "supplies": p,
                })).collect::<Vec<_>>()),
                "setup": loaded.kind.to_string(),
                "driven_channel": driven.name(),
                "records": loaded
                    .records
                    .iter()
                    .enumerate()
                    .map(|(k, r)| record_json(r, names.get(k)))
                    .collect::<Vec<_>>(),
            }));
            continue;
        }
        println!("{}", path.display());
        if let Some((format, cols, picks)) = &listed {
            println!("  format:  {format}, {} columns", cols.len());
            for (c, p) in cols.iter().zip(picks) {
                let unit = c
                    .unit
                    .as_deref()
                    .map(|u| format!(" [{u}]"))
                    .unwrap_or_default();
                let supplies = if p.is_empty() {
                    String::new()
                } else {
                    format!("  -> {}", p.join(", "))
                };
                println!("    {:>3}  {}{unit}{supplies}", c.position, c.label());
            }
        }
        println!(
            "  setup:   {} (driven channel {})",
            loaded.kind,
            driven.name()
        );
        println!("  records: {}", loaded.records.len());
        let header = format!(
            "    {:>4}  {:<9} {:>13} {:>12} {:>10} {:>10} {:>10} {:>8}  {}",
            "step",
            "kind",
            "frequency[Hz]",
            "level",
            "rate[Hz]",
            "start[s]",
            "length[s]",
            "samples",
            if names.is_empty() { "" } else { "name" }
        );
        println!("{}", header.trim_end());
        for (k, r) in loaded.records.iter().enumerate() {
            let (kind, f, level) = describe(&r.excitation);
            let line = format!(
                "    {:>4}  {kind:<9} {:>13} {level:>12.4e} {:>10.3} {:>10.3} {:>10.3} {:>8}  {}",
                r.step,
                f.map_or("-".to_string(), |f| format!("{f:.6}")),
                r.sample_rate_hz,
                r.start_time_s,
                r.len() as f64 / r.sample_rate_hz,
                r.len(),
                names.get(k).map_or("", String::as_str)
            );
            println!("{}", line.trim_end());
        }
    }
    if args.json {
        println!("{}", json!({ "files": out }));
    }
    if let Some(dir) = &args.plot {
        eprintln!("wrote {} drive plot(s) to {}", files.len(), dir.display());
    }
    Ok(())
}
