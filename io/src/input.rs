//! Measured data from whichever form the user has: a bag directory, a bare .mcap, a
//! test-bench CSV export, an ASAM MDF4 or an NI TDMS file.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use forcemap_math::record::Record;

use crate::bag::BagReader;
use crate::channel_map::MapFile;
use crate::csv_export::{CsvImport, read_csv, read_csv_reduced};
use crate::foreign_bag::read_foreign_bag;
use crate::rig_bag::{RigBag, RigBagReader, read_rig_bag};
use crate::table_map::RecordMaking;
use forcemap_math::recipe::SetupKind;

/// Records and what came with them.
#[derive(Debug, Clone)]
pub struct Loaded {
    pub records: Vec<Record>,
    pub kind: SetupKind,
    /// Rig constants carried by the data (bags: `/rig/parameters`).
    pub parameters: BTreeMap<String, f64>,
    /// CSV columns that are not part of the contract.
    pub ignored_columns: Vec<String>,
}

/// What measured data are, which decides how they are analysed.
#[derive(Debug, Clone)]
pub enum Measured {
    /// Excitation steps of a setup (a rig or drive-point run): the frequency-domain path.
    Steps(Loaded),
    /// A force-driven axis record (the EMPS benchmark, or a bag of `AxisSample`s): the
    /// time-domain path.
    Axis(forcemap_math::diagnose::time_domain::AxisRecord),
}

/// Reads `path` as whatever it holds: an axis record (a MAT file, or a bag with an axis
/// topic), else the steps of a bag or a CSV export.
pub fn load_measured(path: &Path) -> anyhow::Result<Measured> {
    if crate::axis::is_mat_file(path) {
        return Ok(Measured::Axis(crate::axis::read_axis(path)?));
    }
    if !is_bag(path) {
        return Ok(Measured::Steps(load(path)?));
    }
    // One opening of the bag decides what it holds and reads it.
    let reader = BagReader::open(path)?;
    if crate::axis::axis_topic_of(&reader)?.is_some() {
        Ok(Measured::Axis(crate::axis::read_axis_bag(&reader, path)?))
    } else {
        let bag = RigBagReader::new(reader, path)?.records()?;
        Ok(Measured::Steps(of_bag(path, bag)?))
    }
}

/// True when `path` is a bag (a directory, or a file ending in .mcap).
pub fn is_bag(path: &Path) -> bool {
    path.is_dir() || path.extension().is_some_and(|e| e == "mcap")
}

/// The kind of setup records are, from the channels they hold (the rule of
/// `SetupKind::of_channels`, the same for every source).
pub fn kind_of(records: &[Record], source: &str) -> anyhow::Result<SetupKind> {
    let first = records.first();
    SetupKind::of_channels(|c| first.is_some_and(|r| r.channel(c).is_some()))
        .map_err(|e| anyhow::anyhow!("{source}: {e}"))
}

/// A measurement file's format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FileFormat {
    Mdf,
    Tdms,
    /// A MATLAB level-5 MAT file.
    Mat,
    /// A JSON object of numeric arrays.
    Json,
    /// A CSV export or another text file of columns.
    Csv,
}

impl FileFormat {
    /// The format of the file at `path`: by its first bytes (MDF's `MDF     ` or `UnFinMF `,
    /// TDMS's `TDSm`, a MAT file's `MATLAB 5.0 MAT-file`), else by its extension (`.mf4`,
    /// `.mdf`, `.tdms`, `.mat`, `.json`), else text (a CSV export).
    pub fn of(path: &Path) -> FileFormat {
        let mut head = [0u8; 8];
        let n = std::fs::File::open(path)
            .and_then(|mut f| std::io::Read::read(&mut f, &mut head))
            .unwrap_or(0);
        let head = &head[..n];
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        if crate::mdf::is_mdf(head) {
            FileFormat::Mdf
        } else if crate::tdms::is_tdms(head) {
            FileFormat::Tdms
        } else if crate::axis::is_mat_file(path) {
            FileFormat::Mat
        } else {
            match ext.as_deref() {
                Some("mf4" | "mdf") => FileFormat::Mdf,
                Some("tdms") => FileFormat::Tdms,
                Some("mat") => FileFormat::Mat,
                Some("json") => FileFormat::Json,
                _ => FileFormat::Csv,
            }
        }
    }
}

/// The records of a bag directory, a bare `.mcap`, a test-bench CSV export, an MDF4 or a TDMS
/// file, with the constants and notices that came with them.
pub fn load(path: &Path) -> anyhow::Result<Loaded> {
    if is_bag(path) {
        of_bag(path, read_rig_bag(path)?)
    } else {
        let csv = match FileFormat::of(path) {
            FileFormat::Mdf => crate::mdf::read_mdf(path)?,
            FileFormat::Tdms => crate::tdms::read_tdms(path)?,
            FileFormat::Mat => anyhow::bail!(
                "{}: a MAT file is read as an axis record (the EMPS form), or through a channel \
                 map naming its variables (--channels MAP)",
                path.display()
            ),
            FileFormat::Json => anyhow::bail!(
                "{}: a JSON file is read through a channel map naming its arrays (--channels MAP)",
                path.display()
            ),
            FileFormat::Csv => read_csv(path)?,
        };
        Ok(of_import(path, csv))
    }
}

/// The records of a file read into the CSV contract, its warnings and notices printed.
fn of_import(path: &Path, csv: CsvImport) -> Loaded {
    let (loaded, said) = import_said(path, csv);
    print_said(&said);
    loaded
}

/// What a reading says on stderr, one line each (`warning: ...`, `notice: ...`), for a caller
/// that prints it when its own progress line is gone.
pub type Said = Vec<String>;

/// Prints what a reading says, one line each, on stderr.
pub fn print_said(said: &Said) {
    for line in said {
        eprintln!("{line}");
    }
}

/// The records of a file read into the CSV contract, and its warnings and notices.
fn import_said(path: &Path, csv: CsvImport) -> (Loaded, Said) {
    let mut said: Said = crate::messages::grouped(&csv.warnings)
        .iter()
        .map(|w| format!("warning: {}: {w}", path.display()))
        .collect();
    said.extend(csv.notices.iter().map(|n| format!("notice: {n}")));
    let loaded = Loaded {
        records: csv.records,
        kind: csv.kind,
        parameters: BTreeMap::new(),
        ignored_columns: csv.ignored_columns,
    };
    (loaded, said)
}

/// Whether [`load_reduced`] streams `path` read through the channel map `channels`, if any:
/// without a map a bag, or a file that is a CSV export, an MDF4 or a TDMS file; with one, a
/// file of columns (not a bag, not a selection of the map's records) and a map of its columns.
pub fn streams(path: &Path, channels: Option<&Path>) -> bool {
    match channels {
        None => {
            is_bag(path)
                || (path.is_file()
                    && matches!(
                        FileFormat::of(path),
                        FileFormat::Csv | FileFormat::Mdf | FileFormat::Tdms
                    ))
        }
        Some(map) => {
            path.is_file() && !is_bag(path) && matches!(MapFile::read(map), Ok(MapFile::Columns(_)))
        }
    }
}

/// [`load_mapped`] of a rig bag, a CSV export, an MDF4 or a TDMS file, or a file of columns
/// through a map of its columns (`channels`; [`streams`]), with each record handed to
/// `keep(kind, record)` as soon as it is read ([`RigBagReader::records_reduced`],
/// [`read_csv_reduced`], [`crate::tabular::read_by_contract_names_reduced`],
/// [`crate::tabular::read_mapped_reduced`]): what `keep` returns is kept in the records. The
/// kind is that of the first record. For an analysis that streams a long recording: memory
/// follows what `keep` keeps and what the format holds while it reads (mdf4-rs holds an MDF4
/// file whole), not the records. What [`load_mapped`] prints is returned, for the caller to
/// print.
pub fn load_reduced(
    path: &Path,
    channels: Option<&Path>,
    mut keep: impl FnMut(SetupKind, Record) -> Option<Record>,
) -> anyhow::Result<(Loaded, Said)> {
    let source = path.display().to_string();
    let mut kind: Option<anyhow::Result<SetupKind>> = None;
    let mut keep_of_kind =
        |r: Record| match kind.get_or_insert_with(|| kind_of(std::slice::from_ref(&r), &source)) {
            Ok(k) => keep(*k, r),
            Err(_) => Some(r),
        };
    if let Some(map_path) = channels {
        let MapFile::Columns(map) = MapFile::read(map_path)? else {
            anyhow::bail!(
                "{source}: only a file of columns through a map of its columns is read record by \
                 record"
            );
        };
        let csv = crate::tabular::read_mapped_reduced(path, &map, &mut keep_of_kind)?;
        if let Some(Err(e)) = kind {
            return Err(e);
        }
        return Ok(import_said(path, csv));
    }
    if is_bag(path) {
        let bag = RigBagReader::open(path)?.records_reduced(&mut keep_of_kind)?;
        let kind = kind.unwrap_or_else(|| kind_of(&bag.records, &source))?;
        return Ok(bag_said(path, bag, kind));
    }
    if !streams(path, None) {
        anyhow::bail!(
            "{source}: only a bag, a CSV export, an MDF4 or a TDMS file is read record by record"
        );
    }
    let csv = match FileFormat::of(path) {
        FileFormat::Mdf | FileFormat::Tdms => {
            crate::tabular::read_by_contract_names_reduced(path, &mut keep_of_kind)?
        }
        _ => read_csv_reduced(path, &mut keep_of_kind)?,
    };
    if let Some(Err(e)) = kind {
        return Err(e);
    }
    Ok(import_said(path, csv))
}

fn of_bag(path: &Path, bag: RigBag) -> anyhow::Result<Loaded> {
    let kind = kind_of(&bag.records, &path.display().to_string())?;
    of_bag_of_kind(path, bag, kind)
}

fn of_bag_of_kind(path: &Path, bag: RigBag, kind: SetupKind) -> anyhow::Result<Loaded> {
    let (loaded, said) = bag_said(path, bag, kind);
    print_said(&said);
    Ok(loaded)
}

/// The records of a bag of setup `kind`, and what its reading says.
fn bag_said(path: &Path, bag: RigBag, kind: SetupKind) -> (Loaded, Said) {
    let at = path.display();
    let mut said: Said = bag
        .left_out
        .iter()
        .map(|why| format!("notice: {at}: {why}"))
        .collect();
    said.extend(
        crate::messages::grouped(&bag.warnings)
            .iter()
            .map(|w| format!("warning: {at}: {w}")),
    );
    said.extend(bag.notices.iter().map(|n| format!("notice: {at}: {n}")));
    let loaded = Loaded {
        records: bag.records,
        kind,
        parameters: bag.parameters,
        ignored_columns: vec![],
    };
    (loaded, said)
}

/// As [`load`]; with a channel map (`channels`), `path` is read through it: a bag recorded
/// by a bench's own tools through a topic map ([`crate::foreign_bag`]), a text, MDF4, TDMS
/// or MAT file through a map of its columns ([`crate::tabular`]).
///
/// `FILE#NAME[,NAME...]` (where no file of that whole name exists) reads only the records the
/// map names so (`table: {records: [{name: NAME, rows: [FIRST, LAST]}, ...]}`): a benchmark's
/// estimation and test sections from one file, say.
pub fn load_mapped(path: &Path, channels: Option<&Path>) -> anyhow::Result<Loaded> {
    if let Some((file, names)) = record_selection(path) {
        return load_selected(path, &file, &names, channels);
    }
    let Some(map_path) = channels else {
        return load(path);
    };
    match MapFile::read(map_path)? {
        MapFile::Topics(map) => {
            if !is_bag(path) {
                anyhow::bail!(
                    "{}: {} maps a bag's topics (topic:, field:); a file of columns needs a \
                     map of its columns (channel:, docs/data.md)",
                    path.display(),
                    map_path.display()
                );
            }
            of_bag(path, read_foreign_bag(path, &map)?)
        }
        MapFile::Columns(map) => {
            if is_bag(path) {
                anyhow::bail!(
                    "{}: {} maps file columns (channel:); a bag needs a map of its topics \
                     (topic:, field:, docs/data.md)",
                    path.display(),
                    map_path.display()
                );
            }
            Ok(of_import(path, crate::tabular::read_mapped(path, &map)?))
        }
    }
}

/// `FILE#NAME,...` split into the file and the record names, when `path` names no file itself
/// and `FILE` does.
pub fn record_selection(path: &Path) -> Option<(PathBuf, Vec<String>)> {
    if path.exists() {
        return None;
    }
    let text = path.to_str()?;
    let (file, names) = text.rsplit_once('#')?;
    let file = PathBuf::from(file);
    file.exists().then(|| {
        (
            file,
            names.split(',').map(|n| n.trim().to_string()).collect(),
        )
    })
}

/// The records `names` of `file`, read through the map that names them, numbered from 0 in the
/// map's order.
fn load_selected(
    path: &Path,
    file: &Path,
    names: &[String],
    channels: Option<&Path>,
) -> anyhow::Result<Loaded> {
    let named = match channels.map(MapFile::read).transpose()? {
        Some(MapFile::Columns(map)) => match &map.records {
            RecordMaking::Rows(rows) => rows.clone(),
            _ => Vec::new(),
        },
        _ => Vec::new(),
    };
    if named.is_empty() {
        anyhow::bail!(
            "{}: no file of this name, and {} names no records to pick after '#' (a map of \
             columns with table: {{records: [{{name: NAME, rows: [FIRST, LAST]}}, ...]}})",
            path.display(),
            channels.map_or("no channel map".to_string(), |m| format!(
                "the map {}",
                m.display()
            ))
        );
    }
    let mut wanted = Vec::new();
    for n in names {
        match named.iter().position(|r| &r.name == n) {
            Some(i) => wanted.push(i),
            None => anyhow::bail!(
                "{}: the map names no record '{n}' (it names {})",
                path.display(),
                named
                    .iter()
                    .map(|r| r.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        }
    }
    let mut loaded = load_mapped(file, channels)?;
    loaded.records.retain(|r| wanted.contains(&r.step));
    for (k, r) in loaded.records.iter_mut().enumerate() {
        r.step = k;
    }
    Ok(loaded)
}

/// As [`load_measured`]; with a channel map, the steps of a bench's own bag.
pub fn load_measured_mapped(path: &Path, channels: Option<&Path>) -> anyhow::Result<Measured> {
    match channels {
        None => load_measured(path),
        Some(_) => Ok(Measured::Steps(load_mapped(path, channels)?)),
    }
}

/// What several files give together: each file's records in the order of the files, their
/// steps numbered on after the previous file's last, each keeping its own sample rate; one setup
/// for all, and the constants the files carry (a constant two files give differently is an
/// error naming both).
pub fn load_files(paths: &[PathBuf], channels: Option<&Path>) -> anyhow::Result<Loaded> {
    let Some((first_path, rest)) = paths.split_first() else {
        anyhow::bail!("no data file given");
    };
    let mut all = load_mapped(first_path, channels)?;
    if rest.is_empty() {
        return Ok(all);
    }
    let next_step = |records: &[Record]| records.iter().map(|r| r.step + 1).max().unwrap_or(0);
    let mut spans = vec![(first_path, 0..next_step(&all.records))];
    for path in rest {
        let next = load_mapped(path, channels)?;
        if next.kind != all.kind {
            anyhow::bail!(
                "{}: its channels are a {} setup's, but {} holds a {} setup's; files \
                 identified together must hold one setup",
                path.display(),
                next.kind,
                first_path.display(),
                all.kind
            );
        }
        for (name, value) in next.parameters {
            match all.parameters.get(&name) {
                Some(v) if *v != value => anyhow::bail!(
                    "{}: carries {name} = {value}, but an earlier file carries {name} = {v}",
                    path.display()
                ),
                _ => {
                    all.parameters.insert(name, value);
                }
            }
        }
        let offset = next_step(&all.records);
        spans.push((path, offset..offset + next_step(&next.records)));
        all.records.extend(next.records.into_iter().map(|mut r| {
            r.step += offset;
            r
        }));
        for c in next.ignored_columns {
            if !all.ignored_columns.contains(&c) {
                all.ignored_columns.push(c);
            }
        }
    }
    let listed: Vec<String> = spans
        .iter()
        .map(|(p, s)| match s.len() {
            0 => format!("{}: no record", p.display()),
            1 => format!("{}: step {}", p.display(), s.start),
            _ => format!("{}: steps {}-{}", p.display(), s.start, s.end - 1),
        })
        .collect();
    eprintln!(
        "notice: {} files read together: {}",
        paths.len(),
        listed.join("; ")
    );
    Ok(all)
}

/// The files `args` name: each argument as it is where such a path exists, else as a glob
/// pattern (`runs/*.txt`, for shells that do not expand it) matching at least one file, in
/// sorted order.
pub fn expand_paths(args: &[PathBuf]) -> anyhow::Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for a in args {
        let text = a.to_string_lossy();
        if a.exists() || !text.contains(['*', '?', '[']) {
            out.push(a.clone());
            continue;
        }
        let mut matched: Vec<PathBuf> = glob::glob(&text)
            .map_err(|e| anyhow::anyhow!("{text}: not a valid file pattern: {e}"))?
            .filter_map(Result::ok)
            .collect();
        if matched.is_empty() {
            anyhow::bail!("{text}: no file matches this pattern");
        }
        matched.sort();
        out.append(&mut matched);
    }
    Ok(out)
}
