//! The float fusion paths, for full-resolution work on the host (also at `crate::float`):
//! the shared driver with the integer path's lifting steps — the same boundary rule,
//! coefficient placement and weights — run in exact floating-point arithmetic, float
//! saliency and float weights, on any size; in `f32` (the host's working path) or `f64`
//! (the reference the trade-off study measures against). The paths differ only by the
//! integer path's rounding.

use super::config::{FuseConfig, LlWeight};
use super::driver::{
    Arith, ImagePair, Join, Samples, ScratchLayout, Sequential, fuse_pair_checked, rings_len,
};
use crate::lifting::{self, LevelBounds, Lift};
use crate::saliency::ll_gain_q16;
use crate::saliency::{SaliencyNorm, map_neighbourhood, row_and_neighbours};
use crate::{Dims, Error, MAX_LEVELS, Wavelet, simd};

mod sealed {
    pub trait Sealed {}
    impl Sealed for f32 {}
    impl Sealed for f64 {}
}

/// A float sample type the float fusion runs in: `f32` or `f64`.
#[allow(private_bounds)] // `Lift` is the lifting's internal seam; users see only the two impls.
pub trait Float:
    sealed::Sealed
    + Lift
    + Default
    + Send
    + Sync
    + PartialOrd
    + core::ops::Mul<Output = Self>
    + core::ops::Div<Output = Self>
{
    /// 0.
    const ZERO: Self;
    /// ½.
    const HALF: Self;
    /// 1.
    const ONE: Self;
    /// 4.
    const FOUR: Self;
    /// The largest sample magnitude accepted: [`MAX_SAMPLE_F32`] for both types.
    const MAX_SAMPLE: Self;
    /// From an `f64` (rounded to nearest for `f32`).
    fn from_f64(v: f64) -> Self;
    /// `|self|`.
    fn abs(self) -> Self;
    /// Whether neither infinite nor NaN.
    fn is_finite(self) -> bool;
    /// `eˣ − 1` for `x` in `0..=1`.
    fn expm1_unit(self) -> Self;
}

impl Float for f32 {
    const ZERO: Self = 0.0;
    const HALF: Self = 0.5;
    const ONE: Self = 1.0;
    const FOUR: Self = 4.0;
    const MAX_SAMPLE: Self = MAX_SAMPLE_F32;
    #[inline(always)]
    fn from_f64(v: f64) -> Self {
        v as f32
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32::abs(self)
    }
    #[inline(always)]
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }
    #[inline(always)]
    fn expm1_unit(self) -> Self {
        expm1_unit(self)
    }
}

impl Float for f64 {
    const ZERO: Self = 0.0;
    const HALF: Self = 0.5;
    const ONE: Self = 1.0;
    const FOUR: Self = 4.0;
    const MAX_SAMPLE: Self = MAX_SAMPLE_F32 as f64;
    #[inline(always)]
    fn from_f64(v: f64) -> Self {
        v
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f64::abs(self)
    }
    #[inline(always)]
    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }
    /// libm's: the reference path takes no shortcut.
    fn expm1_unit(self) -> Self {
        libm::expm1(self)
    }
}

impl<T: Float> Arith for T {
    /// None: floats need no saturation, the bounds are only passed along.
    fn inverse_bounds(_: Wavelet, _: u8) -> [LevelBounds; MAX_LEVELS as usize] {
        [LevelBounds::default(); MAX_LEVELS as usize]
    }

    /// `1 / max`.
    type SaliencyScale = T;

    fn saliency_scale(
        buf: &[T],
        dims: Dims,
        norm: SaliencyNorm,
        wavelet: Wavelet,
        level: u8,
        known_max: Option<T>,
    ) -> Option<T> {
        let max = match norm {
            SaliencyNorm::Local => match known_max {
                Some(max) => max,
                None => {
                    let mut scan = LaplacianScan::new();
                    for y in 0..dims.height() {
                        scan.row(buf, dims, y);
                    }
                    // A deeper level's input is the transform's own LL band: no check.
                    scan.largest()
                }
            },
            // The LL band's DC gain per level, as on the integer path.
            SaliencyNorm::Reference(r) => {
                let gain = T::from_f64(ll_gain_q16(wavelet) as f64 / 65536.0);
                (1..level).fold(T::from_f64(f64::from(r)), |m, _| m * gain)
            }
        };
        (max > T::ZERO && max.is_finite()).then(|| T::ONE / max)
    }

    #[inline(always)]
    fn saliency_row(inv: T, rows: [&[T]; 3], out: &mut [T]) {
        let Some(out) = out.get_mut(..rows[1].len()) else {
            return;
        };
        // Sal/255 = |∇²I| / max, saturated at 1 for a Reference maximum.
        map_neighbourhood(rows, out, laplacian);
        // A pass of its own: a plain map over the row, which vectorizes.
        for v in out.iter_mut() {
            let x = *v * inv;
            *v = (if x < T::ONE { x } else { T::ONE }).expm1_unit();
        }
    }

    #[inline(always)]
    fn weight(s1: T, s2: T) -> T {
        let total = s1 + s2;
        if total > T::ZERO { s1 / total } else { T::HALF }
    }

    #[inline(always)]
    fn blend(h1: T, h2: T, w1: T) -> T {
        w1 * h1 + (T::ONE - w1) * h2
    }

    #[inline(always)]
    fn mix(a: T, b: T, w: LlWeight) -> T {
        let w = T::from_f64(f64::from(w.0) / 32768.0);
        (T::ONE - w) * a + w * b
    }

    #[inline(always)]
    fn abs_ge(a: T, b: T) -> bool {
        a.abs() >= b.abs()
    }

    fn check_samples(buf: &[T], dims: Dims) -> Result<(), Error> {
        dims.check_buffer("image", buf.len())?;
        dims.rows(buf).try_for_each(check_row)
    }

    /// One pass for both: each sample is checked as the centre of its Laplacian, which
    /// saves a read of each image from memory.
    fn check_and_max(buf: &[T], dims: Dims, local_max: bool) -> Result<Option<T>, Error> {
        if !local_max {
            return Self::check_samples(buf, dims).map(|()| None);
        }
        dims.check_buffer("image", buf.len())?;
        checked_laplacian_max(buf, dims).map(Some)
    }
}

simd::kernel! {
    /// Checks every sample of the region (its buffer checked) and returns its largest
    /// `|∇²I|`, in one pass.
    fn checked_laplacian_max<T: Float>(buf: &[T], dims: Dims) -> Result<T, Error> {
        let mut scan = LaplacianScan::new();
        for y in 0..dims.height() {
            scan.row(buf, dims, y);
        }
        scan.finish()
    }
}

/// A scan for the largest `|∇²I|` of a region that checks each sample on the way (as the
/// centre of its own Laplacian). It keeps 32 lanes of each and reduces them once, at the
/// end: as four vectors of eight `f32` the maxima run as four independent chains instead
/// of one waiting on each `max`'s latency, and no row pays for a reduction, a store of its
/// Laplacian or a second read for the check (those took 10 % more instructions over the
/// compare frames, callgrind, and the per-row reduction weighs most on narrow images).
struct LaplacianScan<T> {
    /// The largest `|∇²I|` per lane.
    max: [T; 32],
    /// Per lane, 0 while every sample seen was in range.
    out_of_range: [T; 32],
}

impl<T: Float> LaplacianScan<T> {
    fn new() -> Self {
        Self {
            max: [T::ZERO; 32],
            out_of_range: [T::ZERO; 32],
        }
    }

    /// Takes one centre sample and its `|∇²I|` into a lane.
    #[inline(always)]
    fn take(max: &mut T, out_of_range: &mut T, centre: T, lap: T) {
        // NaN fails both comparisons: never a maximum, always out of range. Selects, not
        // conditional stores: those compiled to masked stores to memory, twice as slow.
        *max = if lap > *max { lap } else { *max };
        let in_range = centre.abs() <= T::MAX_SAMPLE;
        *out_of_range = if in_range { *out_of_range } else { T::ONE };
    }

    /// Takes in row `y` of the region (nothing if `buf` does not hold it), with the
    /// mirrored neighbours of [`row_and_neighbours`].
    #[inline(always)]
    fn row(&mut self, buf: &[T], dims: Dims, y: usize) {
        let Some((up, mid, down)) = row_and_neighbours(buf, dims, y) else {
            return;
        };
        let (max0, oor0) = (&mut self.max[0], &mut self.out_of_range[0]);
        let w = mid.len();
        let at = |r: &[T], x: usize| r.get(x).copied().unwrap_or(T::ZERO);
        // The borders, the left and right neighbours mirrored (both the centre for w = 1).
        for x in [0, w - 1].into_iter().take(w.min(2)) {
            let side = at(
                mid,
                if w == 1 {
                    0
                } else if x == 0 {
                    1
                } else {
                    w - 2
                },
            );
            let c = at(mid, x);
            let lap = laplacian(c, [at(up, x), at(down, x), side, side]);
            Self::take(max0, oor0, c, lap);
        }
        // The interior, 32 samples at a time, then 8, then one by one.
        let (u, d) = (interior(up, 1, w), interior(down, 1, w));
        let (l, c, r) = (
            interior(mid, 0, w),
            interior(mid, 1, w),
            interior(mid, 2, w),
        );
        let rest = Self::blocks(&mut self.max, &mut self.out_of_range, [u, d, l, c, r]);
        let rest = match (
            self.max.first_chunk_mut(),
            self.out_of_range.first_chunk_mut(),
        ) {
            (Some(max), Some(oor)) => Self::blocks::<8>(max, oor, rest),
            _ => rest,
        };
        let (max0, oor0) = (&mut self.max[0], &mut self.out_of_range[0]);
        let [u, d, l, c, r] = rest;
        for ((((&u, &d), &l), &c), &r) in u.iter().zip(d).zip(l).zip(c).zip(r) {
            Self::take(max0, oor0, c, laplacian(c, [u, d, l, r]));
        }
    }

    /// Takes in whole blocks of `N` interior samples, given as their up, down, left,
    /// centre and right neighbours (equally long), into `N` lanes; returns what is left.
    #[inline(always)]
    fn blocks<'a, const N: usize>(
        max: &mut [T; N],
        out_of_range: &mut [T; N],
        [u, d, l, c, r]: [&'a [T]; 5],
    ) -> [&'a [T]; 5] {
        let ((u_n, u_rest), (d_n, d_rest)) = (u.as_chunks::<N>(), d.as_chunks::<N>());
        let ((l_n, l_rest), (c_n, c_rest), (r_n, r_rest)) =
            (l.as_chunks::<N>(), c.as_chunks::<N>(), r.as_chunks::<N>());
        for ((((u, d), l), c), r) in u_n.iter().zip(d_n).zip(l_n).zip(c_n).zip(r_n) {
            let lanes = max.iter_mut().zip(out_of_range.iter_mut());
            let samples = u.iter().zip(d).zip(l).zip(c).zip(r);
            for ((max, oor), ((((&u, &d), &l), &c), &r)) in lanes.zip(samples) {
                Self::take(max, oor, c, laplacian(c, [u, d, l, r]));
            }
        }
        [u_rest, d_rest, l_rest, c_rest, r_rest]
    }

    /// The largest `|∇²I|`, or the error for a sample out of range.
    fn finish(self) -> Result<T, Error> {
        if self.out_of_range.iter().any(|&v| v != T::ZERO) {
            return Err(Error::InvalidParameter {
                name: "sample (NaN, infinite or beyond ±1e9)",
            });
        }
        Ok(self.largest())
    }

    /// The largest `|∇²I|`, whatever the samples' range.
    fn largest(&self) -> T {
        self.max
            .iter()
            .fold(T::ZERO, |m, &v| if v > m { v } else { m })
    }
}

/// The `w − 2` samples of `row` from `from` on (empty for `w < 3`): the interior's
/// centres (`from` 1) or left (0) or right (2) neighbours.
#[inline(always)]
fn interior<T>(row: &[T], from: usize, w: usize) -> &[T] {
    row.get(from..(from + w).saturating_sub(2)).unwrap_or(&[])
}

/// Refuses a row holding a sample the float paths cannot take.
#[inline(always)]
fn check_row<T: Float>(row: &[T]) -> Result<(), Error> {
    // No early exit, so the scan vectorizes; NaN fails the comparison.
    let in_range = row
        .iter()
        .fold(true, |ok, v| ok & (v.abs() <= T::MAX_SAMPLE));
    if in_range {
        Ok(())
    } else {
        Err(Error::InvalidParameter {
            name: "sample (NaN, infinite or beyond ±1e9)",
        })
    }
}

/// `|∇²I|` from a centre and its four neighbours.
#[inline(always)]
fn laplacian<T: Float>(c: T, [up, down, left, right]: [T; 4]) -> T {
    (up + down + left + right - T::FOUR * c).abs()
}

/// `eˣ − 1` for `x` in `0..=1`: `x·q(x)` with `q` a degree-5 polynomial fitted to the
/// minimax error on `0..=1` (by iteratively reweighted least squares), in Horner form.
/// Evaluated in `f32` it is within 2.3e-7 of the exact value there (test
/// `expm1_unit_matches_libm`), as close as `f32` rounding of the sums allows. The Taylor
/// series to the same accuracy needs degree 9 and twice the operations; a per-pixel libm
/// `exp` took a fifth of a fuse step.
#[inline(always)]
fn expm1_unit(x: f32) -> f32 {
    const Q: [f32; 6] = [
        0.999_997_3,
        0.500_051,
        0.166_343_4,
        0.042_600_867,
        0.006_990_449,
        0.002_298_695,
    ];
    // Horner from the top coefficient (0·x + c is c for every finite x, but the
    // compiler may not assume that of floats and would keep the product).
    let (&top, rest) = Q.split_last().unwrap_or((&0.0, &[]));
    let mut acc = top;
    for &c in rest.iter().rev() {
        acc = acc * x + c;
    }
    x * acc
}

/// The largest sample magnitude the float paths accept: far beyond any image (16-bit data
/// is 65535), far enough below `f32::MAX` that Laplacians and sums stay finite.
pub const MAX_SAMPLE_F32: f32 = 1e9;

/// Scratch length (in samples) that [`fuse_pair`] and [`fuse_pair_with`] need for `dims`:
/// as on the integer path ([`crate::fusion::fuse_scratch_len`]), plus a second transform
/// line so both images can be worked on at once, and (except on the Cortex-M7) two rows per
/// image that let each image's saliency be taken in its transform's sweep.
pub fn fuse_scratch_len(dims: Dims) -> usize {
    let rings = if SALIENCY_IN_SWEEP {
        rings_len(dims)
    } else {
        0
    };
    super::integer::fuse_scratch_len(dims) + lifting::scratch_len(dims) + rings
}

/// Whether each image's saliency is taken in its forward transform's sweep (from a ring of
/// row copies) rather than in a pass of its own. The sweep saves a read of each image where
/// memory is slow next to the arithmetic (the hosts' caches); the Cortex-M7 reads its
/// tightly coupled RAM in a cycle and would only pay for the ring's copies (the `f32` fuse
/// step costs more instructions per tile pixel with it: `bash tests/mcu-bench/run.sh`).
const SALIENCY_IN_SWEEP: bool = !cfg!(target_arch = "arm");

/// One float fuse step (`f32` or `f64`) on the `dims` region of `a` and `b`: the fused image replaces `a`,
/// `b` is used as work space. Any size from 1 up, as on the integer path; samples must be
/// finite with `|x| ≤` [`MAX_SAMPLE_F32`].
///
/// ```
/// use rollfuse_core::{Dims, FuseConfig, float};
/// use rollfuse_core::fusion::LlWeight;
///
/// let dims = Dims::new(9, 7)?; // any size
/// let sharp: Vec<f32> = (0..63).map(|i| if i % 9 == 4 { 200.0 } else { 20.0 }).collect();
/// let flat = vec![20.0f32; 63];
/// let (mut a, mut b) = (flat.clone(), sharp.clone());
/// let mut scratch = vec![0.0; float::fuse_scratch_len(dims)];
/// float::fuse_pair(&mut a, &mut b, dims, &FuseConfig::default(), LlWeight::HALF, &mut scratch)?;
/// // The fused image replaces `a`: the line only `b` has is kept (its detail taken from
/// // `b`, the low bands averaged).
/// assert!(a[4] > 60.0 && a[0] < a[4]);
/// # Ok::<(), rollfuse_core::Error>(())
/// ```
pub fn fuse_pair<T: Float>(
    a: &mut [T],
    b: &mut [T],
    dims: Dims,
    cfg: &FuseConfig,
    ll_weight: LlWeight,
    scratch: &mut [T],
) -> Result<(), Error> {
    fuse_pair_with(&Sequential, a, b, dims, cfg, ll_weight, scratch)
}

/// [`fuse_pair`] with each level's two independent halves (saliency and transform of
/// each image) run through `join`, e.g. on two threads. The result does not depend on it.
pub fn fuse_pair_with<T: Float>(
    join: &impl Join,
    a: &mut [T],
    b: &mut [T],
    dims: Dims,
    cfg: &FuseConfig,
    ll_weight: LlWeight,
    scratch: &mut [T],
) -> Result<(), Error> {
    let images = ImagePair { a, b, dims };
    fuse_pair_checked(
        images,
        cfg,
        ll_weight,
        scratch,
        layout(Samples::Unchecked),
        join,
    )
}

/// [`fuse_pair`] on two images whose samples the caller converted from bytes (0–255): in
/// range by construction, so they are not checked again. The result is [`fuse_pair`]'s.
pub(crate) fn fuse_pair_of_bytes<T: Float>(
    images: ImagePair<'_, T>,
    cfg: &FuseConfig,
    ll_weight: LlWeight,
    scratch: &mut [T],
) -> Result<(), Error> {
    let how = layout(Samples::FromBytes);
    fuse_pair_checked(images, cfg, ll_weight, scratch, how, &Sequential)
}

/// The `f32` path's scratch: a second transform line (so `join` can work on both images
/// at once), the saliency rings where the sweep computes saliency.
fn layout(samples: Samples) -> (ScratchLayout, Samples) {
    let layout = ScratchLayout {
        second_line: true,
        rings: SALIENCY_IN_SWEEP,
        table: false,
    };
    (layout, samples)
}

#[cfg(test)]
mod tests {
    use super::{expm1_unit, fuse_pair, fuse_pair_of_bytes, fuse_scratch_len};
    use crate::fusion::{ImagePair, LlWeight};
    use crate::{Dims, FuseConfig, SaliencyNorm, Wavelet};
    use std::{vec, vec::Vec};

    /// Images of bytes fuse as any images do: skipping the check changes nothing, with the
    /// maxima taken (local normalization) or given (a reference), at every depth.
    #[test]
    fn images_of_bytes_fuse_as_any_images_do() {
        let dims = Dims::new(40, 24).unwrap();
        let bytes = |k: usize| -> Vec<f32> {
            (0..dims.pixels())
                .map(|i| f32::from(((i * 37 + k * 11) ^ (i / 40 * 5)) as u8))
                .collect()
        };
        let mut scratch = vec![0f32; fuse_scratch_len(dims)];
        for (norm, levels, wavelet) in [
            (SaliencyNorm::Local, 1, Wavelet::Db2),
            (SaliencyNorm::Reference(180), 2, Wavelet::Db2),
            (SaliencyNorm::Reference(0), 3, Wavelet::Haar),
        ] {
            let cfg = FuseConfig {
                norm,
                levels,
                wavelet,
                ..FuseConfig::default()
            };
            let (mut a, mut b) = (bytes(0), bytes(1));
            fuse_pair(&mut a, &mut b, dims, &cfg, LlWeight::HALF, &mut scratch).unwrap();
            let (mut c, mut d) = (bytes(0), bytes(1));
            let images = ImagePair {
                a: &mut c,
                b: &mut d,
                dims,
            };
            fuse_pair_of_bytes(images, &cfg, LlWeight::HALF, &mut scratch).unwrap();
            assert!(a == c && a != bytes(0), "{cfg:?}");
        }
    }

    #[test]
    fn expm1_unit_matches_libm() {
        let worst = (0..=10_000)
            .map(|i| {
                let x = i as f32 / 10_000.0;
                (expm1_unit(x) as f64 - libm::expm1(x as f64)).abs()
            })
            .fold(0.0, f64::max);
        assert!(worst < 3e-7, "max error {worst}");
    }
}
