//! Image geometry: validated sizes, strides and the in-place subband layout.
//!
//! # Subband layout (in place, rows interleaved)
//!
//! One level on a `w × h` region splits each row into `⌈w/2⌉` low then `⌊w/2⌋` high
//! samples (left and right halves), then lifts each column in place: row pair
//! `(2l, 2l + 1)` becomes row `l` of the column-low band and row `l` of the column-high
//! band where it stands. The region then holds
//!
//! ```text
//!  ┌────────────┬────────────┐   row 0:  LL row 0 | HL row 0
//!  │ LL         │ HL         │   row 1:  LH row 0 | HH row 0
//!  │ LH         │ HH         │   row 2:  LL row 1 | HL row 1
//!  │ LL         │ HL         │   …
//!  │ LH         │ HH         │   (an odd height's last row: LL | HL)
//!  └────────────┴────────────┘
//! ```
//!
//! LL is `⌈w/2⌉ × ⌈h/2⌉` (low along rows, low along columns), HL `⌊w/2⌋ × ⌈h/2⌉` (high
//! along rows), LH `⌈w/2⌉ × ⌊h/2⌋` (high along columns), HH `⌊w/2⌋ × ⌊h/2⌋`. The first
//! letter names the filter along rows (x), the second along columns (y); the paper's
//! "horizontal, vertical, diagonal" details are HL, LH, HH. The next level works on LL:
//! the left `⌈w/2⌉` samples of the even rows, a region with twice the stride
//! ([`Dims::low_band`]). A side of length 1 is left as it is (it is all low band).
//!
//! Rows are interleaved rather than stacked (Mallat's layout: LL over LH) so that the
//! column pass can lift in place, a whole row at a time, in one sweep down the image: no
//! copy of column blocks into scratch and back, and no strided access, which on a
//! 1280×960 `f32` image made the column pass twice as slow as the row pass.

use crate::Error;
use crate::limits::{MAX_DIMENSION, MAX_LEVELS};

/// A validated 2-D region of a row-major buffer: `width × height` elements, rows `stride`
/// elements apart.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Dims {
    width: usize,
    height: usize,
    stride: usize,
}

impl Dims {
    /// A tightly packed `width × height` image (stride = width).
    pub fn new(width: usize, height: usize) -> Result<Self, Error> {
        Self::with_stride(width, height, width)
    }

    /// A `width × height` region whose rows are `stride` elements apart.
    pub fn with_stride(width: usize, height: usize, stride: usize) -> Result<Self, Error> {
        if width == 0 || height == 0 {
            return Err(Error::ZeroSize);
        }
        if width > MAX_DIMENSION || height > MAX_DIMENSION || stride > 4 * MAX_DIMENSION {
            return Err(Error::TooLarge);
        }
        if stride < width {
            return Err(Error::StrideTooSmall { stride, width });
        }
        Ok(Self {
            width,
            height,
            stride,
        })
    }

    /// Width in elements.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in rows.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Distance between rows, in elements.
    pub fn stride(&self) -> usize {
        self.stride
    }

    /// Number of pixels, `width × height`.
    pub fn pixels(&self) -> usize {
        self.width * self.height
    }

    /// The smallest buffer length that holds this region: `(height − 1) · stride + width`.
    pub fn buffer_len(&self) -> usize {
        (self.height - 1) * self.stride + self.width
    }

    /// Fails with [`Error::BufferTooSmall`] unless `len` holds the region.
    pub fn check_buffer(&self, which: &'static str, len: usize) -> Result<(), Error> {
        let needed = self.buffer_len();
        if len < needed {
            return Err(Error::BufferTooSmall {
                which,
                needed,
                got: len,
            });
        }
        Ok(())
    }

    /// The low band (LL) after one level: `⌈w/2⌉ × ⌈h/2⌉`, the left part of the even rows
    /// (twice the stride; see the layout above). A region one row high keeps its stride.
    pub fn low_band(&self) -> Self {
        Self {
            width: self.width.div_ceil(2),
            height: self.height.div_ceil(2),
            stride: if self.height > 1 {
                2 * self.stride
            } else {
                self.stride
            },
        }
    }

    /// The most levels this size allows: level `k` needs the low band of level `k − 1`
    /// to have at least two samples along one side. A 1×1 image allows none.
    pub fn max_levels(&self) -> u8 {
        let mut d = *self;
        let mut levels = 0;
        while levels < MAX_LEVELS && d.width.max(d.height) >= 2 {
            levels += 1;
            d = d.low_band();
        }
        levels
    }

    /// Checks `levels` is in `1..=4` and allowed for this size.
    pub fn check_levels(&self, levels: u8) -> Result<(), Error> {
        if levels == 0 || levels > MAX_LEVELS {
            return Err(Error::LevelsOutOfRange { levels });
        }
        let max = self.max_levels();
        if levels > max {
            return Err(Error::LevelsTooDeep { levels, max });
        }
        Ok(())
    }

    /// Index of element `(x, y)`.
    #[inline]
    pub(crate) fn at(&self, x: usize, y: usize) -> usize {
        y * self.stride + x
    }

    /// Row `y` of the region in `buf` (`width` elements), or `None` if `buf` ends before
    /// it does.
    #[inline]
    pub(crate) fn row<'b, T>(&self, buf: &'b [T], y: usize) -> Option<&'b [T]> {
        let start = self.at(0, y);
        buf.get(start..start + self.width)
    }

    /// Row `y` of the region in `buf`, mutable; `None` if `buf` ends before it does.
    #[inline]
    pub(crate) fn row_mut<'b, T>(&self, buf: &'b mut [T], y: usize) -> Option<&'b mut [T]> {
        let start = self.at(0, y);
        buf.get_mut(start..start + self.width)
    }

    /// The region's rows in `buf`, top to bottom (fewer if `buf` is shorter than
    /// [`Self::buffer_len`]).
    #[inline]
    pub(crate) fn rows<'b, T>(&self, buf: &'b [T]) -> impl Iterator<Item = &'b [T]> {
        let dims = *self;
        (0..self.height).map_while(move |y| dims.row(buf, y))
    }

    /// [`Self::rows`], mutable.
    #[inline]
    pub(crate) fn rows_mut<'b, T>(&self, buf: &'b mut [T]) -> impl Iterator<Item = &'b mut [T]> {
        let (w, h) = (self.width, self.height);
        buf.chunks_mut(self.stride.max(1))
            .take(h)
            .map_while(move |row| row.get_mut(..w))
    }

    /// The error for a `which` buffer of `got` elements that does not hold the region.
    pub(crate) fn too_small(&self, which: &'static str, got: usize) -> Error {
        Error::BufferTooSmall {
            which,
            needed: self.buffer_len(),
            got,
        }
    }
}

/// A strided line inside a buffer: `len` elements, `step` apart, from `start`. The
/// transforms work on whole rows and column blocks ([`Dims::row`]); the tests walk lines
/// one by one as the reference.
#[cfg(test)]
#[derive(Clone, Copy)]
pub(crate) struct Line {
    pub start: usize,
    pub step: usize,
    pub len: usize,
}

#[cfg(test)]
impl Line {
    /// The row `y` of a region.
    pub fn row(dims: Dims, y: usize) -> Self {
        Self {
            start: dims.at(0, y),
            step: 1,
            len: dims.width(),
        }
    }

    /// The column `x` of a region (the transforms lift columns in blocks).
    pub fn column(dims: Dims, x: usize) -> Self {
        Self {
            start: x,
            step: dims.stride(),
            len: dims.height(),
        }
    }

    /// Buffer positions of the line's elements, in order.
    pub fn positions(self) -> impl Iterator<Item = usize> {
        (0..self.len).map(move |k| self.start + k * self.step)
    }
}

/// Whole-sample symmetric extension: maps any index onto `0..n` by mirroring about the
/// first and last samples (`… 2 1 | 0 1 2 … n−1 | n−2 …`). A sequence of length 1 is
/// extended as a constant. `n` must be at least 1.
#[inline]
pub(crate) fn mirror(i: isize, n: usize) -> usize {
    // Most calls are inside the sequence; keep the division for the rest.
    if i >= 0 && (i as usize) < n {
        return i as usize;
    }
    if n <= 1 {
        return 0;
    }
    let period = 2 * (n as isize - 1);
    let m = i.rem_euclid(period);
    (if m >= n as isize { period - m } else { m }) as usize
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    #[test]
    fn mirror_is_whole_sample_symmetric() {
        let n = 4;
        let got: [usize; 12] = core::array::from_fn(|k| mirror(k as isize - 4, n));
        assert_eq!(got, [2, 3, 2, 1, 0, 1, 2, 3, 2, 1, 0, 1]);
        assert_eq!(mirror(-7, 1), 0);
        assert_eq!(mirror(5, 2), 1);
    }

    #[test]
    fn max_levels_follow_the_halving_rule() {
        let levels = |w, h| Dims::new(w, h).unwrap().max_levels();
        assert_eq!(levels(1, 1), 0);
        assert_eq!(levels(2, 1), 1);
        assert_eq!(levels(1, 3), 2);
        assert_eq!(levels(5, 5), 3);
        assert_eq!(levels(9, 1), 4);
        assert_eq!(levels(640, 480), 4);
    }

    #[test]
    fn rows_stop_where_the_buffer_does() {
        let d = Dims::with_stride(2, 3, 3).unwrap();
        let buf = [0, 1, 9, 3, 4, 9, 6, 7];
        assert_eq!(d.row(&buf, 1), Some(&[3, 4][..]));
        assert_eq!(
            d.rows(&buf).collect::<std::vec::Vec<_>>(),
            [[0, 1], [3, 4], [6, 7]]
        );
        assert_eq!(d.rows(&buf[..7]).count(), 2);
        assert_eq!(d.row(&buf[..7], 2), None);
        let mut buf = buf;
        if let Some(row) = d.row_mut(&mut buf, 2) {
            row[1] = 8;
        }
        assert_eq!(buf[7], 8);
        assert!(d.row_mut(&mut buf[..6], 2).is_none());
        assert_eq!(
            d.too_small("image", 7),
            Error::BufferTooSmall {
                which: "image",
                needed: 8,
                got: 7
            }
        );
    }

    #[test]
    fn bad_geometry_is_refused() {
        assert_eq!(Dims::new(0, 3), Err(Error::ZeroSize));
        assert_eq!(
            Dims::with_stride(4, 2, 3),
            Err(Error::StrideTooSmall {
                stride: 3,
                width: 4
            })
        );
        assert_eq!(Dims::new(MAX_DIMENSION + 1, 1), Err(Error::TooLarge));
        let d = Dims::new(4, 4).unwrap();
        assert_eq!(
            d.check_levels(0),
            Err(Error::LevelsOutOfRange { levels: 0 })
        );
        assert_eq!(
            Dims::new(2, 2).unwrap().check_levels(2),
            Err(Error::LevelsTooDeep { levels: 2, max: 1 })
        );
    }
}
