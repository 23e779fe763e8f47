//! The indexed reader trusts nothing in the summary section that the file does not back up:
//! crafted summaries (a huge string length in a summary record, a chunk index declaring a huge
//! uncompressed size or pointing outside the data section, a footer pointing past the file) give
//! an error or a scan of the file, never a large allocation. The memory cases run in a child
//! process under an address-space limit (`ulimit -v`), where an allocation of the declared size
//! aborts the child.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::path::{Path, PathBuf};
use std::process::Command;

use forcemap_io::bag::{BagReader, BagWriter, BagWriterOptions, TopicSpec};

const OP_CHANNEL: u8 = 0x04;
const OP_CHUNK_INDEX: u8 = 0x08;
const FOOTER_AND_MAGIC: usize = 37;

fn value(i: u64) -> Vec<u8> {
    let mut d = vec![0, 1, 0, 0];
    d.extend_from_slice(&(i as f64).to_le_bytes());
    d
}

/// A bag of 300 messages on two topics in three zstd chunks; returns its .mcap file.
fn bag(dir: &Path) -> PathBuf {
    let mut w = BagWriter::create(dir.join("bag")).unwrap();
    let spec = |t| TopicSpec::new(t, "forcemap_test/msg/Value", "float64 data\n");
    let a = w.add_topic(&spec("/a")).unwrap();
    let b = w.add_topic(&spec("/b")).unwrap();
    for i in 0..300u64 {
        w.write(if i % 3 == 0 { a } else { b }, i, i, &value(i))
            .unwrap();
        if i % 100 == 99 {
            w.flush_chunk().unwrap();
        }
    }
    w.finish().unwrap().join("bag_0.mcap")
}

/// (log time, topic, data) of every message.
fn read_all(path: &Path) -> Result<Vec<(u64, String, Vec<u8>)>, String> {
    let bag = BagReader::open(path).map_err(|e| e.to_string())?;
    let messages = bag.messages().map_err(|e| e.to_string())?;
    messages
        .map(|m| {
            m.map(|m| (m.log_time, m.topic.name.clone(), m.data))
                .map_err(|e| e.to_string())
        })
        .collect()
}

/// Offsets (record start, opcode, body start, body length) of the summary records.
fn summary_records(bytes: &[u8]) -> Vec<(usize, u8, usize, usize)> {
    let footer = bytes.len() - FOOTER_AND_MAGIC;
    assert_eq!(bytes[footer], 0x02, "footer opcode");
    let mut pos = u64::from_le_bytes(bytes[footer + 9..footer + 17].try_into().unwrap()) as usize;
    assert!(pos > 8, "the bag has a summary");
    let mut out = vec![];
    while pos < footer {
        let len = u64::from_le_bytes(bytes[pos + 1..pos + 9].try_into().unwrap()) as usize;
        out.push((pos, bytes[pos], pos + 9, len));
        pos += 9 + len;
    }
    out
}

fn patch_u32(bytes: &mut [u8], at: usize, v: u32) {
    bytes[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

fn patch_u64(bytes: &mut [u8], at: usize, v: u64) {
    bytes[at..at + 8].copy_from_slice(&v.to_le_bytes());
}

/// Patches every chunk index's field `field_from_end` bytes before its end (8: uncompressed
/// size, 16: compressed size) or at `field_from_start` (16: chunk start offset).
fn patch_chunk_indexes(bytes: &mut [u8], at: impl Fn(usize, usize) -> usize, v: u64) -> usize {
    let mut n = 0;
    for (_, op, body, len) in summary_records(bytes) {
        if op == OP_CHUNK_INDEX {
            patch_u64(bytes, at(body, len), v);
            n += 1;
        }
    }
    n
}

/// Runs the ignored test `child_reads_the_bag` on `file` in a child process limited to `kib`
/// KiB of address space; returns (exit code, stdout, stderr).
fn read_in_child(file: &Path, kib: u64) -> (Option<i32>, String, String) {
    let exe = std::env::current_exe().unwrap();
    let o = Command::new("bash")
        .arg("-c")
        .arg(format!(
            "ulimit -v {kib}; exec '{}' --exact child_reads_the_bag --ignored --nocapture \
             --test-threads 1",
            exe.display()
        ))
        .env("FORCEMAP_GUARD_FILE", file)
        .output()
        .unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// The child: opens FORCEMAP_GUARD_FILE and reads every message; prints `read N` or
/// `error: ...` (both exit 0; an abort on an allocation does not).
#[test]
#[ignore = "run by read_in_child"]
fn child_reads_the_bag() {
    let file = std::env::var_os("FORCEMAP_GUARD_FILE").expect("FORCEMAP_GUARD_FILE");
    match read_all(Path::new(&file)) {
        Ok(m) => println!("read {}", m.len()),
        Err(e) => println!("error: {e}"),
    }
}

/// 600 MB of address space: plenty for these bags, too little for a declared 900 MiB chunk or
/// a 4 GiB string.
const LIMIT_KIB: u64 = 600_000;

#[test]
fn the_child_reads_a_good_bag_under_the_limit() {
    let tmp = tempfile::tempdir().unwrap();
    let (code, out, err) = read_in_child(&bag(tmp.path()), LIMIT_KIB);
    assert_eq!(code, Some(0), "{out}\n{err}");
    assert!(out.contains("read 300"), "{out}\n{err}");
}

#[test]
fn a_chunk_index_declaring_900_mib_uncompressed_is_not_taken_on_trust() {
    // Before the guard the mcap crate's indexed reader zero-filled 900 MiB for each of these
    // 3 kB chunks. Now the summary is ignored and the file scanned: every message, as written.
    let tmp = tempfile::tempdir().unwrap();
    let file = bag(tmp.path());
    let good = read_all(&file).unwrap();
    let mut bytes = std::fs::read(&file).unwrap();
    let n = patch_chunk_indexes(&mut bytes, |body, len| body + len - 8, 900 << 20);
    assert_eq!(n, 3);
    let bad = tmp.path().join("huge_uncompressed.mcap");
    std::fs::write(&bad, &bytes).unwrap();
    let (code, out, err) = read_in_child(&bad, LIMIT_KIB);
    assert_eq!(code, Some(0), "the child died:\n{out}\n{err}");
    assert!(out.contains("read 300"), "{out}\n{err}");
    assert_eq!(read_all(&bad).unwrap(), good);
}

#[test]
fn a_4_gib_string_length_in_a_summary_channel_is_an_error_not_an_allocation() {
    let tmp = tempfile::tempdir().unwrap();
    let file = bag(tmp.path());
    let mut bytes = std::fs::read(&file).unwrap();
    let (pos, _, body, _) = summary_records(&bytes)
        .into_iter()
        .find(|r| r.1 == OP_CHANNEL)
        .expect("a channel in the summary");
    patch_u32(&mut bytes, body + 4, 0xFFFF_FFF0); // topic length
    let bad = tmp.path().join("huge_topic_length.mcap");
    std::fs::write(&bad, &bytes).unwrap();
    let (code, out, err) = read_in_child(&bad, LIMIT_KIB);
    assert_eq!(code, Some(0), "the child died:\n{out}\n{err}");
    // The scan stops at the damaged record and names it.
    let expected = format!("at byte {pos}");
    assert!(
        out.contains("error:") && out.contains(&expected) && out.contains("runs past"),
        "{out}\n{err}"
    );
}

#[test]
fn chunk_indexes_and_a_footer_pointing_outside_the_file_fall_back_to_the_scan() {
    let tmp = tempfile::tempdir().unwrap();
    let file = bag(tmp.path());
    let good = read_all(&file).unwrap();
    let size = std::fs::metadata(&file).unwrap().len();

    // chunk start offsets past the end of the file (before: "the chunk index points past the
    // end of the file")
    let mut bytes = std::fs::read(&file).unwrap();
    patch_chunk_indexes(&mut bytes, |body, _| body + 16, size + 1000);
    let f = tmp.path().join("chunks_outside.mcap");
    std::fs::write(&f, &bytes).unwrap();
    assert_eq!(read_all(&f).unwrap(), good);

    // compressed size larger than the chunk
    let mut bytes = std::fs::read(&file).unwrap();
    patch_chunk_indexes(&mut bytes, |body, len| body + len - 16, u64::MAX / 2);
    let f = tmp.path().join("compressed_size.mcap");
    std::fs::write(&f, &bytes).unwrap();
    assert_eq!(read_all(&f).unwrap(), good);

    // the footer's summary start past the file (before: an error)
    let mut bytes = std::fs::read(&file).unwrap();
    let footer = bytes.len() - FOOTER_AND_MAGIC;
    patch_u64(&mut bytes, footer + 9, size * 2);
    let f = tmp.path().join("summary_past_the_end.mcap");
    std::fs::write(&f, &bytes).unwrap();
    assert_eq!(read_all(&f).unwrap(), good);

    // a summary record longer than the summary
    let mut bytes = std::fs::read(&file).unwrap();
    let (pos, ..) = summary_records(&bytes)[0];
    patch_u64(&mut bytes, pos + 1, 1 << 40);
    let f = tmp.path().join("summary_record_too_long.mcap");
    std::fs::write(&f, &bytes).unwrap();
    let e = read_all(&f).unwrap_err();
    assert!(e.contains(&format!("{pos}")), "{e}");
}

#[test]
fn a_highly_compressible_chunk_is_read_whole_by_the_scan() {
    // 2000 messages of 1 kB zeros in one chunk: zstd makes 2 MB of it a few hundred bytes, more
    // than the index is trusted with (64 x compressed + 1 MiB); the scan reads it all.
    let tmp = tempfile::tempdir().unwrap();
    let opts = BagWriterOptions {
        chunk_size: 64 << 20,
        max_chunk_age: None,
        ..BagWriterOptions::default()
    };
    let mut w = BagWriter::create_with(tmp.path().join("zeros"), opts).unwrap();
    let id = w
        .add_topic(&TopicSpec::new(
            "/z",
            "forcemap_test/msg/Blob",
            "uint8[] data\n",
        ))
        .unwrap();
    let mut blob = vec![0, 1, 0, 0];
    blob.extend_from_slice(&1000u32.to_le_bytes());
    blob.resize(4 + 4 + 1000, 0);
    for i in 0..2000u64 {
        w.write(id, i, i, &blob).unwrap();
    }
    let file = w.finish().unwrap().join("zeros_0.mcap");
    let bytes = std::fs::read(&file).unwrap();
    let ci = summary_records(&bytes)
        .into_iter()
        .find(|r| r.1 == OP_CHUNK_INDEX)
        .unwrap();
    let (body, len) = (ci.2, ci.3);
    let compressed = u64::from_le_bytes(bytes[body + len - 16..body + len - 8].try_into().unwrap());
    let uncompressed = u64::from_le_bytes(bytes[body + len - 8..body + len].try_into().unwrap());
    assert!(
        uncompressed > 64 * compressed + (1 << 20),
        "{uncompressed} from {compressed}: not beyond the trusted ratio"
    );
    let m = read_all(&file).unwrap();
    assert_eq!(m.len(), 2000);
    assert!(m.iter().all(|(_, t, d)| t == "/z" && *d == blob));
}
