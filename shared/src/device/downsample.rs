//! Camera frames to downsampled 8-bit luma.

use crate::protocol::PixelFormat;
use crate::{Dims, Error};

/// Luma of one pixel at byte offset `at` of a row.
#[inline(always)]
fn luma(row: &[u8], x: usize, format: PixelFormat) -> u32 {
    match format {
        PixelFormat::Gray8 => row.get(x).map_or(0, |&v| u32::from(v)),
        // Y0 U Y1 V: the Y of pixel x is byte 2x.
        PixelFormat::Yuyv => row.get(2 * x).map_or(0, |&v| u32::from(v)),
        PixelFormat::Rgb565 => {
            let lo = row.get(2 * x).map_or(0, |&v| u32::from(v));
            let hi = row.get(2 * x + 1).map_or(0, |&v| u32::from(v));
            let v = lo | hi << 8;
            let (r5, g6, b5) = (v >> 11, (v >> 5) & 0x3f, v & 0x1f);
            // Expand to 8 bits by repeating the top bits, then BT.601 luma in Q8.
            let (r, g, b) = (r5 << 3 | r5 >> 2, g6 << 2 | g6 >> 4, b5 << 3 | b5 >> 2);
            (77 * r + 150 * g + 29 * b + 128) >> 8
        }
    }
}

/// The size of a `width × height` frame downsampled by `factor` (the last
/// `width % factor` columns and `height % factor` rows are dropped).
pub fn downsampled_dims(width: usize, height: usize, factor: usize) -> Result<Dims, Error> {
    if !matches!(factor, 1 | 2 | 4) {
        return Err(Error::InvalidParameter { name: "downsample" });
    }
    Dims::new(width / factor, height / factor)
}

/// Downsamples a `width × height` camera frame in `format` by `factor` (1, 2 or 4): each
/// output pixel is the rounded mean luma of a `factor × factor` box. Writes the packed
/// result to `out` and returns its size.
pub fn downsample(
    src: &[u8],
    format: PixelFormat,
    (width, height): (usize, usize),
    factor: usize,
    out: &mut [u8],
) -> Result<Dims, Error> {
    let dims = downsampled_dims(width, height, factor)?;
    let row_bytes = width * format.bytes_per_pixel();
    let needed = row_bytes * height;
    if src.len() < needed {
        return Err(Error::BufferTooSmall {
            which: "camera frame",
            needed,
            got: src.len(),
        });
    }
    dims.check_buffer("downsampled frame", out.len())?;
    let (w, area) = (dims.width(), (factor * factor) as u32);
    for (y, out_row) in out.chunks_exact_mut(w).take(dims.height()).enumerate() {
        let rows = src.chunks_exact(row_bytes).skip(y * factor).take(factor);
        // Sum each box's rows into the output row, then divide once.
        let mut sums = [0u32; 64];
        for (x0, out_chunk) in (0..w)
            .step_by(sums.len())
            .zip(out_row.chunks_mut(sums.len()))
        {
            sums.fill(0);
            for row in rows.clone() {
                for (k, s) in sums.iter_mut().take(out_chunk.len()).enumerate() {
                    let sx = (x0 + k) * factor;
                    *s += (sx..sx + factor).map(|x| luma(row, x, format)).sum::<u32>();
                }
            }
            for (o, &s) in out_chunk.iter_mut().zip(&sums) {
                *o = ((s + area / 2) / area) as u8;
            }
        }
    }
    Ok(dims)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boxes_average_and_round() {
        let src: [u8; 16] = core::array::from_fn(|i| i as u8 * 10);
        let mut out = [0u8; 4];
        let d = downsample(&src, PixelFormat::Gray8, (4, 4), 2, &mut out).unwrap();
        assert_eq!((d.width(), d.height()), (2, 2));
        // (0 + 10 + 40 + 50) / 4 = 25.
        assert_eq!(out, [25, 45, 105, 125]);
        let mut one = [0u8; 1];
        downsample(&src, PixelFormat::Gray8, (4, 4), 4, &mut one).unwrap();
        assert_eq!(one, [75]);
    }

    #[test]
    fn luma_from_rgb565_and_yuyv() {
        // White, black, pure green in RGB565 little-endian.
        let rgb = [0xff, 0xff, 0x00, 0x00, 0xe0, 0x07];
        let mut out = [0u8; 3];
        downsample(&rgb, PixelFormat::Rgb565, (3, 1), 1, &mut out).unwrap();
        assert_eq!(out, [255, 0, 149]);
        let yuyv = [10, 128, 30, 128];
        let mut out = [0u8; 1];
        downsample(&yuyv, PixelFormat::Yuyv, (2, 2), 2, &mut out).unwrap_err();
        downsample(
            &[10, 128, 30, 128, 50, 1, 70, 2],
            PixelFormat::Yuyv,
            (2, 2),
            2,
            &mut out,
        )
        .unwrap();
        assert_eq!(out, [40]);
    }

    #[test]
    fn bad_sizes_are_errors() {
        let mut out = [0u8; 4];
        assert!(downsample(&[0; 15], PixelFormat::Gray8, (4, 4), 2, &mut out).is_err());
        assert!(downsample(&[0; 16], PixelFormat::Gray8, (4, 4), 3, &mut out).is_err());
        assert!(downsample(&[0; 16], PixelFormat::Gray8, (4, 4), 1, &mut out).is_err());
        assert!(downsample(&[0; 16], PixelFormat::Gray8, (1, 16), 2, &mut out).is_err());
    }
}
