//! `manifest.json` of a folder of frames: written by `rollfuse simulate`, read back by
//! `fuse`, `splice` and `eval` through the same type.
//!
//! A motion system may write the `frames` list alone, each frame's `file` and `strip_row`
//! (its commanded position as the strip row of its top row); everything else is then
//! absent and the `format` empty. A file of another format — a stream's `manifest.json`
//! (`rollfuse-stream-1`), or one a later version wrote — is refused naming its format.

use super::scene::{Effect, Scene};
use crate::Error;
use rollfuse_io::invalid;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The format this version writes and reads (the manifest's `format` field).
pub const FRAMES_FORMAT: &str = "rollfuse-frames-1";

/// `manifest.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// [`FRAMES_FORMAT`]; empty in a motion system's record.
    #[serde(default)]
    pub format: String,
    /// Scene name.
    #[serde(default)]
    pub scene: String,
    /// Seed used.
    #[serde(default)]
    pub seed: u64,
    /// Effects listed.
    #[serde(default)]
    pub effects: Vec<Effect>,
    /// `gray` or `rgb`.
    #[serde(default)]
    pub color: String,
    /// Image width and height, pixels.
    #[serde(default)]
    pub image_size: Option<[usize; 2]>,
    /// Belt mm per pixel.
    #[serde(default)]
    pub mm_per_px: Option<f64>,
    /// The frames.
    pub frames: Vec<FrameRecord>,
    /// Ground truth files, relative to the output folder.
    #[serde(default)]
    pub truth: Option<Truth>,
    /// The scene as simulated (defaults filled in).
    #[serde(default)]
    pub scene_file: Option<Scene>,
}

/// What `manifest.json` records of one frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameRecord {
    /// The PNG's file name.
    pub file: String,
    /// Commanded belt position of the roller's apex, mm (what the motion system reports).
    #[serde(default)]
    pub offset_mm: f64,
    /// True belt position (differs with `jitter`), mm.
    #[serde(default)]
    pub actual_offset_mm: f64,
    /// Commanded position as a strip row of image row 0 (fractional pixels).
    pub strip_row: f64,
    /// True position as a strip row of image row 0.
    #[serde(default)]
    pub actual_strip_row: f64,
    /// How far the belt lay sideways (`wander`): image column `x` shows strip column `x +
    /// actual_sideways_px`.
    #[serde(default)]
    pub actual_sideways_px: f64,
    /// The stages that ran.
    #[serde(default)]
    pub stages: Vec<Effect>,
}

/// Where the ground truth is.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    /// Height map over the strip, mm, float32 `.npy` (rows along the belt).
    pub height_npy: String,
    /// The same as a 16-bit PNG, 1 µm per level.
    pub height_png: String,
    /// The ideal contact image over the strip (the MS-SSIM reference).
    pub ideal_png: String,
    /// Strip size: [width, rows].
    pub strip_size: [usize; 2],
    /// Belt position of strip row 0, mm.
    pub strip_origin_mm: f64,
    /// Region masks (name → file), 255 inside.
    pub regions: Vec<(String, String)>,
    /// Up to six frames across the roll, side by side.
    pub contact_sheet_png: String,
    /// A textile's fabric and defects (`truth/defects.json`); absent for other objects.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub defects_json: Option<String>,
}

/// The roller as a manifest records it: what the contact window is computed from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Roller {
    /// Frame width and height, pixels.
    pub image_size: [usize; 2],
    /// Roller radius, mm.
    pub radius_mm: f64,
    /// Press depth at the apex, mm.
    pub press_depth_mm: f64,
    /// Belt mm per pixel.
    pub mm_per_px: f64,
}

impl Manifest {
    /// Reads `path`: a manifest of this format or a motion system's `frames` list. Another
    /// format (a stream's record) or a field of the wrong type is refused naming the file.
    pub fn read(path: &Path) -> Result<Self, Error> {
        #[derive(Deserialize)]
        struct Tag {
            #[serde(default)]
            format: String,
        }
        let text = std::fs::read_to_string(path).map_err(|source| Error::Read {
            what: "manifest",
            path: path.to_path_buf(),
            source,
        })?;
        let tag: Tag = serde_json::from_str(&text)
            .map_err(|e| Error::Invalid(format!("{} is not a JSON object: {e}", path.display())))?;
        match tag.format.as_str() {
            "" | FRAMES_FORMAT => {}
            other => invalid!(
                "{} is of format {other}, not a manifest of frames ({FRAMES_FORMAT}, or a \
                 motion system's `frames` list)",
                path.display()
            ),
        }
        serde_json::from_str(&text).map_err(|e| {
            Error::Invalid(format!(
                "{} is not a manifest of frames: {e}",
                path.display()
            ))
        })
    }

    /// The record of the frame whose file is named `name`.
    pub fn frame(&self, name: &str) -> Option<&FrameRecord> {
        self.frames.iter().find(|f| f.file == name)
    }

    /// The roller the frames were rendered with, where the manifest records it.
    pub fn roller(&self) -> Option<Roller> {
        let sensor = &self.scene_file.as_ref()?.sensor;
        Some(Roller {
            image_size: self.image_size?,
            radius_mm: sensor.roller_radius_mm,
            press_depth_mm: sensor.press_depth_mm,
            mm_per_px: sensor.mm_per_px,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Result<Manifest, Error> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("manifest.json");
        std::fs::write(&path, text).unwrap();
        Manifest::read(&path)
    }

    #[test]
    fn a_motion_system_s_frames_list_is_a_manifest() {
        let m = read(r#"{"frames": [{"file": "a.png", "strip_row": 12.5}]}"#).unwrap();
        assert_eq!(m.frame("a.png").map(|f| f.strip_row), Some(12.5));
        assert!(m.frame("b.png").is_none());
        assert_eq!(m.roller(), None);
        assert!(m.format.is_empty());
    }

    #[test]
    fn other_records_and_formats_are_refused_by_name() {
        let stream = read(r#"{"format": "rollfuse-stream-1", "messages": 3}"#).unwrap_err();
        let said = format!("{stream:#}");
        assert!(
            said.contains("of format rollfuse-stream-1, not a manifest of frames"),
            "{said}"
        );
        let newer = read(r#"{"format": "rollfuse-frames-9", "frames": []}"#).unwrap_err();
        assert!(
            format!("{newer:#}").contains("of format rollfuse-frames-9"),
            "{newer:#}"
        );
        let typo = read(r#"{"frames": [{"file": "a.png", "strip_row": "NaN"}]}"#).unwrap_err();
        let said = format!("{typo:#}");
        assert!(
            said.contains("not a manifest of frames") && said.contains("invalid type"),
            "{said}"
        );
        let missing = read(r#"{"frames": [{"file": "a.png"}]}"#).unwrap_err();
        assert!(format!("{missing:#}").contains("missing field `strip_row`"));
        assert!(read("[1, 2]").is_err());
    }
}
