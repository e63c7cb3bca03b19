//! Images on the host: planes of `f32` gray levels, loaded from PNG (and what else the
//! `image` crate was built to read) and saved as PNG or NumPy arrays ([`ImageFormat`]).

use crate::files::{PngLayout, WriteError, write_png};
use std::path::{Path, PathBuf};

/// The largest image read by default, pixels: 32 Mi (e.g. 640 × 52 000 rows), at most
/// 384 MiB as three planes of `f32`. `rollfuse --max-pixels` sets another.
pub const DEFAULT_MAX_PIXELS: u64 = 32 << 20;

/// The largest image read or built (a canvas of frames), pixels: an image over it is
/// refused from its header before it is decoded, a canvas before it is allocated. The
/// command line's `--max-pixels`, Python's `max_pixels`; [`DEFAULT_MAX_PIXELS`] by
/// default.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PixelLimit(pub u64);

impl Default for PixelLimit {
    fn default() -> Self {
        Self(DEFAULT_MAX_PIXELS)
    }
}

impl PixelLimit {
    /// The limit for images the tool made itself — frames and strips the demo and `eval`
    /// render from scenes the simulator has checked, a recorded roll's own strip
    /// segments: the default, whatever `--max-pixels` says of the images a command is
    /// given.
    pub const OWN: PixelLimit = PixelLimit(DEFAULT_MAX_PIXELS);

    /// The limit, pixels.
    pub fn pixels(self) -> u64 {
        self.0
    }

    /// Whether `pixels` fit.
    pub fn admits(self, pixels: u64) -> bool {
        pixels <= self.0
    }
}

/// A window that does not lie inside the image it was to be cut from.
#[derive(Debug, thiserror::Error)]
#[error(
    "crop of {}×{} at row {}, column {} lies outside a {}×{} image",
    window[3], window[2], window[0], window[1], image[1], image[0]
)]
pub struct OutsideImage {
    /// Top row, left column, height and width of the window.
    pub window: [usize; 4],
    /// The image's height and width.
    pub image: [usize; 2],
}

/// Why an image could not be read: the operating system's fault ([`ReadError::Io`]) told
/// apart from the file's ([`ReadError::Decode`], [`ReadError::OverLimit`],
/// [`ReadError::Empty`]).
#[derive(Debug)]
pub enum ReadError {
    /// The file could not be opened or read: missing, not allowed, a device fault.
    Io {
        /// The image's path.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// Not an image this build reads, or its data is damaged.
    Decode {
        /// The image's path.
        path: PathBuf,
        /// What the decoder said.
        source: ::image::ImageError,
    },
    /// Its header gives more pixels than the limit: refused before it is decoded.
    OverLimit {
        /// The image's path.
        path: PathBuf,
        /// Its width and height, pixels.
        size: (u32, u32),
        /// The limit it is over.
        limit: PixelLimit,
    },
    /// It has no pixels.
    Empty {
        /// The image's path.
        path: PathBuf,
    },
}

impl std::fmt::Display for ReadError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Io { path, .. } | Self::Decode { path, .. } => {
                write!(f, "cannot read image {}", path.display())
            }
            Self::OverLimit {
                path,
                size: (w, h),
                limit,
            } => write!(
                f,
                "image {} is {w}×{h} = {} pixels, over the limit of {} (--max-pixels)",
                path.display(),
                u64::from(*w) * u64::from(*h),
                limit.pixels()
            ),
            Self::Empty { path } => write!(f, "image {} is empty", path.display()),
        }
    }
}

impl std::error::Error for ReadError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Io { source, .. } => Some(source),
            Self::Decode { source, .. } => Some(source),
            Self::OverLimit { .. } | Self::Empty { .. } => None,
        }
    }
}

impl ReadError {
    /// The decoder's error about `path`, an I/O error kept as one.
    fn of(path: &Path, e: ::image::ImageError) -> Self {
        let path = path.to_path_buf();
        match e {
            ::image::ImageError::IoError(source) => Self::Io { path, source },
            source => Self::Decode { path, source },
        }
    }
}

/// A reader of `path` that has guessed its format from its first bytes.
fn reader(
    path: &Path,
) -> Result<::image::ImageReader<std::io::BufReader<std::fs::File>>, ReadError> {
    ::image::ImageReader::open(path)
        .and_then(|r| r.with_guessed_format())
        .map_err(|source| ReadError::Io {
            path: path.to_path_buf(),
            source,
        })
}

/// An image file's width and height, from its header alone.
pub fn dimensions(path: &Path) -> Result<(u32, u32), ReadError> {
    reader(path)?
        .into_dimensions()
        .map_err(|e| ReadError::of(path, e))
}

/// Reads `path`'s header, refusing an image over the pixel limit before anything is
/// decoded or allocated.
fn open_within_limit(path: &Path, limit: PixelLimit) -> Result<::image::DynamicImage, ReadError> {
    let (w, h) = dimensions(path)?;
    if !limit.admits(u64::from(w) * u64::from(h)) {
        return Err(ReadError::OverLimit {
            path: path.to_path_buf(),
            size: (w, h),
            limit,
        });
    }
    reader(path)?.decode().map_err(|e| ReadError::of(path, e))
}

/// The formats images are written in, chosen by the output's extension. A new format is a
/// value here, its extension in [`ImageFormat::EXTENSIONS`] and its writer in
/// [`Planes::save`]; every command that writes one image takes it from there.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageFormat {
    /// PNG, 8 or 16 bits a sample, gray or RGB.
    Png,
    /// A NumPy array of `f32` on the 8-bit scale, the fused values unrounded: rows ×
    /// columns (gray) or rows × columns × 3 (RGB).
    Npy,
}

impl ImageFormat {
    /// Each format's file extension.
    pub const EXTENSIONS: &'static [(&'static str, ImageFormat)] =
        &[("png", ImageFormat::Png), ("npy", ImageFormat::Npy)];

    /// The format `target`'s extension names (any case), or an error that lists them.
    pub fn of(target: &Path) -> Result<Self, WriteError> {
        let ext = target.extension().and_then(|e| e.to_str()).unwrap_or("");
        Self::EXTENSIONS
            .iter()
            .find(|(name, _)| name.eq_ignore_ascii_case(ext))
            .map(|&(_, format)| format)
            .ok_or_else(|| {
                let names: Vec<String> = Self::EXTENSIONS
                    .iter()
                    .map(|(n, _)| format!(".{n}"))
                    .collect();
                WriteError::Refused(format!(
                    "{}: images are written as {} files; name it with one of those",
                    target.display(),
                    names.join(" or ")
                ))
            })
    }
}

/// Whether `path` is a PNG whose pixels are palette indices (colour type 3 in its header).
fn is_palette_png(path: &Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; 26];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok_and(|()| {
            head.starts_with(b"\x89PNG\r\n\x1a\n") && &head[12..16] == b"IHDR" && head[25] == 3
        })
}

/// A 16-bit sample on the 8-bit scale of [`Planes`] (times 255/65535).
pub fn from_u16(v: u16) -> f32 {
    f32::from(v) * (255.0 / 65535.0)
}

/// An image as planes of `f32` values on the 8-bit scale (0..=255; 16-bit files are scaled
/// by 255/65535): one plane (gray) or three (red, green, blue), each row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Planes {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// One plane (gray) or three (red, green, blue).
    pub planes: Vec<Vec<f32>>,
}

impl Planes {
    /// The first plane upsampled `d`× bilinearly (sample centres aligned), as a gray
    /// image: the device's downsampled strips brought back to camera pixels.
    pub fn upsampled(&self, d: usize) -> Planes {
        let img = self;
        let (w, h) = (img.width, img.height);
        let (ow, oh) = (w * d, h * d);
        let src = &img.planes[0];
        let at = |x: isize, y: isize| {
            let (x, y) = (x.clamp(0, w as isize - 1), y.clamp(0, h as isize - 1));
            src[y as usize * w + x as usize]
        };
        let mut out = vec![0f32; ow * oh];
        for oy in 0..oh {
            let fy = (oy as f32 + 0.5) / d as f32 - 0.5;
            let (y0, ty) = (fy.floor() as isize, fy - fy.floor());
            for ox in 0..ow {
                let fx = (ox as f32 + 0.5) / d as f32 - 0.5;
                let (x0, tx) = (fx.floor() as isize, fx - fx.floor());
                let top = at(x0, y0) + tx * (at(x0 + 1, y0) - at(x0, y0));
                let bottom = at(x0, y0 + 1) + tx * (at(x0 + 1, y0 + 1) - at(x0, y0 + 1));
                out[oy * ow + ox] = top + ty * (bottom - top);
            }
        }
        Planes {
            width: ow,
            height: oh,
            planes: vec![out],
        }
    }

    /// The gray levels: the one plane of a gray image, the mean of the channels of an RGB
    /// one.
    pub fn gray(&self) -> std::borrow::Cow<'_, [f32]> {
        match self.planes.as_slice() {
            [only] => std::borrow::Cow::Borrowed(only),
            planes => {
                let n = planes.len() as f32;
                std::borrow::Cow::Owned(
                    (0..self.width * self.height)
                        .map(|i| planes.iter().map(|p| p[i]).sum::<f32>() / n)
                        .collect(),
                )
            }
        }
    }

    /// Rounds and clamps to 8-bit: one byte per pixel (gray) or three interleaved (RGB).
    pub fn to_u8(&self) -> Vec<u8> {
        let n = self.width * self.height;
        let c = self.planes.len();
        let mut out = vec![0u8; n * c];
        for (ci, plane) in self.planes.iter().enumerate() {
            for (i, v) in plane.iter().enumerate() {
                out[i * c + ci] = v.round().clamp(0.0, 255.0) as u8;
            }
        }
        out
    }

    /// The `height × width` window with its top-left at `(top, left)`; fails if it does not
    /// lie inside the image.
    pub fn crop(
        &self,
        top: usize,
        left: usize,
        height: usize,
        width: usize,
    ) -> Result<Self, OutsideImage> {
        if top + height > self.height || left + width > self.width {
            return Err(OutsideImage {
                window: [top, left, height, width],
                image: [self.height, self.width],
            });
        }
        let planes = self
            .planes
            .iter()
            .map(|p| {
                p.chunks_exact(self.width)
                    .skip(top)
                    .take(height)
                    .flat_map(|row| &row[left..left + width])
                    .copied()
                    .collect()
            })
            .collect();
        Ok(Self {
            width,
            height,
            planes,
        })
    }

    /// Whether this is an RGB image.
    pub fn is_rgb(&self) -> bool {
        self.planes.len() == 3
    }

    /// Reads a PNG (or any format the `image` crate was built with): 8- or 16-bit, gray or
    /// RGB (an alpha channel is dropped; gray+alpha reads as gray). An image over `limit`
    /// is refused from its header, before it is decoded.
    pub fn load(path: &Path, limit: PixelLimit) -> Result<Self, ReadError> {
        let img = open_within_limit(path, limit)?;
        let (w, h) = (img.width() as usize, img.height() as usize);
        let color = img.color();
        let planes = match (
            color.has_color(),
            color.bytes_per_pixel() / color.channel_count(),
        ) {
            (false, 1) => vec![
                img.to_luma8()
                    .into_raw()
                    .into_iter()
                    .map(f32::from)
                    .collect(),
            ],
            (false, _) => vec![
                img.to_luma16()
                    .into_raw()
                    .into_iter()
                    .map(from_u16)
                    .collect(),
            ],
            (true, depth) => {
                let data: Vec<f32> = if depth == 1 {
                    img.to_rgb8()
                        .into_raw()
                        .into_iter()
                        .map(f32::from)
                        .collect()
                } else {
                    img.to_rgb16()
                        .into_raw()
                        .into_iter()
                        .map(from_u16)
                        .collect()
                };
                let planes: Vec<Vec<f32>> = (0..3)
                    .map(|c| data.iter().skip(c).step_by(3).copied().collect())
                    .collect();
                // A palette of grays (how some tools save gray images) is gray.
                if planes[1..].iter().all(|p| *p == planes[0]) && is_palette_png(path) {
                    planes.into_iter().take(1).collect()
                } else {
                    planes
                }
            }
        };
        if w == 0 || h == 0 {
            return Err(ReadError::Empty {
                path: path.to_path_buf(),
            });
        }
        Ok(Self {
            width: w,
            height: h,
            planes,
        })
    }

    /// Rounds and clamps to 16-bit (the 8-bit scale times 65535/255): one sample per pixel
    /// (gray) or three interleaved (RGB).
    pub fn to_u16(&self) -> Vec<u16> {
        let c = self.planes.len();
        let mut out = vec![0u16; self.width * self.height * c];
        for (ci, plane) in self.planes.iter().enumerate() {
            for (o, v) in out.iter_mut().skip(ci).step_by(c).zip(plane) {
                *o = (v * (65535.0 / 255.0)).round().clamp(0.0, 65535.0) as u16;
            }
        }
        out
    }

    /// Saves as a gray or RGB PNG of 8 or 16 bits per sample (16 keeps the fractions of
    /// gray levels that fusion produces), whole or not at all ([`crate::files`]).
    pub fn save_png_bits(&self, path: &Path, bits: u8) -> Result<(), WriteError> {
        let layout = PngLayout::new(self.planes.len(), bits)?;
        let bytes = match bits {
            8 => self.to_u8(),
            _ => self.to_u16().iter().flat_map(|v| v.to_ne_bytes()).collect(),
        };
        write_png(path, &bytes, (self.width, self.height), layout)
    }

    /// Saves in the format `path`'s extension names ([`ImageFormat::of`]), whole or not at
    /// all: a PNG of `png_bits` (8 or 16) a sample, or a NumPy array of the values as they
    /// are.
    pub fn save(&self, path: &Path, png_bits: u8) -> Result<(), WriteError> {
        match ImageFormat::of(path)? {
            ImageFormat::Png => self.save_png_bits(path, png_bits),
            ImageFormat::Npy => crate::files::write_bytes_atomic(path, &self.to_npy()?),
        }
    }

    /// The image as `.npy` bytes: rows × columns, or rows × columns × 3 interleaved.
    fn to_npy(&self) -> Result<Vec<u8>, WriteError> {
        let (w, h, c) = (self.width, self.height, self.planes.len());
        if c == 1 {
            return crate::npy::encode_f32(&self.planes[0], h, w);
        }
        let interleaved: Vec<f32> = (0..w * h)
            .flat_map(|i| self.planes.iter().map(move |p| p[i]))
            .collect();
        crate::npy::encode_f32_shaped(&interleaved, &[h, w, c])
    }

    /// Saves as an 8-bit gray or RGB PNG, whole or not at all.
    pub fn save_png(&self, path: &Path) -> Result<(), WriteError> {
        self.save_png_bits(path, 8)
    }

    /// An 8-bit gray or RGB PNG into `batch`, moved into place with the rest of it.
    pub fn add_png(&self, batch: &mut crate::files::Batch, path: &Path) -> Result<(), WriteError> {
        let layout = PngLayout::new(self.planes.len(), 8)?;
        crate::files::add_png(
            batch,
            path,
            &self.to_u8(),
            (self.width, self.height),
            layout,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_caller_s_limit_is_its_own() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.png");
        let image = Planes {
            width: 8,
            height: 4,
            planes: vec![vec![7.0; 32]],
        };
        image.save_png(&path).unwrap();
        // Two limits in one process: no setting left behind by the other.
        let refused = Planes::load(&path, PixelLimit(31)).unwrap_err();
        assert!(
            format!("{refused:#}").contains("over the limit of 31"),
            "{refused:#}"
        );
        assert_eq!(Planes::load(&path, PixelLimit(32)).unwrap(), image);
        assert_eq!(Planes::load(&path, PixelLimit::default()).unwrap(), image);
    }

    #[test]
    fn a_read_error_says_whose_fault_it_is() {
        let dir = tempfile::tempdir().unwrap();
        let missing = Planes::load(&dir.path().join("none.png"), PixelLimit::default());
        assert!(matches!(missing, Err(ReadError::Io { source, .. })
            if source.kind() == std::io::ErrorKind::NotFound));
        let junk = dir.path().join("junk.png");
        std::fs::write(&junk, b"\x89PNG\r\n\x1a\nnot really").unwrap();
        let damaged = Planes::load(&junk, PixelLimit::default()).unwrap_err();
        assert!(matches!(damaged, ReadError::Decode { .. }), "{damaged:?}");
        assert!(
            format!("{:#}", anyhow::Error::from(damaged)).starts_with("cannot read image "),
            "the message names the file, then the decoder's reason"
        );
        let image = Planes {
            width: 3,
            height: 2,
            planes: vec![vec![1.0; 6]],
        };
        let path = dir.path().join("a.png");
        image.save_png(&path).unwrap();
        let over = Planes::load(&path, PixelLimit(5)).unwrap_err();
        assert!(
            matches!(over, ReadError::OverLimit { size: (3, 2), .. }),
            "{over:?}"
        );
    }

    #[test]
    fn the_extension_names_the_format_and_npy_keeps_the_values() {
        let dir = tempfile::tempdir().unwrap();
        assert_eq!(
            ImageFormat::of(Path::new("a.PNG")).unwrap(),
            ImageFormat::Png
        );
        assert_eq!(
            ImageFormat::of(Path::new("a.npy")).unwrap(),
            ImageFormat::Npy
        );
        let refused = ImageFormat::of(Path::new("a.tif")).unwrap_err().to_string();
        assert!(refused.contains(".png or .npy"), "{refused}");
        let rgb = Planes {
            width: 2,
            height: 1,
            planes: vec![vec![0.25, 1.0], vec![2.0, 3.0], vec![4.0, 255.5]],
        };
        let path = dir.path().join("rgb.npy");
        rgb.save(&path, 8).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert!(String::from_utf8_lossy(&bytes[..128]).contains("'shape': (1, 2, 3)"));
        let values: Vec<f32> = bytes[bytes.len() - 24..]
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
            .collect();
        assert_eq!(values, [0.25, 2.0, 4.0, 1.0, 3.0, 255.5]);
        assert!(rgb.save(&dir.path().join("rgb.tif"), 8).is_err());
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            1,
            "nothing else written"
        );
    }
}
