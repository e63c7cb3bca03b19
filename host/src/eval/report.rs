//! The paper's figures for one image — IE and MS-SSIM against a reference, and their
//! spread over strips (eqs. 8–9) — as `rollfuse metrics` prints them and the evaluations
//! tabulate them.

use super::metrics::{
    Gray, StripAxis, WINDOW, entropy, gray_normalize, ms_ssim_raw, ms_ssim_scales, population_std,
    strip, strip_ranges,
};
use crate::image::Planes;
use anyhow::{bail, ensure};

/// The paper's figures for one image.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Report {
    /// Information entropy of the gray-normalized image, bits.
    pub ie: f64,
    /// Population std of the per-strip IE.
    pub ie_std: f64,
    /// MS-SSIM against the reference (both gray-normalized).
    pub ms_ssim: Option<f64>,
    /// Population std of the per-strip MS-SSIM.
    pub ms_ssim_std: Option<f64>,
    /// Per-strip IE.
    pub strip_ie: Vec<f64>,
    /// Per-strip MS-SSIM.
    pub strip_ms_ssim: Option<Vec<f64>>,
}

/// The gray version of an image (mean of its channels), gray-normalized to 0..=255.
pub fn normalized_gray(img: &Planes) -> anyhow::Result<Gray> {
    let n = img.planes.len() as f64;
    let gray: Vec<f64> = (0..img.width * img.height)
        .map(|i| img.planes.iter().map(|p| p[i] as f64).sum::<f64>() / n)
        .collect();
    Gray::new(img.width, img.height, gray_normalize(&gray))
}

fn to_u8(g: &Gray) -> Vec<u8> {
    g.data
        .iter()
        .map(|v| v.round().clamp(0.0, 255.0) as u8)
        .collect()
}

/// Information entropy of the gray-normalized image, bits (the paper's IE).
pub fn ie(image: &Planes) -> anyhow::Result<f64> {
    Ok(ie_of(&normalized_gray(image)?))
}

/// IE of an already gray-normalized image (or strip of one).
fn ie_of(g: &Gray) -> f64 {
    entropy(&to_u8(g))
}

/// MS-SSIM of `image` against `reference`, both gray-normalized; they must have one size.
pub fn ms_ssim(image: &Planes, reference: &Planes) -> anyhow::Result<f64> {
    same_size(image, reference)?;
    ms_ssim_raw(&normalized_gray(image)?, &normalized_gray(reference)?)
}

fn same_size(image: &Planes, reference: &Planes) -> anyhow::Result<()> {
    if (reference.width, reference.height) != (image.width, image.height) {
        bail!(
            "the reference is {}×{} but the image is {}×{}",
            reference.width,
            reference.height,
            image.width,
            image.height
        );
    }
    Ok(())
}

/// Whether MS-SSIM fits `image` and each of its strips `ranges` (of `len` along `axis`):
/// [`ms_ssim_scales`], the rule MS-SSIM itself applies, checked before any work.
fn ms_ssim_fits(
    image: &Planes,
    len: usize,
    ranges: &[std::ops::Range<usize>],
    axis: StripAxis,
) -> anyhow::Result<()> {
    let (w, h) = (image.width, image.height);
    ensure!(
        ms_ssim_scales(w, h) > 0,
        "MS-SSIM needs at least {WINDOW}×{WINDOW} pixels; the image is {w}×{h}"
    );
    let thinnest = ranges.iter().map(|r| r.len()).min().unwrap_or(0);
    let (strip_size, unit) = match axis {
        StripAxis::Rows => ((w, thinnest), "rows"),
        StripAxis::Columns => ((thinnest, h), "columns"),
    };
    ensure!(
        ms_ssim_scales(strip_size.0, strip_size.1) > 0,
        "MS-SSIM of each strip needs strips at least {WINDOW} {unit} thick; {len} {unit} in \
         {} strips leave {thinnest}: pass --strips {} or fewer",
        ranges.len(),
        len / WINDOW
    );
    Ok(())
}

/// Measures `image` (and against `reference`), with `strips` strips along `axis`.
pub fn measure(
    image: &Planes,
    reference: Option<&Planes>,
    strips: usize,
    axis: StripAxis,
) -> anyhow::Result<Report> {
    ensure!(strips >= 1, "--strips must be at least 1");
    let len = match axis {
        StripAxis::Rows => image.height,
        StripAxis::Columns => image.width,
    };
    ensure!(
        strips <= len,
        "--strips {strips} is more than the image's {len} {axis:?}"
    );
    let g = normalized_gray(image)?;
    let ranges = strip_ranges(len, strips);
    let strip_ie: Vec<f64> = ranges
        .iter()
        .map(|r| ie_of(&strip(&g, axis, r.clone())))
        .collect();
    let (mut ms, mut strip_ms) = (None, None);
    if let Some(reference) = reference {
        same_size(image, reference)?;
        ms_ssim_fits(image, len, &ranges, axis)?;
        let r = normalized_gray(reference)?;
        ms = Some(ms_ssim_raw(&g, &r)?);
        strip_ms = Some(
            ranges
                .iter()
                .map(|c| ms_ssim_raw(&strip(&g, axis, c.clone()), &strip(&r, axis, c.clone())))
                .collect::<anyhow::Result<Vec<f64>>>()?,
        );
    }
    Ok(Report {
        ie: ie_of(&g),
        ie_std: population_std(&strip_ie),
        ms_ssim: ms,
        ms_ssim_std: strip_ms.as_deref().map(population_std),
        strip_ie,
        strip_ms_ssim: strip_ms,
    })
}
