//! `rollfuse eval`: the analogues of the paper's Table II (ablations) and Table III (single
//! frame, fusion of 3/4/6 frames, time splicing) on simulated standardized samples.
//!
//! Per scene: the middle frame is the single-image baseline. Fusions and the splice use
//! consecutive frames around it, placed by their commanded belt offsets, and every result is
//! measured over the middle frame's footprint against the ideal contact image of the same
//! belt rows (the simulator's ground truth, standing in for the paper's optical image).

use super::report::{Report, measure};
use crate::eval::metrics::StripAxis;
use crate::fullres::align::Offset;
use crate::fullres::{Placed, Precision, fuse_mosaic, splice};
use crate::image::{PixelLimit, Planes};
use crate::sim::{Scene, Simulator};
use anyhow::{Context, ensure};
use rollfuse_core::{Ablation, FuseConfig, LlWeighting};

/// One row of a table: a method on a scene, and its figures.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Row {
    /// Scene name.
    pub scene: String,
    /// Method (e.g. "fusion of 4", "single image").
    pub method: String,
    /// The figures.
    pub report: Report,
}

/// The frames of a scene as the camera delivers them (8-bit), their canvas rows (strip
/// row of each frame's top row), the ideal image and the strip's regions.
pub(crate) struct Acquisition {
    pub frames: Vec<Planes>,
    pub rows: Vec<i64>,
    pub ideal: Planes,
    /// Region name and mask (strip rows × width, 255 inside).
    pub regions: Vec<(String, Vec<u8>)>,
}

/// Renders every frame of `scene`, rounded to 8 bits as a camera would.
pub(crate) fn acquire(scene: &Scene) -> anyhow::Result<Acquisition> {
    let sim = Simulator::new(scene)?;
    let mut frames = Vec::new();
    let mut rows = Vec::new();
    for k in 0..sim.frames() {
        let f = sim.frame(k);
        let bytes = f.image.to_u8();
        let c = f.image.planes.len();
        let planes = (0..c)
            .map(|ci| {
                bytes
                    .iter()
                    .skip(ci)
                    .step_by(c)
                    .map(|&v| f32::from(v))
                    .collect()
            })
            .collect();
        frames.push(Planes {
            width: f.image.width,
            height: f.image.height,
            planes,
        });
        rows.push(sim.strip_row_of_top(f.offset_mm).round() as i64);
    }
    Ok(Acquisition {
        frames,
        rows,
        ideal: sim.ideal(),
        regions: sim.strip().regions.clone(),
    })
}

/// Rows `top..top + h` of an image (all columns).
pub(crate) fn crop_rows(img: &Planes, top: usize, h: usize) -> anyhow::Result<Planes> {
    Ok(img.crop(top, 0, h, img.width)?)
}

/// The figures of the paper's evaluation for one scene.
pub fn evaluate_scene(scene: &Scene, base: &FuseConfig, strips: usize) -> anyhow::Result<Vec<Row>> {
    evaluate_acquired(scene, &acquire(scene)?, base, strips)
}

/// [`evaluate_scene`] on frames already rendered from `scene` by [`acquire`].
pub(crate) fn evaluate_acquired(
    scene: &Scene,
    acq: &Acquisition,
    base: &FuseConfig,
    strips: usize,
) -> anyhow::Result<Vec<Row>> {
    let n = acq.frames.len();
    ensure!(
        n >= 7,
        "scene {} has {n} frames; the evaluation needs at least 7",
        scene.name
    );
    // The middle frame, with two frames before it and three after (fusion of 6).
    let m = (n - 1) / 2;
    let h = acq.frames[m].height;
    let reference = crop_rows(
        &acq.ideal,
        usize::try_from(acq.rows[m]).context("frame above the strip")?,
        h,
    )?;
    // Frames first..=last placed by motion; the result cropped to frame m's footprint.
    let over = |first: usize,
                last: usize,
                how: &dyn Fn(&[Placed]) -> crate::fullres::Result<Planes>|
     -> anyhow::Result<Planes> {
        let placed: Vec<Placed> = (first..=last)
            .map(|k| Placed {
                image: &acq.frames[k],
                at: Offset {
                    dy: acq.rows[k],
                    dx: 0,
                },
            })
            .collect();
        let out = how(&placed)?;
        let top = acq.rows[first..=last].iter().min().copied().unwrap_or(0);
        crop_rows(&out, (acq.rows[m] - top) as usize, h)
    };
    let fuse =
        |cfg: FuseConfig| move |p: &[Placed]| fuse_mosaic(p, &cfg, Precision::F32, PixelLimit::OWN);
    let row = |method: &str, img: &Planes| -> anyhow::Result<Row> {
        Ok(Row {
            scene: scene.name.clone(),
            method: method.to_string(),
            report: measure(img, Some(&reference), strips, StripAxis::Rows)?,
        })
    };
    let mut rows = vec![row("single image", &acq.frames[m])?];
    for count in [3usize, 4, 6] {
        let first = m + 1 - count.div_ceil(2);
        let img = over(first, first + count - 1, &fuse(*base))?;
        rows.push(row(&format!("fusion of {count}"), &img)?);
    }
    let equal = FuseConfig {
        ll_weighting: LlWeighting::Equal,
        ..*base
    };
    rows.push(row(
        "fusion of 4, equal LL weights",
        &over(m - 1, m + 2, &fuse(equal))?,
    )?);
    rows.push(row(
        "time splicing (6 frames)",
        &over(m - 2, m + 3, &|p| splice(p, 4, PixelLimit::OWN))?,
    )?);
    for (name, ablation) in [
        ("ablation: no wavelet (4)", Ablation::NoWavelet),
        ("ablation: single LL (4)", Ablation::SingleLl),
        ("ablation: max-|high| (4)", Ablation::MaxHigh),
    ] {
        let cfg = FuseConfig { ablation, ..*base };
        rows.push(row(name, &over(m - 1, m + 2, &fuse(cfg))?)?);
    }
    Ok(rows)
}

/// The rows as a Markdown table, with the change of each fusion against the single image.
pub fn markdown(rows: &[Row]) -> String {
    let mut out = String::from(
        "| scene | method | IE | IE_std | MS-SSIM | MS-SSIM_std | IE vs single | IE_std vs single | MS-SSIM vs single |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let single = rows
            .iter()
            .find(|s| s.scene == r.scene && s.method == "single image");
        let rel = |a: f64, b: f64| format!("{:+.1} %", 100.0 * (a - b) / b);
        let (d_ie, d_std, d_ms) = match single {
            Some(s) if s.method != r.method => (
                rel(r.report.ie, s.report.ie),
                rel(r.report.ie_std, s.report.ie_std),
                format!(
                    "{:+.4}",
                    r.report.ms_ssim.unwrap_or(0.0) - s.report.ms_ssim.unwrap_or(0.0)
                ),
            ),
            _ => ("".into(), "".into(), "".into()),
        };
        out.push_str(&format!(
            "| {} | {} | {:.4} | {:.4} | {:.4} | {:.4} | {d_ie} | {d_std} | {d_ms} |\n",
            r.scene,
            // A `|` in a name (e.g. "max-|high|") would end the cell.
            r.method.replace('|', "\\|"),
            r.report.ie,
            r.report.ie_std,
            r.report.ms_ssim.unwrap_or(f64::NAN),
            r.report.ms_ssim_std.unwrap_or(f64::NAN),
        ));
    }
    out
}

/// The rows as CSV.
pub fn csv(rows: &[Row]) -> String {
    let mut out = String::from("scene,method,ie,ie_std,ms_ssim,ms_ssim_std\n");
    for r in rows {
        out.push_str(&format!(
            "{},{},{:.6},{:.6},{:.6},{:.6}\n",
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
