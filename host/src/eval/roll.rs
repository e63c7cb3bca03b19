//! `rollfuse eval --roll`: whole rolls. Each scene is rolled as a conveyor would: 120
//! frames 0.35 mm apart (7 px at the built-in scenes' scale), the belt's speed varying by
//! ±25 % from frame to frame (commanded) and its position off by up to 2 px (unknown).
//! Four ways to a strip are measured against the ideal contact image of the same belt
//! rows, over every row all of them cover:
//!
//! - **single apex frame**: the middle frame alone, over its own rows (the paper's
//!   single-image baseline; it cannot cover the strip);
//! - **time splicing**: each row from the frame whose apex is nearest, by the commanded
//!   motion, blended over 4 rows at the seams;
//! - **device strip**: the virtual device's fused tiles (the firmware's pipeline at its
//!   default configuration, the camera's full resolution; a downsampled strip would be
//!   brought back to full resolution bilinearly);
//! - **contact-window strip**: `rollfuse fuse` on the roll, aligned by matching
//!   (commanded rows as the prediction), fused over the contact window.

use super::report::measure;
use super::tables::{Row, acquire, crop_rows};
use crate::eval::metrics::StripAxis;
use crate::fullres::align::Offset;
use crate::fullres::roll::StripInMemory;
use crate::fullres::strip::{StripOptions, fuse_strip};
use crate::fullres::{Placed, splice};
use crate::image::{PixelLimit, Planes};
use crate::link::sim::SimDevice;
use crate::sim::{Effect, Scene, Simulator};
use anyhow::{Context, ensure};

/// Frames of a rolled scene.
pub const ROLL_FRAMES: usize = 120;
/// Belt travel between frames, mm.
pub const ROLL_SPACING_MM: f64 = 0.35;

/// `scene` rolled as a conveyor: [`ROLL_FRAMES`] frames [`ROLL_SPACING_MM`] apart, with
/// `speed` and `jitter` added to its effects.
pub fn rolled(scene: &Scene) -> anyhow::Result<Scene> {
    let mut s = scene.clone();
    s.sensor.frames = ROLL_FRAMES;
    s.sensor.frame_spacing_mm = ROLL_SPACING_MM;
    for e in [Effect::Speed, Effect::Jitter] {
        if !s.has(e) {
            s.effects.insert(0, e);
        }
    }
    s.validate().context("the rolled scene")?;
    Ok(s)
}

/// The virtual device's strip of `scene` at its default configuration, upsampled to camera
/// pixels, the strip row of its first row, and the device's downsampling factor.
fn device_strip(scene: &Scene, sim: &Simulator) -> anyhow::Result<(i64, Planes, usize)> {
    let tmp = std::env::temp_dir().join(format!("rollfuse-eval-roll-{}", std::process::id()));
    let mut device = SimDevice::start(scene)?;
    let d = usize::from(device.default_config().downsample);
    let opts = crate::stream::Options::into_folder(&tmp);
    let result = (|| {
        crate::stream::run(&mut device, &opts, &crate::progress::Silent)?;
        let segments = crate::strip_file::read_segments(&tmp.join("strip.json"))?;
        ensure!(
            segments.len() == 1,
            "the device's strip of {} has {} segments (lost tiles)",
            scene.name,
            segments.len()
        );
        let first = segments[0].first_row;
        let strip = Planes::load(&tmp.join(&segments[0].file), PixelLimit::OWN)?;
        // Device rows count from the first frame's top, in downsampled rows.
        let origin = sim.strip_row_of_top(sim.frame(0).offset_mm).round() as i64;
        Ok((origin + first * d as i64, strip.upsampled(d), d))
    })();
    let _ = std::fs::remove_dir_all(&tmp);
    result
}

/// The whole-roll table for one scene (rolled by [`rolled`] first).
pub fn evaluate_roll(scene: &Scene, strips: usize) -> anyhow::Result<Vec<Row>> {
    let scene = rolled(scene)?;
    let sim = Simulator::new(&scene)?;
    let acq = acquire(&scene)?;
    let commanded: Vec<f64> = (0..sim.frames())
        .map(|k| sim.strip_row_of_top(sim.frame(k).offset_mm))
        .collect();
    let opts = StripOptions::tracked(scene.sensor.roller_geometry(), commanded);
    let (sink, _) = fuse_strip(
        acq.frames.iter().cloned().map(Ok),
        &opts,
        |_, _| Ok(StripInMemory::default()),
        |_| Ok(()),
    )?;
    let host_first = sink.first_row.context("empty strip")?;
    let host = sink.image.context("empty strip")?;
    let placed: Vec<Placed> = acq
        .frames
        .iter()
        .zip(&acq.rows)
        .map(|(image, &dy)| Placed {
            image,
            at: Offset { dy, dx: 0 },
        })
        .collect();
    let spliced = splice(&placed, 4, PixelLimit::OWN)?;
    let splice_first = acq.rows.iter().copied().min().unwrap_or(0);
    let (device_first, device, d) = device_strip(&scene, &sim)?;
    // Rows every strip and the ideal cover.
    let spans = [
        (host_first, host.height),
        (splice_first, spliced.height),
        (device_first, device.height),
        (0, acq.ideal.height),
    ];
    let top = spans.iter().map(|s| s.0).max().unwrap_or(0);
    let end = spans.iter().map(|s| s.0 + s.1 as i64).min().unwrap_or(0);
    ensure!(end > top, "the strips of {} share no rows", scene.name);
    let rows = (end - top) as usize;
    let crop = |img: &Planes, first: i64| crop_rows(img, (top - first) as usize, rows);
    let reference = crop(&acq.ideal, 0)?;
    let row = |method: String, img: &Planes, reference: &Planes| -> anyhow::Result<Row> {
        Ok(Row {
            scene: scene.name.clone(),
            method,
            report: measure(img, Some(reference), strips, StripAxis::Rows)?,
        })
    };
    let m = acq.frames.len() / 2;
    let h = acq.frames[m].height;
    let own = crop_rows(&acq.ideal, usize::try_from(acq.rows[m])?, h)?;
    Ok(vec![
        row(
            format!("single apex frame ({h} rows)"),
            &acq.frames[m],
            &own,
        )?,
        row(
            format!("time splicing, commanded motion ({rows} rows)"),
            &crop(&spliced, splice_first)?,
            &reference,
        )?,
        row(
            match d {
                1 => format!("device strip 1× ({rows} rows)"),
                d => format!("device strip {d}×, upsampled ({rows} rows)"),
            },
            &crop(&device, device_first)?,
            &reference,
        )?,
        row(
            format!("contact-window strip ({rows} rows)"),
            &crop(&host, host_first)?,
            &reference,
        )?,
    ])
}

/// The rows as a Markdown table.
pub fn markdown(rows: &[Row]) -> String {
    let mut out = String::from(
        "| scene | method (rows compared) | IE | IE_std | MS-SSIM | MS-SSIM_std |\n|---|---|---|---|---|---|\n",
    );
    for r in rows {
        out.push_str(&format!(
            "| {} | {} | {:.4} | {:.4} | {:.4} | {:.4} |\n",
            r.scene,
            r.method,
            r.report.ie,
            r.report.ie_std,
            r.report.ms_ssim.unwrap_or(f64::NAN),
            r.report.ms_ssim_std.unwrap_or(f64::NAN)
        ));
    }
    out
}
