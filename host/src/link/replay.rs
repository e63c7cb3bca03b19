//! Recorded streams: every message received from a device, in order, as it arrived
//! (corrupt ones too), so a run can be played back and give the same results.
//!
//! File format: the 8 bytes `RFSTRM01`, then one record per message: its length as a
//! little-endian `u32`, then its bytes.

use super::{Received, Transport};
use anyhow::{Context, bail};
use rollfuse_core::protocol::MAX_MESSAGE;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};
use std::time::Duration;

const MAGIC: &[u8; 8] = b"RFSTRM01";

/// Plays a recorded stream back; commands sent to it are ignored.
pub struct Replay {
    path: PathBuf,
    reader: BufReader<std::fs::File>,
}

impl Replay {
    /// Opens a recording, checking its header.
    pub fn open(path: &Path) -> anyhow::Result<Self> {
        let file = std::fs::File::open(path)
            .with_context(|| format!("cannot open recording {}", path.display()))?;
        let mut reader = BufReader::new(file);
        let mut magic = [0u8; 8];
        reader
            .read_exact(&mut magic)
            .ok()
            .filter(|_| &magic == MAGIC)
            .with_context(|| format!("{} is not a rollfuse stream recording", path.display()))?;
        Ok(Self {
            path: path.to_path_buf(),
            reader,
        })
    }
}

impl Transport for Replay {
    fn send(&mut self, _message: &[u8]) -> anyhow::Result<()> {
        Ok(())
    }

    fn receive(&mut self, buf: &mut [u8], _timeout: Duration) -> anyhow::Result<Received> {
        let mut len = [0u8; 4];
        match self.reader.read_exact(&mut len) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => {
                return Ok(Received::Closed);
            }
            Err(e) => return Err(e).context(format!("reading {}", self.path.display())),
        }
        let n = u32::from_le_bytes(len) as usize;
        if n > buf.len() || n > 2 * MAX_MESSAGE {
            bail!(
                "{}: a record of {n} bytes is longer than any message: the file is damaged",
                self.path.display()
            );
        }
        match self.reader.read_exact(&mut buf[..n]) {
            Ok(()) => Ok(Received::Message(n)),
            // A recording cut off mid-record ends there; what came before stands.
            Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => Ok(Received::Closed),
            Err(e) => Err(e).context(format!("reading {}", self.path.display())),
        }
    }

    fn is_live(&self) -> bool {
        false
    }
}

/// Writes every received message to a recording, under a temporary name until
/// [`Recorder::finish`] moves it into place (a failed session leaves the previous
/// recording as it was).
pub struct Recorder {
    file: crate::files::PendingFile,
}

impl Recorder {
    /// Starts a recording (replacing the file at `path` when finished).
    pub fn create(path: &Path) -> anyhow::Result<Self> {
        let mut file = crate::files::PendingFile::create(path)
            .with_context(|| format!("cannot create recording {}", path.display()))?;
        file.write_all(MAGIC)?;
        Ok(Self { file })
    }

    /// Appends one message.
    pub fn record(&mut self, message: &[u8]) -> anyhow::Result<()> {
        self.file.write_all(&(message.len() as u32).to_le_bytes())?;
        self.file.write_all(message)
    }

    /// Flushes, syncs and moves the recording into place.
    pub fn finish(self) -> anyhow::Result<()> {
        self.file.commit()
    }

    /// [`Recorder::finish`] for a session that failed: the recording is kept only where no
    /// file is at its name (it never replaces an older one); whether it was kept.
    pub fn keep_if_new(self) -> anyhow::Result<bool> {
        self.file.commit_if_new()
    }
}
