//! The one error type of the core. Every public function that can be handed a bad
//! argument returns `Result<_, Error>`; nothing in this crate panics on input.

use core::fmt;

/// Why a core operation refused its arguments.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Error {
    /// Width or height is zero.
    ZeroSize,
    /// The row stride is smaller than the width.
    StrideTooSmall {
        /// Requested row stride, in elements.
        stride: usize,
        /// Image width, in elements.
        width: usize,
    },
    /// A side exceeds the largest the core accepts ([`crate::MAX_DIMENSION`]), or the row
    /// stride exceeds four times that.
    TooLarge,
    /// The number of decomposition levels is outside `1..=4`.
    LevelsOutOfRange {
        /// Requested levels.
        levels: u8,
    },
    /// The image is too small for the requested number of levels: at level `k` the low band
    /// of level `k − 1` must still have at least two samples along one side.
    LevelsTooDeep {
        /// Requested levels.
        levels: u8,
        /// The most levels this size allows.
        max: u8,
    },
    /// A buffer is shorter than the geometry needs.
    BufferTooSmall {
        /// Which buffer (a static name, e.g. `"scratch"`).
        which: &'static str,
        /// Elements needed.
        needed: usize,
        /// Elements given.
        got: usize,
    },
    /// A sample handed to a forward transform is outside `±MAX_SAMPLE`
    /// ([`crate::lifting::MAX_SAMPLE`]), the range for which the coefficient bounds are proven.
    SampleOutOfRange,
    /// Two inputs that must agree in size do not.
    SizeMismatch,
    /// A parameter is outside its documented range.
    InvalidParameter {
        /// The parameter's name.
        name: &'static str,
    },
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Error::ZeroSize => f.write_str("image width and height must be at least 1"),
            Error::StrideTooSmall { stride, width } => {
                write!(f, "row stride {stride} is smaller than width {width}")
            }
            Error::TooLarge => write!(
                f,
                "image is larger than {} pixels on a side (or its stride than {})",
                crate::MAX_DIMENSION,
                4 * crate::MAX_DIMENSION
            ),
            Error::LevelsOutOfRange { levels } => {
                write!(f, "levels must be 1..=4, got {levels}")
            }
            Error::LevelsTooDeep { levels, max } => {
                write!(
                    f,
                    "{levels} levels is too deep for this size (at most {max})"
                )
            }
            Error::BufferTooSmall { which, needed, got } => {
                write!(f, "{which} buffer too small: need {needed}, got {got}")
            }
            Error::SampleOutOfRange => write!(
                f,
                "sample outside ±{} (the range the integer transform accepts)",
                crate::lifting::MAX_SAMPLE
            ),
            Error::SizeMismatch => f.write_str("input sizes do not match"),
            Error::InvalidParameter { name } => write!(f, "parameter `{name}` is out of range"),
        }
    }
}

impl core::error::Error for Error {}
