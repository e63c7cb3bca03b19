//! Settings named in words — `db2`, `no-wavelet`, `per-frame` — one table a setting, read
//! by the command line and by the Python package alike, so a value has one name
//! everywhere and a new value is one line of its table.
//!
//! ```
//! use rollfuse::names::{Named, parse};
//! use rollfuse::core::Wavelet;
//!
//! assert_eq!(Wavelet::from_name("db2"), Some(Wavelet::Db2));
//! assert_eq!(Wavelet::Haar.name(), "haar");
//! let err = parse::<Wavelet>("wavelet", "db4").unwrap_err();
//! assert_eq!(err, "wavelet must be one of 'haar', 'db2', got 'db4'");
//! ```

use crate::eval::metrics::StripAxis;
use crate::fullres::Precision;
use rollfuse_core::protocol::{NormMode, WaveletId};
use rollfuse_core::{Ablation, LlWeighting, Wavelet};

/// A setting whose values have names.
pub trait Named: Copy + PartialEq + Send + Sync + 'static {
    /// Every value: its name, a line of help, the value — in the order help lists them.
    const VALUES: &'static [(&'static str, &'static str, Self)];

    /// The value's name.
    fn name(self) -> &'static str {
        Self::VALUES
            .iter()
            .find(|(_, _, v)| *v == self)
            .map_or("?", |(name, _, _)| name)
    }

    /// The value of that name, if there is one.
    fn from_name(name: &str) -> Option<Self> {
        Self::VALUES
            .iter()
            .find(|(n, _, _)| *n == name)
            .map(|(_, _, v)| *v)
    }
}

/// The value named `value` of the setting `what`, or a one-line error that lists the
/// names it could be.
pub fn parse<T: Named>(what: &str, value: &str) -> Result<T, String> {
    T::from_name(value).ok_or_else(|| {
        let names: Vec<String> = T::VALUES.iter().map(|(n, _, _)| format!("'{n}'")).collect();
        format!("{what} must be one of {}, got '{value}'", names.join(", "))
    })
}

impl Named for Wavelet {
    const VALUES: &'static [(&'static str, &'static str, Self)] = &[
        ("haar", "Haar", Wavelet::Haar),
        ("db2", "Daubechies-4", Wavelet::Db2),
    ];
}

impl Named for WaveletId {
    const VALUES: &'static [(&'static str, &'static str, Self)] = &[
        ("haar", "Haar", WaveletId::Haar),
        ("db2", "Daubechies-4", WaveletId::Db2),
    ];
}

impl Named for Ablation {
    const VALUES: &'static [(&'static str, &'static str, Self)] = &[
        ("none", "the full method", Ablation::None),
        (
            "no-wavelet",
            "pixel average instead of the wavelet transform",
            Ablation::NoWavelet,
        ),
        (
            "single-ll",
            "keep one image's LL band instead of the mean",
            Ablation::SingleLl,
        ),
        (
            "max-high",
            "max-|coefficient| instead of saliency weights",
            Ablation::MaxHigh,
        ),
    ];
}

impl Named for LlWeighting {
    const VALUES: &'static [(&'static str, &'static str, Self)] = &[
        (
            "paper",
            "the paper's pairwise mean: the newest frame weighs ½",
            LlWeighting::Paper,
        ),
        (
            "equal",
            "every frame weighs 1/n: independent of order",
            LlWeighting::Equal,
        ),
    ];
}

impl Named for NormMode {
    const VALUES: &'static [(&'static str, &'static str, Self)] = &[
        (
            "per-tile",
            "saliency normalized by each tile's own maximum",
            NormMode::PerTile,
        ),
        (
            "per-frame",
            "by the maximum over the rows of the frame its tiles come from",
            NormMode::PerFrame,
        ),
    ];
}

impl Named for Precision {
    const VALUES: &'static [(&'static str, &'static str, Self)] = &[
        (
            "f32",
            "f32 (the host's full-resolution path)",
            Precision::F32,
        ),
        (
            "fixed",
            "the MCU's integer path on 8-bit data (16-bit input is rounded to 8 bits)",
            Precision::Fixed,
        ),
    ];
}

impl Named for StripAxis {
    const VALUES: &'static [(&'static str, &'static str, Self)] = &[
        (
            "rows",
            "bands of rows: along the belt, the direction contact depth varies",
            StripAxis::Rows,
        ),
        (
            "columns",
            "bands of columns: across the belt",
            StripAxis::Columns,
        ),
    ];
}

#[cfg(test)]
mod tests {
    use super::*;

    fn round_trips<T: Named + std::fmt::Debug>() {
        for &(name, _, value) in T::VALUES {
            assert_eq!(value.name(), name);
            assert_eq!(T::from_name(name), Some(value));
        }
        let names: std::collections::BTreeSet<_> = T::VALUES.iter().map(|v| v.0).collect();
        assert_eq!(names.len(), T::VALUES.len(), "a name given twice");
    }

    #[test]
    fn every_value_has_one_name_and_back() {
        round_trips::<Wavelet>();
        round_trips::<WaveletId>();
        round_trips::<Ablation>();
        round_trips::<LlWeighting>();
        round_trips::<NormMode>();
        round_trips::<Precision>();
        round_trips::<StripAxis>();
    }

    /// The names `Literal` lists for Python's type checkers in the package's stub.
    fn stub_literal(stub: &str, alias: &str) -> Vec<String> {
        let line = stub
            .lines()
            .find(|l| l.starts_with(&format!("{alias} = Literal[")))
            .unwrap_or_else(|| panic!("the stub has no `{alias} = Literal[…]`"));
        line.split('"')
            .skip(1)
            .step_by(2)
            .map(str::to_string)
            .collect()
    }

    #[test]
    fn the_python_stub_names_the_values_the_tables_do() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../python/rollfuse/_rollfuse.pyi"
        );
        let stub = std::fs::read_to_string(path).unwrap();
        fn names<T: Named>() -> Vec<String> {
            T::VALUES.iter().map(|v| v.0.to_string()).collect()
        }
        assert_eq!(stub_literal(&stub, "Wavelet"), names::<Wavelet>());
        assert_eq!(stub_literal(&stub, "Ablation"), names::<Ablation>());
        assert_eq!(stub_literal(&stub, "Precision"), names::<Precision>());
        assert_eq!(stub_literal(&stub, "LlWeighting"), names::<LlWeighting>());
    }
}
