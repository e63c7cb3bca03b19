//! The recording reader, the message decoder and the strip assembler fed crafted
//! recordings: tile messages with valid CRCs but any index (near 0, near jumps, near
//! 2³²), any size (0×0 included) and pixel counts that lie, junk records, truncated
//! records and a truncated end. Whatever comes, `stream` must not panic, must leave no
//! temporary behind, and must write no more strip than the tiles it was given can
//! account for (at most 64 black tiles of fill between two received ones).
//!
//! The cases run per test run are `ROLLFUSE_FUZZ_CASES` (default 64); failures proptest
//! finds are kept in `stream_fuzz.proptest-regressions` beside this file and replayed
//! first on every run.

use proptest::prelude::*;
use rollfuse::link::replay::Replay;
use rollfuse::progress::Silent;
use rollfuse::stream::{self, Options};
use rollfuse_core::protocol::{self, DeviceMessage, MAX_MESSAGE};
use std::path::Path;

fn cases() -> u32 {
    std::env::var("ROLLFUSE_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(64)
}

/// One record of a crafted recording.
#[derive(Debug, Clone)]
enum Record {
    /// A tile with a valid CRC: the stream's size unless `odd` (any size, 0×0 included),
    /// with `lie` pixels instead of `width × height` when given.
    Tile {
        index: u32,
        odd: Option<(u16, u16)>,
        lie: Option<usize>,
    },
    /// Random bytes.
    Junk(Vec<u8>),
    /// A valid tile cut short.
    Cut(usize),
}

fn index() -> impl Strategy<Value = u32> {
    prop_oneof![
        0u32..40,
        (0u32..200).prop_map(|i| i * 33),
        (0u32..8).prop_map(|d| u32::MAX - d),
        (0u32..8).prop_map(|d| 2_000_000_000 + d),
        any::<u32>(),
    ]
}

fn record() -> impl Strategy<Value = Record> {
    prop_oneof![
        8 => (
            index(),
            prop_oneof![6 => Just(None), 1 => (0u16..40, 0u16..10).prop_map(Some)],
            prop_oneof![6 => Just(None), 1 => (0usize..500).prop_map(Some)],
        )
            .prop_map(|(index, odd, lie)| Record::Tile { index, odd, lie }),
        1 => proptest::collection::vec(any::<u8>(), 0..64).prop_map(Record::Junk),
        1 => (0usize..64).prop_map(Record::Cut),
    ]
}

fn tile(seq: u32, index: u32, (width, height): (u16, u16), pixels: usize) -> Vec<u8> {
    let data = vec![77u8; pixels];
    let msg = DeviceMessage::Tile(protocol::Tile {
        index,
        width,
        height,
        observations: 1,
        pixels: &data,
    });
    let mut buf = vec![0u8; MAX_MESSAGE];
    // A message over the limits does not encode: it becomes junk of its own size.
    match protocol::encode(seq, &msg, &mut buf) {
        Ok(n) => buf[..n].to_vec(),
        Err(_) => vec![0xA5; pixels.min(64)],
    }
}

/// The recording's bytes: magic, then length-prefixed records of tiles of `size` (unless
/// odd), perhaps cut at the end.
fn recording(records: &[Record], size: (u16, u16), cut_end: usize) -> Vec<u8> {
    let mut out = b"RFSTRM01".to_vec();
    for (seq, r) in records.iter().enumerate() {
        let bytes = match r {
            Record::Tile { index, odd, lie } => {
                let (w, h) = odd.unwrap_or(size);
                let pixels = lie.unwrap_or(usize::from(w) * usize::from(h));
                tile(seq as u32, *index, (w, h), pixels)
            }
            Record::Junk(b) => b.clone(),
            Record::Cut(n) => {
                let t = tile(seq as u32, 5, (8, 4), 32);
                t[..(*n).min(t.len())].to_vec()
            }
        };
        out.extend_from_slice(&(bytes.len() as u32).to_le_bytes());
        out.extend_from_slice(&bytes);
    }
    let keep = out.len().saturating_sub(cut_end);
    out.truncate(keep.max(8));
    out
}

/// Every file below `dir`, with its size.
fn files(dir: &Path) -> Vec<(String, u64)> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            (
                e.file_name().to_string_lossy().into_owned(),
                e.metadata().unwrap().len(),
            )
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases()))]

    #[test]
    fn crafted_recordings_are_read_without_a_panic_or_an_unbounded_strip(
        records in proptest::collection::vec(record(), 0..24),
        size in (1u16..40, 1u16..10),
        cut_end in prop_oneof![3 => Just(0usize), 1 => 0usize..40],
    ) {
        let tmp = tempfile::tempdir().unwrap();
        let rec = tmp.path().join("rec.bin");
        std::fs::write(&rec, recording(&records, size, cut_end)).unwrap();
        let out = tmp.path().join("out");
        std::fs::create_dir(&out).unwrap();
        let mut link = Replay::open(&rec).unwrap();
        let options = Options::into_folder(&out);
        // An error is an answer; a panic fails the test.
        let _ = stream::run(&mut link, &options, &Silent);
        let written = files(&out);
        for (name, _) in &written {
            prop_assert!(!name.starts_with('.'), "a temporary was left: {name}");
        }
        // Each received tile is at most 40 × 10 pixels, plus at most 64 tiles of fill
        // before it; PNG of constant rows compresses, so this bounds the files loosely.
        let tiles = records.len() as u64;
        let bound = 64 * 1024 + tiles * 65 * 40 * 10;
        let total: u64 = written.iter().map(|(_, n)| n).sum();
        prop_assert!(
            total <= bound,
            "{total} bytes in {} files written for {tiles} records",
            written.len()
        );
    }
}
