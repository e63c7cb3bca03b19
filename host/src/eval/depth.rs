//! `rollfuse eval --depth`: the analogue of the paper's Table IV on the simulated
//! three-sphere scene.
//!
//! The three equal spheres lie along the belt, so in any one frame only the one under
//! the roller's apex is pressed to full depth: the others are shallower, and their
//! reconstructed contact areas and heights are smaller. Three inputs are reconstructed
//! over the middle frame's footprint (the frame with the middle sphere at the apex):
//!
//! - the single middle frame;
//! - the fusion of three frames, one with each sphere at the apex;
//! - the fusion of two frames, the first and last sphere at the apex (the paper's
//!   two-image case).
//!
//! Fusion is the host's f32 path (db2, one level, per channel), frames placed by their
//! commanded offsets. Per sphere: the **area overlap** is the fraction of its footprint
//! (the region mask of the ground truth) where the reconstruction rises above
//! [`AREA_HEIGHT_MM`], and the **peak** is the highest reconstructed point inside it.
//! The table gives each one's standard deviation over the three spheres (population std):
//! the spread the curved gel puts between objects that are in fact the same.

use super::tables::{Acquisition, acquire, crop_rows};
use crate::depth::lights::Lights;
use crate::depth::{DepthMap, reconstruct};
use crate::fullres::align::Offset;
use crate::fullres::{Placed, Precision, fuse_mosaic};
use crate::image::{PixelLimit, Planes};
use crate::sim::Scene;
use anyhow::{Context, ensure};
use rollfuse_core::FuseConfig;

/// A pixel counts as in contact where the reconstruction is above this height.
pub const AREA_HEIGHT_MM: f32 = 0.05;

/// One method's figures.
#[derive(Debug, Clone, serde::Serialize)]
pub struct DepthRow {
    /// "single middle frame", "fusion of 3", "fusion of 2".
    pub method: String,
    /// Frames used.
    pub frames: Vec<usize>,
    /// Area overlap of each sphere, 0..1.
    pub overlap: Vec<f64>,
    /// Peak height of each sphere, mm.
    pub peak_mm: Vec<f64>,
    /// Std of the overlaps.
    pub overlap_std: f64,
    /// Std of the peaks, mm.
    pub peak_std_mm: f64,
    /// The height map.
    #[serde(skip)]
    pub depth: DepthMap,
}

fn std_dev(v: &[f64]) -> f64 {
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / v.len() as f64).sqrt()
}

/// Runs the evaluation on `scene` (an RGB scene with three regions).
pub fn evaluate_depth(scene: &Scene) -> anyhow::Result<Vec<DepthRow>> {
    ensure!(
        scene.has(crate::sim::Effect::Rgb),
        "scene {} is not RGB: depth needs the three LED channels",
        scene.name
    );
    let acq = acquire(scene)?;
    ensure!(
        acq.regions.len() == 3,
        "scene {} has {} regions; the depth table needs three spheres",
        scene.name,
        acq.regions.len()
    );
    let (w, h) = (acq.frames[0].width, acq.frames[0].height);
    let spheres = spheres_along_the_belt(&acq, w);
    let apex: Vec<usize> = spheres
        .iter()
        .map(|s| frame_nearest_apex(&acq, s.0, h))
        .collect();
    let m = apex[1];
    let top = usize::try_from(acq.rows[m]).context("the middle frame lies above the strip")?;
    // The spheres' masks over the middle frame's footprint.
    let masks: Vec<&[u8]> = spheres
        .iter()
        .map(|(_, mask)| {
            mask.get(top * w..(top + h) * w)
                .context("region outside the strip")
        })
        .collect::<anyhow::Result<_>>()?;
    let lights = Lights {
        mm_per_px: scene.sensor.mm_per_px,
        red: scene.lights.red,
        green: scene.lights.green,
        blue: scene.lights.blue,
        gains: [1.0; 3],
    };
    let cases: [(&str, Vec<usize>); 3] = [
        ("single middle frame", vec![m]),
        ("fusion of 3", apex.clone()),
        ("fusion of 2", vec![apex[0], apex[2]]),
    ];
    cases
        .into_iter()
        .map(|(method, frames)| {
            let image = if frames.len() == 1 {
                acq.frames[m].clone()
            } else {
                fused_over(&acq, &frames, m, h)?
            };
            let depth = reconstruct(&image, None, &lights)?;
            let (overlap, peak_mm): (Vec<f64>, Vec<f64>) = masks
                .iter()
                .map(|mask| sphere_figures(mask, &depth))
                .unzip();
            Ok(DepthRow {
                method: method.to_string(),
                overlap_std: std_dev(&overlap),
                peak_std_mm: std_dev(&peak_mm),
                frames,
                overlap,
                peak_mm,
                depth,
            })
        })
        .collect()
}

/// Each sphere's centre row on the strip (strip `w` wide) with its mask, in belt order.
fn spheres_along_the_belt(acq: &Acquisition, w: usize) -> Vec<(f64, &Vec<u8>)> {
    let mut spheres: Vec<(f64, &Vec<u8>)> = acq
        .regions
        .iter()
        .map(|(_, mask)| {
            let (sum, n) = mask
                .iter()
                .enumerate()
                .filter(|(_, m)| **m > 0)
                .fold((0.0, 0usize), |(s, n), (i, _)| (s + (i / w) as f64, n + 1));
            (sum / n.max(1) as f64, mask)
        })
        .collect();
    spheres.sort_by(|a, b| a.0.total_cmp(&b.0));
    spheres
}

/// The frame (`h` rows) whose middle row is nearest strip row `row`.
fn frame_nearest_apex(acq: &Acquisition, row: f64, h: usize) -> usize {
    (0..acq.frames.len())
        .min_by(|&a, &b| {
            let d = |k: usize| (acq.rows[k] as f64 + h as f64 / 2.0 - row).abs();
            d(a).total_cmp(&d(b))
        })
        .unwrap_or(0)
}

/// The fusion of `frames` at their belt rows, over frame `m`'s footprint (`h` rows).
fn fused_over(acq: &Acquisition, frames: &[usize], m: usize, h: usize) -> anyhow::Result<Planes> {
    let placed: Vec<Placed> = frames
        .iter()
        .map(|&k| Placed {
            image: &acq.frames[k],
            at: Offset {
                dy: acq.rows[k],
                dx: 0,
            },
        })
        .collect();
    let out = fuse_mosaic(
        &placed,
        &FuseConfig::default(),
        Precision::F32,
        PixelLimit::OWN,
    )?;
    let first = frames.iter().map(|&k| acq.rows[k]).min().unwrap_or(0);
    crop_rows(&out, (acq.rows[m] - first) as usize, h)
}

/// A sphere's share of its mask reconstructed above [`AREA_HEIGHT_MM`], and its peak, mm.
fn sphere_figures(mask: &[u8], depth: &DepthMap) -> (f64, f64) {
    let inside = mask.iter().filter(|&&v| v > 0).count().max(1);
    let (mut hit, mut peak) = (0usize, 0f32);
    for (&v, &z) in mask.iter().zip(&depth.height_mm) {
        if v > 0 {
            hit += usize::from(z > AREA_HEIGHT_MM);
            peak = peak.max(z);
        }
    }
    (hit as f64 / inside as f64, f64::from(peak))
}

/// The table in Markdown, with each std's change against the first row (the single frame).
pub fn markdown(rows: &[DepthRow]) -> String {
    let mut s = String::from(
        "| method | frames | area overlap per sphere | std of area overlap | peak per sphere (mm) | std of peak (mm) |\n|---|---|---|---|---|---|\n",
    );
    let list = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x:.3}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    // "(−87 %)" after every row but the first.
    let change = |k: usize, v: f64, base: f64| {
        if k == 0 || base <= 0.0 {
            String::new()
        } else {
            format!(" ({:+.0} %)", 100.0 * (v - base) / base)
        }
    };
    let (ob, pb) = rows
        .first()
        .map_or((0.0, 0.0), |b| (b.overlap_std, b.peak_std_mm));
    for (k, r) in rows.iter().enumerate() {
        s += &format!(
            "| {} | {:?} | {} | {:.4}{} | {} | {:.4}{} |\n",
            r.method,
            r.frames,
            list(&r.overlap),
            r.overlap_std,
            change(k, r.overlap_std, ob),
            list(&r.peak_mm),
            r.peak_std_mm,
            change(k, r.peak_std_mm, pb),
        );
    }
    s
}

/// The table as CSV.
pub fn csv(rows: &[DepthRow]) -> String {
    let mut s = String::from(
        "method,frames,overlap_1,overlap_2,overlap_3,overlap_std,peak_1_mm,peak_2_mm,peak_3_mm,peak_std_mm\n",
    );
    for r in rows {
        let frames = r
            .frames
            .iter()
            .map(|k| k.to_string())
            .collect::<Vec<_>>()
            .join(" ");
        let nums = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x:.6}"))
                .collect::<Vec<_>>()
                .join(",")
        };
        s += &format!(
            "{},{},{},{:.6},{},{:.6}\n",
            r.method,
            frames,
            nums(&r.overlap),
            r.overlap_std,
            nums(&r.peak_mm),
            r.peak_std_mm
        );
    }
    s
}
