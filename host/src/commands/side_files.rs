//! The files `fuse` and `splice` write beside an image `OUT` (`STEM.EXT`), and the rule
//! that they belong to one output: once a run's own outputs are in place, every side file
//! of that name it did not write is removed, so none describes an image it no longer
//! matches (a roll's index beside a mosaic, a mosaic's offsets beside a strip).
//!
//! A file is removed only if it is what the tool writes under that name (by its first
//! bytes): a user's own `STEM.json` of other content is left alone.

use rollfuse::strip_file::StripWriter;
use std::path::{Path, PathBuf};

/// A kind of file written beside `OUT`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// A roll's strip index, `STEM.json`, and its numbered segments `STEM.NNNN.EXT`.
    Strip,
    /// A roll's per-frame placements, `STEM.frames.csv`.
    FramesCsv,
    /// A mosaic's offsets, `STEM.offsets.json`.
    Offsets,
}

impl Side {
    const ALL: [Side; 3] = [Side::Strip, Side::FramesCsv, Side::Offsets];

    /// The file's path beside `out`.
    pub fn path(self, out: &Path) -> PathBuf {
        match self {
            Side::Strip => StripWriter::index_path(out),
            Side::FramesCsv => out.with_extension("frames.csv"),
            Side::Offsets => out.with_extension("offsets.json"),
        }
    }

    /// How the file the tool writes begins.
    fn begins_with(self) -> &'static [u8] {
        match self {
            Side::Strip => b"{\n  \"width\":",
            Side::FramesCsv => b"frame,file,row,col,",
            Side::Offsets => b"{\n  \"align\":",
        }
    }

    /// Whether the file at `path` is one the tool wrote as this kind (a regular file: a FIFO
    /// of that name is never opened, which could wait forever).
    fn written_by_us(self, path: &Path) -> bool {
        if !std::fs::metadata(path).is_ok_and(|m| m.is_file()) {
            return false;
        }
        let want = self.begins_with();
        let mut head = vec![0; want.len()];
        std::fs::File::open(path)
            .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut head))
            .is_ok_and(|()| head == want)
    }
}

/// Removes the side files of `out` that are not among `written` (the run just put its
/// outputs in place). An older strip's segments go with its index; `out` itself, when the
/// new output is a single image, has just been replaced.
pub fn remove_others(out: &Path, written: &[Side]) -> anyhow::Result<()> {
    for side in Side::ALL.into_iter().filter(|s| !written.contains(s)) {
        let path = side.path(out);
        if !side.written_by_us(&path) {
            continue;
        }
        let mut stale = vec![path];
        if side == Side::Strip {
            stale.extend(StripWriter::segments_on_disk(out, 0));
        }
        rollfuse::files::remove_stale(stale)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_tools_own_files_of_other_outputs_are_removed() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("strip.png");
        let write = |name: &str, text: &str| std::fs::write(dir.path().join(name), text).unwrap();
        write("strip.png", "the new image");
        write("strip.json", "{\n  \"width\": 8, \"segments\": []}");
        write("strip.0000.png", "segment");
        write("strip.0001.png", "segment");
        write("strip.frames.csv", "frame,file,row,col,source\n");
        write("strip.offsets.json", "{\"mine\": true}");
        remove_others(&out, &[Side::FramesCsv]).unwrap();
        let left = |name: &str| dir.path().join(name).exists();
        assert!(left("strip.png") && left("strip.frames.csv"));
        assert!(!left("strip.json") && !left("strip.0000.png") && !left("strip.0001.png"));
        assert!(left("strip.offsets.json"), "not ours: kept");
        // A FIFO in a side file's place is neither opened (which would wait for a writer)
        // nor removed.
        let fifo = dir.path().join("other.offsets.json");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        assert!(made.unwrap().success());
        remove_others(&dir.path().join("other.png"), &[]).unwrap();
        assert!(left("other.offsets.json"));
    }
}
