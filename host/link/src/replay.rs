//! Recorded streams: every message received from a device, in order, as it arrived
//! (corrupt ones too), so a run can be played back and give the same results.
//!
//! File format: the 8 bytes `RFSTRM01`, then one record per message: its length as a
//! little-endian `u32`, then its bytes.
//!
//! Damage is stepped over, not refused: a record whose length no message can have (a
//! flipped bit in its prefix, say) starts a search, byte by byte, for the next place
//! where a record holds a message that decodes (its CRC and structure check out); what
//! lies between is skipped and counted ([`Damage`]). A record whose message does not
//! decode is kept as it is (messages are recorded as they arrived, corrupt ones too) when
//! what follows it starts a record; otherwise its length was damaged, and the search
//! starts there too. A file's header met again (two recordings joined with `cat`) is
//! passed over and the second recording plays on. A record cut off by the end of the file
//! is skipped like damage; what came before stands.

use super::{Error, Received, Transport};
use rollfuse_core::protocol::{self, DeviceMessage, MAX_MESSAGE, MIN_MESSAGE};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::time::Duration;

const MAGIC: &[u8; 8] = b"RFSTRM01";

/// The longest record taken as it is: messages as they arrived may be longer than any
/// valid one (junk on the wire), not this much.
const MAX_RECORD: usize = 2 * MAX_MESSAGE;

/// How many records after an undecodable one must look like records for it to be kept.
const FOLLOWING: u32 = 2;

/// What a replay stepped over.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Damage {
    /// Bytes skipped while searching for the next good record.
    pub bytes_skipped: u64,
    /// Places where the records lost their framing.
    pub places: u64,
    /// Recordings joined after the first (their headers passed over).
    pub joined: u64,
}

impl Damage {
    /// A line for the user, or `None` when nothing was stepped over.
    pub fn describe(&self) -> Option<String> {
        let mut parts = Vec::new();
        if self.places > 0 {
            parts.push(format!(
                "{} damaged bytes skipped in {} places (every record after them that checks out was kept)",
                self.bytes_skipped, self.places
            ));
        }
        if self.joined > 0 {
            parts.push(format!(
                "{} joined recordings played in turn",
                self.joined + 1
            ));
        }
        (!parts.is_empty()).then(|| parts.join("; "))
    }
}

/// Plays a recorded stream back; commands sent to it are ignored.
pub struct Replay {
    path: PathBuf,
    file: std::fs::File,
    /// Bytes read and not yet taken, from `start` on.
    window: Vec<u8>,
    start: usize,
    eof: bool,
    /// Whether the records lost their framing and the next good one is being searched for.
    searching: bool,
    damage: Damage,
}

impl Replay {
    /// Opens a recording, checking its header.
    pub fn open(path: &Path) -> Result<Self, Error> {
        let file = std::fs::File::open(path).map_err(|e| Error::File {
            doing: "open",
            path: path.to_path_buf(),
            source: e.into(),
        })?;
        let mut me = Self {
            path: path.to_path_buf(),
            file,
            window: Vec::new(),
            start: 0,
            eof: false,
            searching: false,
            damage: Damage::default(),
        };
        let n = me.fill(MAGIC.len())?;
        if me.at_hand(n) != MAGIC {
            return Err(Error::NotARecording {
                path: path.to_path_buf(),
            });
        }
        me.start += MAGIC.len();
        Ok(me)
    }

    /// What the replay has stepped over so far.
    pub fn damage(&self) -> Damage {
        self.damage
    }

    /// Reads until `want` bytes are at hand, or the file ends: how many are.
    fn fill(&mut self, want: usize) -> Result<usize, Error> {
        while self.window.len() - self.start < want && !self.eof {
            self.window.drain(..self.start);
            self.start = 0;
            let had = self.window.len();
            self.window.resize(had + (1 << 16).max(want), 0);
            let n = loop {
                match self.file.read(&mut self.window[had..]) {
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                    other => break other,
                }
            };
            let n = n.map_err(|e| Error::File {
                doing: "read",
                path: self.path.clone(),
                source: e.into(),
            })?;
            self.window.truncate(had + n);
            self.eof = n == 0;
        }
        Ok((self.window.len() - self.start).min(want))
    }

    /// The `n` bytes at hand from the current place.
    fn at_hand(&self, n: usize) -> &[u8] {
        &self.window[self.start..self.start + n]
    }

    /// The record length written `at` bytes on (4 bytes there at hand).
    fn length_at(&self, at: usize) -> usize {
        let b = self.at_hand(at + 4);
        u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]) as usize
    }

    /// Whether the `n`-byte message of the record `at` bytes on (at hand) decodes.
    fn decodes_at(&self, at: usize, n: usize) -> bool {
        protocol::decode::<DeviceMessage>(&self.at_hand(at + 4 + n)[at + 4..]).is_ok()
    }

    /// Ends the replay at a cut-off end: the `n` bytes left are skipped.
    fn cut_end(&mut self, n: usize) -> Received {
        self.damage.bytes_skipped += n as u64;
        self.start += n;
        Received::Closed
    }

    /// Whether the `n`-byte record at hand is one: its message decodes, or — outside a
    /// search, where messages recorded corrupt as they arrived are kept — what follows it
    /// starts records too ([`Replay::records_follow`]).
    fn record_holds(&mut self, n: usize) -> Result<bool, Error> {
        if self.decodes_at(0, n) {
            return Ok(true);
        }
        Ok(!self.searching
            && !self.swallows_a_record(n)
            && self.records_follow(4 + n, FOLLOWING)?)
    }

    /// Whether a record whose message decodes lies inside the `n`-byte record at hand (all
    /// of it at hand): then its length was damaged. Tiles are all of one size, so a
    /// flipped length can span a whole number of them exactly and land on a record that
    /// checks out; kept as it is, it would take the good records inside it down with it,
    /// unseen.
    fn swallows_a_record(&self, n: usize) -> bool {
        (1..n).any(|at| {
            let inner = self.length_at(at);
            (MIN_MESSAGE..=MAX_MESSAGE).contains(&inner)
                && at + 4 + inner <= 4 + n
                && self.decodes_at(at, inner)
        })
    }

    /// Whether records start `at` bytes on: the file ends there, or a header is there, or
    /// a record whose message decodes — or, `depth` more times, one of a length a message
    /// can have whose following bytes pass the same test.
    fn records_follow(&mut self, at: usize, depth: u32) -> Result<bool, Error> {
        let got = self.fill(at + MAGIC.len())?;
        if got == at {
            return Ok(true);
        }
        if got < at + 4 {
            return Ok(false);
        }
        if &self.at_hand(got)[at..] == MAGIC {
            return Ok(true);
        }
        let n = self.length_at(at);
        if !(MIN_MESSAGE..=MAX_RECORD).contains(&n) || self.fill(at + 4 + n)? < at + 4 + n {
            return Ok(false);
        }
        if self.decodes_at(at, n) {
            return Ok(true);
        }
        Ok(depth > 0 && self.records_follow(at + 4 + n, depth - 1)?)
    }

    /// Steps one byte further in a search for the next good record.
    fn skip_byte(&mut self) {
        if !self.searching {
            self.searching = true;
            self.damage.places += 1;
        }
        self.start += 1;
        self.damage.bytes_skipped += 1;
    }
}

impl Transport for Replay {
    fn send(&mut self, _message: &[u8]) -> Result<(), Error> {
        Ok(())
    }

    fn receive(&mut self, buf: &mut [u8], _timeout: Duration) -> Result<Received, Error> {
        loop {
            let got = self.fill(MAGIC.len())?;
            if got < 4 {
                // The end, or a length prefix cut off by it.
                return Ok(self.cut_end(got));
            }
            if self.at_hand(got) == MAGIC {
                self.start += MAGIC.len();
                self.damage.joined += 1;
                self.searching = false;
                continue;
            }
            let n = self.length_at(0);
            if n <= MAX_RECORD.min(buf.len())
                && self.fill(4 + n)? == 4 + n
                && self.record_holds(n)?
            {
                buf[..n].copy_from_slice(&self.at_hand(4 + n)[4..]);
                self.start += 4 + n;
                self.searching = false;
                return Ok(Received::Message(n));
            }
            // A length no message has, a record the file's end cuts off, or one that
            // does not fit between its neighbours: the framing is lost here.
            self.skip_byte();
        }
    }

    fn is_live(&self) -> bool {
        false
    }

    fn damage(&self) -> Option<String> {
        self.damage.describe()
    }
}

/// Writes every received message to a recording, under a temporary name until
/// [`Recorder::finish`] moves it into place (a failed session leaves the previous
/// recording as it was).
pub struct Recorder {
    file: rollfuse_io::files::PendingFile,
}

impl Recorder {
    /// Starts a recording (replacing the file at `path` when finished).
    pub fn create(path: &Path) -> Result<Self, Error> {
        let mut file = rollfuse_io::files::PendingFile::create(path).map_err(|e| Error::File {
            doing: "create",
            path: path.to_path_buf(),
            source: e.into(),
        })?;
        file.write_all(MAGIC)?;
        Ok(Self { file })
    }

    /// Appends one message.
    pub fn record(&mut self, message: &[u8]) -> Result<(), Error> {
        self.file.write_all(&(message.len() as u32).to_le_bytes())?;
        Ok(self.file.write_all(message)?)
    }

    /// Flushes, syncs and moves the recording into place.
    pub fn finish(self) -> Result<(), Error> {
        Ok(self.file.commit()?)
    }

    /// [`Recorder::finish`] for a session that failed: the recording is kept only where no
    /// file is at its name (it never replaces an older one); whether it was kept.
    pub fn keep_if_new(self) -> Result<bool, Error> {
        Ok(self.file.commit_if_new()?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rollfuse_core::protocol::Tile;

    #[test]
    fn a_recording_that_is_not_there_is_told_from_one_that_is_not_a_recording() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rec.bin");
        let missing = Replay::open(&path).err().unwrap();
        assert!(
            matches!(missing, Error::File { doing: "open", .. }),
            "{missing:?}"
        );
        std::fs::write(&path, b"PNG, not a recording").unwrap();
        let other = Replay::open(&path).err().unwrap();
        assert!(matches!(other, Error::NotARecording { .. }), "{other:?}");
        assert!(other.to_string().contains("rec.bin"), "{other}");
    }

    /// A recording's bytes: the header, then `count` tile messages (indices from `first`).
    fn recording(first: u32, count: u32) -> Vec<u8> {
        let mut bytes = MAGIC.to_vec();
        let mut buf = vec![0u8; MAX_MESSAGE];
        for index in first..first + count {
            // Mostly black pixels: runs of zeros look like plausible lengths.
            let pixels: Vec<u8> = (0..64u32)
                .map(|i| if i % 9 == 0 { index as u8 } else { 0 })
                .collect();
            let tile = DeviceMessage::Tile(Tile {
                index,
                width: 8,
                height: 8,
                observations: 4,
                pixels: &pixels,
            });
            let n = protocol::encode(index, &tile, &mut buf).unwrap();
            bytes.extend((n as u32).to_le_bytes());
            bytes.extend(&buf[..n]);
        }
        bytes
    }

    /// Every tile index the replay of `bytes` gives, and its damage.
    fn replayed(bytes: &[u8]) -> (Vec<u32>, Damage) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.rfs");
        std::fs::write(&path, bytes).unwrap();
        let mut replay = Replay::open(&path).unwrap();
        let mut buf = vec![0u8; MAX_RECORD];
        let mut indices = Vec::new();
        while let Received::Message(n) = replay.receive(&mut buf, Duration::ZERO).unwrap() {
            if let Ok((_, DeviceMessage::Tile(t))) = protocol::decode::<DeviceMessage>(&buf[..n]) {
                indices.push(t.index);
            }
        }
        (indices, replay.damage())
    }

    /// Where record `k` (from 0) starts.
    fn record_at(bytes: &[u8], k: usize) -> usize {
        let mut at = MAGIC.len();
        for _ in 0..k {
            let n = u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
            at += 4 + n;
        }
        at
    }

    #[test]
    fn a_flipped_length_loses_at_most_its_neighbours_and_is_counted() {
        let good = recording(0, 133);
        for (record, bit) in [(130, 31), (130, 20), (0, 30), (131, 3), (132, 28)] {
            let mut bytes = good.clone();
            let at = record_at(&bytes, record);
            bytes[at + bit / 8] ^= 1 << (bit % 8);
            let (indices, damage) = replayed(&bytes);
            let lost: Vec<u32> = (0..133).filter(|i| !indices.contains(i)).collect();
            assert!(lost.len() <= 2, "record {record} bit {bit}: lost {lost:?}");
            assert!(indices.windows(2).all(|w| w[0] < w[1]), "{indices:?}");
            assert!(
                lost.is_empty() || damage.places >= 1 || record == 132,
                "record {record} bit {bit}: {damage:?}"
            );
        }
        let (indices, damage) = replayed(&good);
        assert_eq!((indices.len(), damage), (133, Damage::default()));
    }

    #[test]
    fn joined_recordings_play_in_turn_and_junk_between_them_is_skipped() {
        let mut bytes = recording(0, 50);
        bytes.extend(recording(50, 50));
        let (indices, damage) = replayed(&bytes);
        assert_eq!(indices, (0..100).collect::<Vec<_>>());
        assert_eq!(damage.joined, 1);
        assert!(damage.describe().unwrap().contains("2 joined recordings"));
        let mut bytes = recording(0, 20);
        bytes.extend(b"\xff\xff\xff\x7fjunk junk junk");
        bytes.extend(&recording(20, 20)[MAGIC.len()..]);
        let (indices, damage) = replayed(&bytes);
        assert_eq!(indices, (0..40).collect::<Vec<_>>());
        assert_eq!((damage.places, damage.bytes_skipped), (1, 18));
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(
            std::env::var("ROLLFUSE_FUZZ_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(64)
        ))]

        /// Any damage (bytes replaced, inserted, removed, the file cut): no error, no tile
        /// that is not the recording's, in order, and the tiles no damage touched kept.
        #[test]
        fn damage_anywhere_keeps_the_untouched_tiles_and_makes_up_none(
            edits in proptest::collection::vec(
                (proptest::prelude::any::<proptest::sample::Index>(), 0u8..3, proptest::prelude::any::<u8>()),
                1..6,
            ),
        ) {
            let good = recording(0, 40);
            let mut bytes = good.clone();
            let mut touched = Vec::new();
            for (at, kind, b) in edits {
                let i = MAGIC.len() + at.index(bytes.len() - MAGIC.len());
                touched.push(i);
                match kind {
                    0 => bytes[i] ^= b | 1,
                    1 => bytes.insert(i, b),
                    _ => { bytes.remove(i); }
                }
            }
            let (indices, _) = replayed(&bytes);
            proptest::prop_assert!(indices.iter().all(|&i| i < 40), "{:?}", indices);
            proptest::prop_assert!(indices.windows(2).all(|w| w[0] < w[1]), "{:?}", indices);
            // Each edit can break the framing around it: at most a few tiles each.
            proptest::prop_assert!(indices.len() + 3 * touched.len() >= 40, "{} kept", indices.len());
        }
    }

    /// One damaged byte anywhere — a length's second byte among them, which moves the
    /// length by a whole number of the recording's equal-sized records — loses at most its
    /// own record and one beside it, and a loss of more than the damaged record is counted.
    #[test]
    fn one_damaged_byte_anywhere_loses_at_most_its_neighbour() {
        let good = recording(0, 40);
        for at in MAGIC.len()..good.len() {
            for flip in [0x01u8, 0x04, 0x05, 0x80] {
                let mut bytes = good.clone();
                bytes[at] ^= flip;
                let (indices, damage) = replayed(&bytes);
                let lost = 40 - indices.len();
                assert!(lost <= 2, "byte {at} ^ {flip:#x}: kept {indices:?}");
                assert!(indices.windows(2).all(|w| w[0] < w[1]), "{indices:?}");
                assert!(
                    lost <= 1 || damage.places >= 1,
                    "byte {at} ^ {flip:#x}: {damage:?}"
                );
            }
        }
    }

    #[test]
    fn a_recording_cut_anywhere_keeps_what_came_before() {
        let good = recording(0, 10);
        for cut in [good.len() - 1, good.len() - 30, record_at(&good, 5) + 2] {
            let (indices, _) = replayed(&good[..cut]);
            let whole = (0..10).filter(|&k| record_at(&good, k + 1) <= cut).count() as u32;
            assert_eq!(indices, (0..whole).collect::<Vec<_>>(), "cut at {cut}");
        }
    }
}
