//! Writing a simulation to disk: `frame_0000.png …`, `truth/`, `contact_sheet.png`,
//! `lights.toml` (RGB scenes: the true light file for `rollfuse depth`) and
//! `manifest.json`.

use super::manifest::{FRAMES_FORMAT, FrameRecord, Manifest, Truth};
use super::render::{FrameDefect, Planes, Simulator, Strip, StripDefect};
use super::scene::Object;
use super::textile;
use crate::Error;
use rollfuse_io::files::{Batch, PngLayout, WriteError, add_png};
use rollfuse_io::progress::Progress;
use rollfuse_io::{invalid, npy};
use serde::Serialize;
use std::path::Path;

/// `truth/defects.json`: what the detector should find.
#[derive(Debug, Serialize)]
pub struct DefectsTruth {
    /// The fabric's name.
    pub fabric: String,
    /// Its label: the place in `sim::textile::FABRICS`.
    pub class: usize,
    /// Belt position of strip row 0, mm.
    pub strip_origin_mm: f64,
    /// Belt mm per pixel.
    pub mm_per_px: f64,
    /// The defects, boxes on the canvas (mm) and on the strip (pixels).
    pub defects: Vec<StripDefect>,
    /// Each frame's view of them, in frame order.
    pub frames: Vec<FrameDefects>,
}

/// The defects one frame shows.
#[derive(Debug, Serialize)]
pub struct FrameDefects {
    /// The frame's file.
    pub file: String,
    /// The defects in view.
    pub defects: Vec<FrameDefect>,
}

/// Puts up to six evenly spaced frames side by side, 4 px apart on white.
fn contact_sheet(frames: &[Planes]) -> Planes {
    let (w, h, c) = (frames[0].width, frames[0].height, frames[0].planes.len());
    let gap = 4;
    let width = frames.len() * (w + gap) - gap;
    let mut planes = vec![vec![255f32; width * h]; c];
    for (k, f) in frames.iter().enumerate() {
        for (dst, src) in planes.iter_mut().zip(&f.planes) {
            for y in 0..h {
                let x0 = k * (w + gap);
                dst[y * width + x0..y * width + x0 + w].copy_from_slice(&src[y * w..(y + 1) * w]);
            }
        }
    }
    Planes {
        width,
        height: h,
        planes,
    }
}

/// Removes `frame_NNNN.png` files numbered `count` and above, left by an earlier, longer
/// run into the same folder: they would otherwise be taken for frames of this one.
fn remove_stale_frames(out: &Path, count: usize) -> Result<(), WriteError> {
    let listed = std::fs::read_dir(out).map_err(WriteError::io("list", out))?;
    for entry in listed {
        let path = entry.map_err(WriteError::io("list", out))?.path();
        if let Some(k) = frame_index(&path)
            && k >= count
        {
            std::fs::remove_file(&path).map_err(WriteError::io("remove stale", &path))?;
        }
    }
    Ok(())
}

/// The frame number of a file named as `write` names frames (`frame_NNNN.png`).
fn frame_index(path: &Path) -> Option<usize> {
    let name = path.file_name()?.to_str()?;
    let digits = name.strip_prefix("frame_")?.strip_suffix(".png")?;
    (digits.len() == 4 && digits.bytes().all(|b| b.is_ascii_digit()))
        .then(|| digits.parse().ok())
        .flatten()
}

/// Refuses, before any work, an input (`what`, e.g. the scene) that a simulation into
/// `out` would replace or remove: a file in `out` named as one of its outputs
/// (`manifest.json`, `contact_sheet.png`, `lights.toml`, any `frame_NNNN.png`), or
/// anything under `out/truth/`.
pub fn refuse_overwriting(input: &Path, what: &str, out: &Path) -> Result<(), WriteError> {
    let at = rollfuse_io::files::resolved(input);
    let dir = rollfuse_io::files::resolved(out);
    let named_as_output = at.parent() == Some(dir.as_path())
        && (frame_index(&at).is_some()
            || at.file_name().is_some_and(|n| {
                ["manifest.json", "contact_sheet.png", "lights.toml"]
                    .iter()
                    .any(|o| n == *o)
            }));
    if named_as_output || at.starts_with(dir.join("truth")) {
        invalid!(
            "the {what} {} is where the simulation writes into {}: refusing to overwrite an input",
            input.display(),
            out.display()
        );
    }
    Ok(())
}

/// Adds the ground truth under `out/truth/` to `batch`: the height map (`.npy` in mm,
/// 16-bit `.png` in µm), the ideal contact image and each region's mask; returns the
/// regions' names and files.
fn add_truth(
    batch: &mut Batch,
    sim: &Simulator,
    strip: &Strip,
    out: &Path,
) -> Result<Vec<(String, String)>, Error> {
    // Validation bounds every scene value; this is the last word on what is written.
    if !strip.height_mm.iter().all(|h| h.is_finite()) {
        invalid!("the scene's height map is not finite everywhere: nothing written");
    }
    let truth_dir = out.join("truth");
    batch.add_bytes(
        &truth_dir.join("height.npy"),
        &npy::encode_f32(&strip.height_mm, strip.rows, strip.width)?,
    )?;
    let microns: Vec<u8> = strip
        .height_mm
        .iter()
        .flat_map(|h| ((h * 1000.0).round().clamp(0.0, 65535.0) as u16).to_ne_bytes())
        .collect();
    let size = (strip.width, strip.rows);
    add_png(
        batch,
        &truth_dir.join("height.png"),
        &microns,
        size,
        PngLayout::Gray16,
    )?;
    sim.ideal().add_png(batch, &truth_dir.join("ideal.png"))?;
    let mut regions = Vec::new();
    for (name, mask) in &strip.regions {
        let file = format!("truth/region_{name}.png");
        add_png(batch, &out.join(&file), mask, size, PngLayout::Gray8)?;
        regions.push((name.clone(), file));
    }
    Ok(regions)
}

/// Adds `truth/defects.json` to `batch` for a textile scene, with each frame's view of
/// the defects; returns its file name (none for other objects).
fn add_defects(
    batch: &mut Batch,
    sim: &Simulator,
    frames: Vec<FrameDefects>,
    out: &Path,
) -> Result<Option<String>, Error> {
    let Object::Textile { fabric, .. } = &sim.scene().object else {
        return Ok(None);
    };
    let strip = sim.strip();
    let truth = DefectsTruth {
        fabric: fabric.clone(),
        class: textile::FABRICS
            .iter()
            .position(|f| f.name == fabric)
            .ok_or_else(|| Error::Invalid(format!("unknown fabric {fabric:?}")))?,
        strip_origin_mm: strip.origin_mm,
        mm_per_px: sim.scene().sensor.mm_per_px,
        defects: strip.defects.clone(),
        frames,
    };
    let file = "truth/defects.json";
    let json = to_json(&truth)? + "\n";
    batch.add_bytes(&out.join(file), json.as_bytes())?;
    Ok(Some(file.to_string()))
}

/// `value` as indented JSON.
fn to_json(value: &impl Serialize) -> Result<String, Error> {
    serde_json::to_string_pretty(value).map_err(|e| Error::Invalid(e.to_string()))
}

/// Renders every frame of `sim` into `out` with its ground truth and manifest; `progress`
/// counts the frames rendered.
pub fn write(sim: &Simulator, out: &Path, progress: &dyn Progress) -> Result<Manifest, Error> {
    std::fs::create_dir_all(out.join("truth")).map_err(WriteError::io("create", out))?;
    // Every file is written before any is moved into place, the manifest last: a failure
    // leaves the previous run's files as they were, never a mix.
    let mut batch = Batch::new();
    let scene = sim.scene();
    let mmpp = scene.sensor.mm_per_px;
    let mut frames = Vec::with_capacity(sim.frames());
    let sheet_every = sim.frames().div_ceil(6).max(1);
    let mut sheet = Vec::new();
    let mut frame_defects = Vec::new();
    let simulating = format!("simulating {}", scene.name);
    progress.start(&simulating, Some(sim.frames() as u64), "frames");
    for k in 0..sim.frames() {
        let f = sim.frame(k);
        if k % sheet_every == sheet_every / 2 || sim.frames() == 1 {
            sheet.push(f.image.clone());
        }
        let file = format!("frame_{k:04}.png");
        f.image.add_png(&mut batch, &out.join(&file))?;
        frame_defects.push(FrameDefects {
            file: file.clone(),
            defects: sim.defects_in(&f),
        });
        frames.push(FrameRecord {
            file,
            offset_mm: f.offset_mm,
            actual_offset_mm: f.actual_offset_mm,
            strip_row: sim.strip_row_of_top(f.offset_mm),
            actual_strip_row: sim.strip_row_of_top(f.actual_offset_mm),
            actual_sideways_px: f.sideways_px,
            stages: f.stages.clone(),
        });
        progress.advance_to(k as u64 + 1);
    }
    progress.finish();
    let strip = sim.strip();
    let regions = add_truth(&mut batch, sim, strip, out)?;
    let defects_json = add_defects(&mut batch, sim, frame_defects, out)?;
    contact_sheet(&sheet).add_png(&mut batch, &out.join("contact_sheet.png"))?;
    if scene.has(super::Effect::Rgb) {
        // The lights the frames were rendered with: what `rollfuse depth` needs.
        let lights = rollfuse_depth::lights::Lights {
            mm_per_px: mmpp,
            red: scene.lights.red,
            green: scene.lights.green,
            blue: scene.lights.blue,
            gains: [1.0; 3],
        };
        let toml = lights
            .to_toml()
            .map_err(|e| Error::Invalid(e.to_string()))?;
        batch.add_bytes(&out.join("lights.toml"), toml.as_bytes())?;
    }
    let manifest = Manifest {
        format: FRAMES_FORMAT.to_string(),
        scene: scene.name.clone(),
        seed: scene.seed,
        effects: scene.effects.clone(),
        color: if scene.has(super::Effect::Rgb) {
            "rgb"
        } else {
            "gray"
        }
        .to_string(),
        image_size: Some([scene.sensor.width_px, scene.sensor.height_px]),
        mm_per_px: Some(mmpp),
        frames,
        truth: Some(Truth {
            height_npy: "truth/height.npy".into(),
            height_png: "truth/height.png".into(),
            ideal_png: "truth/ideal.png".into(),
            strip_size: [strip.width, strip.rows],
            strip_origin_mm: strip.origin_mm,
            regions,
            contact_sheet_png: "contact_sheet.png".into(),
            defects_json,
        }),
        scene_file: Some(scene.clone()),
    };
    let json = to_json(&manifest)?;
    batch.add_bytes(&out.join("manifest.json"), (json + "\n").as_bytes())?;
    batch.commit()?;
    remove_stale_frames(out, sim.frames())?;
    Ok(manifest)
}
