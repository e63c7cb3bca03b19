//! The model file: the network's tensors in safetensors, with what is needed to use them
//! in its metadata — the format, the channel widths, the fabric and defect names, the
//! command that trained it and, when it was calibrated, what its training cloth looks like
//! to it ([`super::familiar`]).

use super::familiar::Familiarity;
use super::net::{Net, Widths};
use anyhow::Context;
use burn::module::Module;
use burn::store::{ApplyError, ModuleSnapshot, SafetensorsStore};
use burn::tensor::Device;
use rollfuse_io::files::write_bytes_atomic;
use rollfuse_sim::textile::DefectKind;
use std::collections::HashMap;
use std::path::Path;

/// The metadata's format tag.
pub const FORMAT: &str = "rollfuse-detector-1";
/// Largest model file read, bytes.
pub const MAX_MODEL_BYTES: u64 = 256 << 20;

/// Heatmap score a detection needs, for a model that names none of its own.
pub const DEFAULT_THRESHOLD: f32 = 0.3;

/// Refuses a detection threshold outside 0..=1 (what `--threshold` takes).
pub fn check_threshold(threshold: f32) -> crate::Result<()> {
    rollfuse_io::require!(
        (0.0..=1.0).contains(&threshold),
        "--threshold must be in 0..=1, got {threshold}"
    );
    Ok(())
}

/// What a model file says about its network.
#[derive(Debug, Clone, PartialEq)]
pub struct About {
    /// Channel widths.
    pub widths: Widths,
    /// Fabric class names, in label order.
    pub fabrics: Vec<String>,
    /// How it was made (command line and seed).
    pub made_by: String,
    /// What the training cloth's features look like (none in models made before they
    /// were recorded: such a model cannot tell an unknown fabric).
    pub familiarity: Option<Familiarity>,
    /// The heatmap score its detections need unless told otherwise, where it was chosen
    /// for it (else [`DEFAULT_THRESHOLD`]).
    pub threshold: Option<f32>,
}

impl About {
    fn metadata(&self) -> crate::Result<HashMap<String, String>> {
        let w = self.widths.0.map(|c| c.to_string()).join(",");
        let kinds: Vec<&str> = DefectKind::ALL.iter().map(|k| k.name()).collect();
        let mut meta = HashMap::from([
            ("format".into(), FORMAT.into()),
            ("widths".into(), w),
            ("fabrics".into(), self.fabrics.join(",")),
            ("kinds".into(), kinds.join(",")),
            ("made_by".into(), self.made_by.clone()),
        ]);
        if let Some(f) = &self.familiarity {
            meta.insert("familiarity".into(), f.to_metadata()?);
        }
        if let Some(t) = self.threshold {
            meta.insert("threshold".into(), t.to_string());
        }
        Ok(meta)
    }

    fn parse(meta: &HashMap<String, String>) -> crate::Result<Self> {
        let get = |k: &str| {
            meta.get(k)
                .with_context(|| format!("no `{k}` in its metadata"))
        };
        rollfuse_io::require!(
            get("format")? == FORMAT,
            "its format is {:?}, not {FORMAT:?}",
            get("format")?
        );
        let kinds: Vec<&str> = DefectKind::ALL.iter().map(|k| k.name()).collect();
        rollfuse_io::require!(
            *get("kinds")? == kinds.join(","),
            "it detects {:?}, not {}",
            get("kinds")?,
            kinds.join(",")
        );
        let widths: Vec<usize> = get("widths")?
            .split(',')
            .map(|c| c.trim().parse::<usize>())
            .collect::<Result<_, _>>()
            .context("its widths are not numbers")?;
        let widths: [usize; 4] = widths
            .try_into()
            .map_err(|_| anyhow::anyhow!("it lists other than 4 widths"))?;
        rollfuse_io::require!(
            widths.iter().all(|&c| (1..=1024).contains(&c)),
            "its widths {widths:?} are out of range"
        );
        let fabrics: Vec<String> = get("fabrics")?.split(',').map(str::to_string).collect();
        rollfuse_io::require!(
            (1..=1000).contains(&fabrics.len()),
            "it lists no fabric classes"
        );
        let familiarity = meta
            .get("familiarity")
            .map(|text| {
                Familiarity::from_metadata(text, super::cells::TEXTURE.dim(), fabrics.len())
            })
            .transpose()?;
        let threshold = meta
            .get("threshold")
            .map(|t| -> crate::Result<f32> {
                let t: f32 = t.parse().context("its threshold is not a number")?;
                check_threshold(t).context("its threshold")?;
                Ok(t)
            })
            .transpose()?;
        Ok(Self {
            widths: Widths(widths),
            fabrics,
            made_by: meta.get("made_by").cloned().unwrap_or_default(),
            familiarity,
            threshold,
        })
    }
}

/// Writes `net` and `about` to `path`, whole or not at all.
pub fn save(path: &Path, net: &Net, about: &About) -> crate::Result<()> {
    let mut store = SafetensorsStore::from_bytes(None).clear_metadata();
    for (k, v) in about.metadata()? {
        store = store.metadata(k, v);
    }
    net.valid()
        .save_into(&mut store)
        .map_err(|e| anyhow::anyhow!("cannot encode the model: {e}"))?;
    let bytes = store
        .get_bytes()
        .map_err(|e| anyhow::anyhow!("cannot encode the model: {e}"))?;
    Ok(write_bytes_atomic(path, &bytes)?)
}

/// The model built into the tool (`models/detector.safetensors`; see `docs/detect.md`
/// for the command and seed that made it).
pub const BUILT_IN: &[u8] = include_bytes!("../../../models/detector.safetensors");

/// Reads a model file and builds its network; every problem is one line naming the file.
pub fn load(path: &Path) -> crate::Result<(Net, About)> {
    let shown = path.display().to_string();
    let size = std::fs::metadata(path)
        .with_context(|| format!("cannot read model {shown}"))?
        .len();
    if size > MAX_MODEL_BYTES {
        rollfuse_io::invalid!(
            "model {shown} is {size} bytes, more than a model can be ({MAX_MODEL_BYTES})"
        );
    }
    let bytes = std::fs::read(path).with_context(|| format!("cannot read model {shown}"))?;
    from_bytes(bytes, &shown)
}

/// The built-in model.
pub fn built_in() -> crate::Result<(Net, About)> {
    rollfuse_io::require!(
        !BUILT_IN.is_empty(),
        "this build has no built-in model: pass --model (rollfuse train writes one)"
    );
    from_bytes(BUILT_IN.to_vec(), "(built in)")
}

/// Builds the network of a model file's bytes on the CPU; `shown` names it in errors.
pub fn from_bytes(bytes: Vec<u8>, shown: &str) -> crate::Result<(Net, About)> {
    let (_, meta) = safetensors::SafeTensors::read_metadata(&bytes)
        .map_err(|e| anyhow::anyhow!("model {shown} is not a safetensors file ({e})"))?;
    let about = meta
        .metadata()
        .as_ref()
        .context("no metadata")
        .and_then(|meta| Ok(About::parse(meta)?))
        .map_err(|e| anyhow::anyhow!("model {shown} is not a rollfuse detector: {e:#}"))?;
    // The network computes in f32; a tensor stored otherwise is refused here, by name,
    // rather than converted or left to fail inside the network.
    let mut names: Vec<(String, safetensors::Dtype)> = meta
        .tensors()
        .into_iter()
        .filter(|(_, info)| info.dtype != safetensors::Dtype::F32)
        .map(|(name, info)| (name, info.dtype))
        .collect();
    names.sort();
    if let Some((name, dtype)) = names.first() {
        rollfuse_io::invalid!(
            "model {shown} stores {name} as {dtype:?}; a detector's tensors are F32{}",
            match names.len() - 1 {
                0 => String::new(),
                n => format!(" ({n} more tensors are not)"),
            }
        );
    }
    let mut net = Net::new(about.widths, about.fabrics.len(), &Device::flex());
    // Mismatches are collected and reported here, one line, rather than by the store.
    let mut store = SafetensorsStore::from_bytes(Some(bytes)).validate(false);
    let applied = net
        .load_from(&mut store)
        .map_err(|e| anyhow::anyhow!("model {shown} is corrupt: {}", first_line(&e)))?;
    if let Some(e) = applied.errors.first() {
        let more = match applied.errors.len() - 1 {
            0 => String::new(),
            n => format!(" (and {n} more)"),
        };
        rollfuse_io::invalid!(
            "model {shown} does not fit the network it describes: {}{more}",
            mismatch(e)
        );
    }
    if let Some((name, _)) = applied.missing.first() {
        rollfuse_io::invalid!("model {shown} lacks the tensor {name}");
    }
    Ok((net, about))
}

/// One tensor's mismatch, in a few words.
fn mismatch(e: &ApplyError) -> String {
    match e {
        ApplyError::ShapeMismatch {
            path,
            expected,
            found,
        } => format!(
            "{path} is {:?}, the network needs {:?}",
            found.as_slice(),
            expected.as_slice()
        ),
        ApplyError::DTypeMismatch {
            path,
            expected,
            found,
        } => format!("{path} is {found:?}, the network needs {expected:?}"),
        other => first_line(&format!("{other:?}")),
    }
}

/// An error's first line.
pub fn first_line(e: &dyn std::fmt::Display) -> String {
    e.to_string().lines().next().unwrap_or_default().to_string()
}
