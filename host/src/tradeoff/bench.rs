//! The Cortex-M7 bench's results (`tests/mcu-bench/run.sh` writes them): instructions per
//! frame of the device pipeline for every configuration, from the `pipeline` rows of its
//! CSV, and the build of the bench binary that measured them.

use super::setup::Setup;
use anyhow::{Context, bail};
use std::collections::HashMap;
use std::path::Path;

/// The bench output format this reads (its second line says which it is).
const FORMAT: &str = "2";

/// At 30 frames/s and 480 MHz a frame has 16 M cycles; the pipeline may take 10 % of it.
pub const BUDGET_INSTRUCTIONS: f64 = 1.6e6;

/// One configuration's cost on the MCU.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct McuCost {
    /// Instructions per frame in steady state (QVGA camera frames).
    pub instructions_per_frame: f64,
    /// Whether its buffers fit the firmware's.
    pub fits_ram: bool,
}

impl McuCost {
    /// Whether it fits the time budget ([`BUDGET_INSTRUCTIONS`]) and the firmware's RAM.
    pub fn fits(&self) -> bool {
        self.fits_ram && self.instructions_per_frame <= BUDGET_INSTRUCTIONS
    }
}

/// Key: precision, wavelet, levels, downsample, normalization — as the CSV spells them.
type Key = (String, String, u8, u8, String);

/// The bench's pipeline rows, by configuration.
#[derive(Debug, Clone, Default)]
pub struct McuTable {
    /// The bench binary's id (the first 16 hex digits of its SHA-256), if read.
    pub build: Option<String>,
    rows: HashMap<Key, McuCost>,
}

impl McuTable {
    /// No bench results (the study then reports host time only).
    pub fn empty() -> Self {
        Self::default()
    }

    /// Reads the bench's CSV.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read the MCU bench's results {}", path.display()))?;
        Self::parse(&text).with_context(|| format!("in {}", path.display()))
    }

    /// Parses the bench's CSV: comment lines (`# build ID`, `# rollfuse-mcu-bench format
    /// N`, `# section,name,…` naming the columns), then rows; only `pipeline` rows are kept.
    pub fn parse(text: &str) -> anyhow::Result<Self> {
        let mut table = Self::default();
        let mut columns: Option<Vec<&str>> = None;
        for (n, line) in text.lines().enumerate() {
            if let Some(comment) = line.strip_prefix("# ") {
                if let Some(id) = comment.strip_prefix("build ") {
                    table.build = Some(id.trim().to_string());
                } else if let Some(v) = comment.strip_prefix("rollfuse-mcu-bench format ") {
                    if v.trim() != FORMAT {
                        bail!(
                            "bench format {}, this tool reads format {FORMAT}: re-run the bench",
                            v.trim()
                        );
                    }
                } else if comment.starts_with("section,") {
                    columns = Some(comment.split(',').collect());
                }
                continue;
            }
            let fields: Vec<&str> = line.split(',').collect();
            let Some(cols) = &columns else {
                bail!("line {}: a row before the column names", n + 1);
            };
            if fields.first() != Some(&"pipeline") {
                continue;
            }
            let get = |name: &str| -> anyhow::Result<&str> {
                let i = cols.iter().position(|c| *c == name);
                i.and_then(|i| fields.get(i).copied())
                    .with_context(|| format!("line {}: no {name} column", n + 1))
            };
            let precision = match get("name")?.strip_prefix("frame_") {
                Some(p) => p.to_string(),
                None => bail!("line {}: pipeline row named {:?}", n + 1, get("name")?),
            };
            let num = |name: &str| -> anyhow::Result<f64> {
                get(name)?
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite() && *v >= 0.0)
                    .with_context(|| format!("line {}: {name} is not a count", n + 1))
            };
            let small = |name: &str| -> anyhow::Result<u8> {
                get(name)?
                    .parse()
                    .with_context(|| format!("line {}: {name} is not a small number", n + 1))
            };
            let key = (
                precision,
                get("wavelet")?.to_string(),
                small("levels")?,
                small("downsample")?,
                get("norm")?.to_string(),
            );
            let cost = McuCost {
                instructions_per_frame: num("per_call")?,
                fits_ram: get("fits_firmware_ram")? == "1",
            };
            table.rows.insert(key, cost);
        }
        if columns.is_none() {
            bail!("no header line: is this the MCU bench's CSV?");
        }
        Ok(table)
    }

    /// The cost of `setup`, if the bench measured it.
    pub fn get(&self, setup: &Setup) -> Option<McuCost> {
        let key = (
            setup.precision_name().to_string(),
            setup.wavelet_name().to_string(),
            setup.levels,
            setup.downsample,
            setup.norm_name().to_string(),
        );
        self.rows.get(&key).copied()
    }

    /// How many configurations it holds.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// Whether it holds none.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rollfuse_core::device::Precision;

    const CSV: &str = "# build 0123456789abcdef\n\
        # rollfuse-mcu-bench format 2\n\
        # section,name,wavelet,levels,downsample,norm,pixels,calls,instructions,per_call,per_pixel,observed_per_call,fits_firmware_ram\n\
        calibration,loop,db2,2,2,frame,1,1,400,40.0,40.00,,\n\
        pipeline,frame_fixed,db2,1,1,frame,76800,8,22102840,2762855.0,35.97,1.50,1\n\
        pipeline,frame_f32,haar,1,1,tile,76800,8,42985160,5373145.0,69.96,1.50,0\n";

    #[test]
    fn pipeline_rows_are_read_by_configuration() {
        let t = McuTable::parse(CSV).unwrap();
        assert_eq!(t.build.as_deref(), Some("0123456789abcdef"));
        assert_eq!(t.len(), 2);
        let d = t.get(&Setup::DEFAULT).unwrap();
        assert_eq!(d.instructions_per_frame, 2_762_855.0);
        assert!(d.fits_ram && !d.fits());
        let other = Setup {
            wavelet: rollfuse_core::protocol::WaveletId::Haar,
            levels: 1,
            downsample: 1,
            precision: Precision::F32,
            per_frame: false,
        };
        assert!(!t.get(&other).unwrap().fits_ram);
        assert!(t.get(&Setup { levels: 3, ..other }).is_none());
    }

    #[test]
    fn broken_files_are_clear_errors() {
        assert!(McuTable::parse("hello\n").is_err());
        let old = CSV.replace("format 2", "format 1");
        assert!(
            McuTable::parse(&old)
                .unwrap_err()
                .to_string()
                .contains("format 1")
        );
        let bad = CSV.replace("2762855.0", "lots");
        let err = McuTable::parse(&bad).unwrap_err().to_string();
        assert!(err.contains("per_call"), "{err}");
        let truncated: String =
            CSV.lines().take(5).collect::<Vec<_>>().join("\n") + "\npipeline,frame_fixed,db2";
        assert!(McuTable::parse(&truncated).is_err());
    }
}
