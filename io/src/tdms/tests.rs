//! The TDMS reader on hand-made segments: chunks, carried-over objects, interleaving, byte
//! order, lengths past the data.
use super::segments::*;
use super::*;

#[test]
fn object_paths_name_channels() {
    assert_eq!(channel_name("/'run'/'force_n'").as_deref(), Some("force_n"));
    assert_eq!(channel_name("/'a''b'/'it''s'").as_deref(), Some("it's"));
    assert_eq!(channel_name("/'run'"), None);
    assert_eq!(channel_name("/"), None);
}

/// A segment: `objects` as (path, data type and values per chunk), then `raw`.
fn segment(toc: u32, objects: &[(&str, Option<(u32, u64)>)], raw: &[u8]) -> Vec<u8> {
    let big = toc & TOC_BIG_ENDIAN != 0;
    let u32b = |v: u32| {
        if big {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        }
    };
    let u64b = |v: u64| {
        if big {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        }
    };
    let mut meta = Vec::new();
    if toc & TOC_META_DATA != 0 {
        meta.extend(u32b(objects.len() as u32));
        for (path, index) in objects {
            meta.extend(u32b(path.len() as u32));
            meta.extend(path.as_bytes());
            match index {
                None => meta.extend(u32b(NO_RAW_DATA)),
                Some((code, n)) => {
                    meta.extend(u32b(20));
                    meta.extend(u32b(*code));
                    meta.extend(u32b(1));
                    meta.extend(u64b(*n));
                }
            }
            meta.extend(u32b(0));
        }
    }
    let mut out = b"TDSm".to_vec();
    out.extend(toc.to_le_bytes());
    out.extend(u32b(4713));
    out.extend(u64b((meta.len() + raw.len()) as u64));
    out.extend(u64b(meta.len() as u64));
    out.extend(meta);
    out.extend(raw);
    out
}

fn parsed(bytes: &[u8]) -> Result<TdmsFile, String> {
    parse(&mut Bytes::Memory(bytes.into())).map_err(|f| match f {
        Fault::Format(m) => m,
        Fault::Io(e) => e.to_string(),
    })
}

/// An object's values, read block by block as the reader does, with the count its metadata
/// gave.
fn data(bytes: &[u8], file: &TdmsFile, path: &str) -> Vec<f64> {
    let mut reader = TdmsBlocks::new(
        Bytes::Memory(bytes.into()),
        file.segments.clone().into(),
        vec![path.to_string()],
    );
    let mut values = Vec::new();
    while let Some(mut block) = reader.next_block().unwrap() {
        values.append(&mut block[0]);
    }
    assert_eq!(values.len() as u64, file.objects[path].values, "{path}");
    values
}

#[test]
fn chunks_segments_interleaving_and_byte_order() {
    const A: &str = "/'g'/'a'";
    const B: &str = "/'g'/'b'";
    let le = TOC_META_DATA | TOC_NEW_OBJ_LIST | TOC_RAW_DATA;
    // Two chunks of (a: 2 f64, b: 2 i16) in one segment.
    let mut raw = Vec::new();
    for chunk in 0..2 {
        for k in 0..2 {
            raw.extend((f64::from(chunk * 2 + k) + 0.5).to_le_bytes());
        }
        for k in 0..2 {
            raw.extend((-(chunk * 2 + k) as i16).to_le_bytes());
        }
    }
    let mut bytes = segment(
        le,
        &[("/", None), (A, Some((10, 2))), (B, Some((2, 2)))],
        &raw,
    );
    // A segment of raw data only: the previous objects and indices.
    let mut raw2 = 9.5f64.to_le_bytes().to_vec();
    raw2.extend(8.5f64.to_le_bytes());
    raw2.extend(7i16.to_le_bytes());
    raw2.extend(6i16.to_le_bytes());
    bytes.extend(segment(TOC_RAW_DATA, &[], &raw2));
    // Big-endian, interleaved (a f64, b u8 per row), cut in the middle of the third row.
    let mut raw3 = Vec::new();
    for k in 0..3u8 {
        raw3.extend((100.0 + f64::from(k)).to_be_bytes());
        raw3.push(k);
    }
    raw3.truncate(raw3.len() - 4);
    let be = le | TOC_INTERLEAVED | TOC_BIG_ENDIAN;
    bytes.extend(segment(be, &[(A, Some((10, 3))), (B, Some((5, 3)))], &raw3));
    let file = parsed(&bytes).unwrap();
    assert_eq!(
        data(&bytes, &file, A),
        [0.5, 1.5, 2.5, 3.5, 9.5, 8.5, 100.0, 101.0]
    );
    assert_eq!(
        data(&bytes, &file, B),
        [0.0, -1.0, -2.0, -3.0, 7.0, 6.0, 0.0, 1.0]
    );
}

#[test]
fn lengths_past_the_data_are_errors_not_allocations() {
    let le = TOC_META_DATA | TOC_NEW_OBJ_LIST | TOC_RAW_DATA;
    let mut bytes = segment(le, &[("/'g'/'a'", Some((10, 1)))], &1f64.to_le_bytes());
    // The path's length prefix claims 4 GiB.
    bytes[32..36].copy_from_slice(&u32::MAX.to_le_bytes());
    let e = parsed(&bytes).unwrap_err();
    assert!(
        e.contains("segment 0 (byte 0)") && e.contains("bytes needed"),
        "{e}"
    );
}

#[test]
fn not_tdms_is_refused() {
    let e = read_tdms_bytes(b"MDF     ", Path::new("x.tdms")).unwrap_err();
    assert!(
        e.to_string().contains("x.tdms: TDMS: not a TDMS file"),
        "{e}"
    );
}

/// Segments larger than a block: a large contiguous chunk (each channel's values read a
/// block at a time from its part), many small chunks (read a group at a time), interleaved
/// rows past a block; each with a last chunk or row cut short.
#[test]
fn segments_larger_than_a_block_read_block_by_block() {
    const A: &str = "/'g'/'a'";
    const B: &str = "/'g'/'b'";
    let le = TOC_META_DATA | TOC_NEW_OBJ_LIST | TOC_RAW_DATA;
    let (mut a, mut b) = (Vec::new(), Vec::new());
    let mut bytes = Vec::new();
    // One chunk of 400 000 f64 of a, then 400 000 i32 of b (4.8 MB), and a second chunk cut
    // within a's part: a's first 1000 values are there, b has none of it.
    let n = 400_000u64;
    let mut raw = Vec::new();
    for k in 0..n + 1000 {
        raw.extend((k as f64 * 0.5).to_le_bytes());
        a.push(k as f64 * 0.5);
        if k + 1 == n {
            for j in 0..n {
                raw.extend((-(j as i32)).to_le_bytes());
                b.push(-(j as f64));
            }
        }
    }
    bytes.extend(segment(le, &[(A, Some((10, n))), (B, Some((3, n)))], &raw));
    // Small chunks (3 a, 3 b) repeated 300 000 times: 10.8 MB, the last chunk cut in b.
    let mut raw = Vec::new();
    for c in 0..300_000u32 {
        for k in 0..3 {
            raw.extend(f64::from(c * 3 + k).to_le_bytes());
            a.push(f64::from(c * 3 + k));
        }
        for k in 0..3 {
            if c == 299_999 && k == 2 {
                break;
            }
            raw.extend((c as i32 + k).to_le_bytes());
            b.push(f64::from(c as i32 + k));
        }
    }
    bytes.extend(segment(le, &[(A, Some((10, 3))), (B, Some((3, 3)))], &raw));
    // Interleaved rows (a f64, b i32), 200 000 and a row cut short.
    let mut raw = Vec::new();
    for k in 0..200_000u32 {
        raw.extend((f64::from(k) + 0.25).to_le_bytes());
        raw.extend((k as i32).to_le_bytes());
        a.push(f64::from(k) + 0.25);
        b.push(f64::from(k));
    }
    raw.extend(1e9f64.to_le_bytes());
    let il = le | TOC_INTERLEAVED;
    bytes.extend(segment(il, &[(A, Some((10, 1))), (B, Some((3, 1)))], &raw));
    let file = parsed(&bytes).unwrap();
    assert_eq!(data(&bytes, &file, A), a);
    assert_eq!(data(&bytes, &file, B), b);
    // Both at once, in blocks of the same rows while both have them.
    let mut reader = TdmsBlocks::new(
        Bytes::Memory(bytes.as_slice().into()),
        file.segments.clone().into(),
        vec![A.to_string(), B.to_string()],
    );
    let (mut got_a, mut got_b) = (Vec::new(), Vec::new());
    while let Some(mut block) = reader.next_block().unwrap() {
        assert_eq!(block[0].len(), block[1].len());
        assert!(block[0].len() <= 3 * blocks::BLOCK_VALUES);
        got_a.append(&mut block[0]);
        got_b.append(&mut block[1]);
    }
    let rows = a.len().min(b.len());
    assert_eq!(got_a, a[..rows]);
    assert_eq!(got_b, b[..rows]);
}
