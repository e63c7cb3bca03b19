//! Writing a height map: `.npy` (float32 mm, for numpy), a colour-mapped PNG with a scale
//! bar, and a binary PLY point cloud.

//!
//! Each writer adds its file to a [`Batch`]: the caller commits the files together.

use super::DepthMap;
use rollfuse_io::files::{Batch, PngLayout, WriteError, add_png};
use rollfuse_io::font;
use std::io::Write;
use std::path::Path;

/// Writes `DEPTH.npy`: float32 heights in mm, `height × width`, row-major.
pub fn write_npy(depth: &DepthMap, batch: &mut Batch, path: &Path) -> Result<(), WriteError> {
    let bytes = rollfuse_io::npy::encode_f32(&depth.height_mm, depth.height, depth.width)?;
    batch.add_bytes(path, &bytes)
}

/// The colour of a height in `0..=max` (viridis; below 0 is the bottom colour).
fn colour(v: f32, max: f32) -> [u8; 3] {
    let t = f64::from((v / max).clamp(0.0, 1.0));
    let c = colorous::VIRIDIS.eval_continuous(t);
    [c.r, c.g, c.b]
}

/// Writes the picture: heights in viridis from 0 to the largest height, and at the right a
/// scale bar labelled with both ends in mm.
pub fn write_png(depth: &DepthMap, batch: &mut Batch, path: &Path) -> Result<(), WriteError> {
    let (w, h) = (depth.width, depth.height);
    let max = depth
        .height_mm
        .iter()
        .copied()
        .fold(0f32, f32::max)
        .max(1e-3);
    let top = format!("{max:.2} MM");
    let zoom = if h >= 160 { 2 } else { 1 };
    let label_w = (top.len() * 6 + 1) * zoom;
    let (bar_x, bar_w) = (w + 8, 10);
    let cw = bar_x + bar_w + 6 + label_w;
    let ch = h.max(9 * zoom * 3);
    let mut img = image::RgbImage::from_pixel(cw as u32, ch as u32, image::Rgb([255, 255, 255]));
    for y in 0..h {
        for x in 0..w {
            img.put_pixel(
                x as u32,
                y as u32,
                image::Rgb(colour(depth.height_mm[y * w + x], max)),
            );
        }
    }
    // The bar: top = max, bottom = 0.
    for y in 0..ch {
        let v = max * (1.0 - y as f32 / (ch - 1).max(1) as f32);
        for x in bar_x..bar_x + bar_w {
            img.put_pixel(x as u32, y as u32, image::Rgb(colour(v, max)));
        }
    }
    let label_x = bar_x + bar_w + 6;
    draw_text(&mut img, &top, label_x, 0, zoom);
    draw_text(&mut img, "0 MM", label_x, ch - 7 * zoom, zoom);
    add_png(batch, path, img.as_raw(), (cw, ch), PngLayout::Rgb8)
}

/// Draws `text` in the 5×7 font, black, scaled by `zoom`, with its top-left at `(x, y)`.
fn draw_text(img: &mut image::RgbImage, text: &str, x: usize, y: usize, zoom: usize) {
    for (k, c) in text.chars().enumerate() {
        for row in 0..7 {
            for col in 0..5 {
                if !font::cell(c, col, row) {
                    continue;
                }
                for dy in 0..zoom {
                    for dx in 0..zoom {
                        let (px, py) = (x + (k * 6 + col) * zoom + dx, y + row * zoom + dy);
                        if px < img.width() as usize && py < img.height() as usize {
                            img.put_pixel(px as u32, py as u32, image::Rgb([0, 0, 0]));
                        }
                    }
                }
            }
        }
    }
}

/// Writes a binary little-endian PLY with one vertex per pixel: `x` along columns, `y`
/// along rows, `z` the height, all in mm.
pub fn write_ply(depth: &DepthMap, batch: &mut Batch, path: &Path) -> Result<(), WriteError> {
    batch.add(path, |out| {
        ply(depth, out).map_err(|e| WriteError::io("write", path)(e).into())
    })
}

fn ply(depth: &DepthMap, out: &mut impl Write) -> std::io::Result<()> {
    let n = depth.width * depth.height;
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\ncomment rollfuse depth, mm\nelement vertex {n}\n\
         property float x\nproperty float y\nproperty float z\nend_header\n"
    )?;
    let k = depth.mm_per_px as f32;
    for (i, &z) in depth.height_mm.iter().enumerate() {
        let (x, y) = ((i % depth.width) as f32 * k, (i / depth.width) as f32 * k);
        for v in [x, y, z] {
            out.write_all(&v.to_le_bytes())?;
        }
    }
    Ok(())
}
