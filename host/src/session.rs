//! A streaming session opened: what to stream from and into, every option checked and no
//! output an input, the output folder made and the link opened — what `rollfuse stream`
//! and the Python package's `rollfuse.stream` both run before [`crate::stream::run`].
//! Messages name the options as the command line spells them.

use crate::link::Transport;
use crate::link::replay::Replay;
use crate::link::sim::{DeviceMemory, SimDevice};
use crate::link::usb::Usb;
use crate::serve;
use crate::sim::Scene;
use crate::stream::{self, Options};
use anyhow::{Context, bail, ensure};
use rollfuse_core::protocol::{DeviceConfig, NormMode, WaveletId};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// What to stream from and into.
#[derive(Debug, Clone)]
pub struct Request {
    /// `usb`, `sim` (the virtual device, with a scene) or `replay:FILE`.
    pub device: String,
    /// With `sim`: the scene the virtual device's camera sees.
    pub scene: Option<PathBuf>,
    /// The output folder: the strip and `manifest.json`.
    pub out: PathBuf,
    /// Where every received message is recorded, if anywhere.
    pub record: Option<PathBuf>,
    /// Stop after this many tiles.
    pub tiles: Option<u64>,
    /// Stop after this many seconds.
    pub seconds: Option<f64>,
    /// What the device is told to fuse with.
    pub fusion: Fusion,
    /// With `sim`: as much pipeline memory as the configuration needs.
    pub unbounded_memory: bool,
    /// With `sim`: frames a second in real time (none: virtual time).
    pub frame_rate: Option<f64>,
    /// The live page's address, if one is served.
    pub serve: Option<String>,
    /// Files the session reads besides its device's (a detector's model), by what they
    /// are: never written over.
    pub other_inputs: Vec<(&'static str, PathBuf)>,
    /// Most rows per strip segment.
    pub segment_rows: usize,
    /// Where the roll is kept in the inspection records, if anywhere.
    pub records: Option<RecordsRequest>,
}

/// `--records`, `--line`, `--mm-per-px`.
#[derive(Debug, Clone)]
pub struct RecordsRequest {
    /// A SQLite file's path or a `postgres://` URL.
    pub records: String,
    /// The production line.
    pub line: String,
    /// Belt millimetres a camera pixel (with `sim`, default the scene's).
    pub mm_per_px: Option<f64>,
}

/// The device configuration a session asks for.
#[derive(Debug, Clone, Copy)]
pub struct Fusion {
    /// The wavelet.
    pub wavelet: WaveletId,
    /// Decomposition levels.
    pub levels: u8,
    /// Box downsampling of camera frames.
    pub downsample: u8,
    /// Tile height along the belt, downsampled rows.
    pub tile_rows: u16,
    /// Frames fused into each tile.
    pub frames_per_tile: u8,
    /// Belt travel between frames, camera pixels (none: the scene's, or the module's).
    pub spacing_px: Option<u16>,
    /// Offset refinement search, ± downsampled rows.
    pub refine_rows: u8,
    /// Saliency normalization.
    pub norm: NormMode,
}

impl Default for Fusion {
    /// The module's own configuration.
    fn default() -> Self {
        let m = DeviceConfig::default();
        Self {
            wavelet: m.wavelet,
            levels: m.levels,
            downsample: m.downsample,
            tile_rows: m.tile_rows,
            frames_per_tile: m.frames_per_tile,
            spacing_px: None,
            refine_rows: m.refine_rows,
            norm: m.norm,
        }
    }
}

impl Fusion {
    /// The configuration sent, with `spacing_default` where no spacing is given.
    fn config(&self, spacing_default: u16) -> DeviceConfig {
        DeviceConfig {
            wavelet: self.wavelet,
            levels: self.levels,
            downsample: self.downsample,
            tile_rows: self.tile_rows,
            frames_per_tile: self.frames_per_tile,
            frame_spacing_px: self.spacing_px.unwrap_or(spacing_default),
            refine_rows: self.refine_rows,
            norm: self.norm,
        }
    }
}

/// A session ready to run: its link, options and the address to serve on.
pub struct Opened {
    /// The device, virtual device or recording.
    pub link: Box<dyn Transport>,
    /// The session's options.
    pub opts: Options,
    /// `--serve`'s address.
    pub serve: Option<std::net::SocketAddr>,
    /// The output folder, removed again if the session writes nothing to it.
    pub folder: crate::files::NewFolder,
}

/// Checks every option of `request` (and that no output is an input), makes the output
/// folder and opens the link: what `rollfuse stream` runs, and the Python package's
/// `rollfuse.stream`.
pub fn open(request: &Request) -> anyhow::Result<Opened> {
    let checked = check(request)?;
    let folder = crate::files::NewFolder::create(&request.out)?;
    crate::files::check_writable(&request.out.join("manifest.json"))?;
    if let Some(r) = &request.record {
        crate::files::check_writable(r)?;
    }
    ensure!(
        request.segment_rows >= 1,
        "--segment-rows must be at least 1"
    );
    let (link, config, scene_scale) = open_link(request, &checked)?;
    let keep = (request.records.as_ref())
        .map(|r| keep_roll(request, r, &checked, config, scene_scale))
        .transpose()?;
    let opts = Options {
        out: request.out.clone(),
        config,
        max_tiles: request.tiles,
        max_duration: checked.max_duration,
        record: request.record.clone(),
        segment_rows: request.segment_rows,
        keep,
    };
    Ok(Opened {
        link,
        opts,
        serve: checked.serve,
        folder,
    })
}

/// What the options say, once checked.
struct Checked {
    /// `--device replay:FILE`'s file.
    replay: Option<std::path::PathBuf>,
    /// `--seconds`.
    max_duration: Option<Duration>,
    /// `--serve`.
    serve: Option<std::net::SocketAddr>,
    /// `--frame-rate`, as the time between frames.
    frame_period: Option<Duration>,
}

/// Checks the options and that the recording written is none of the inputs.
fn check(request: &Request) -> anyhow::Result<Checked> {
    if let Some(s) = request.seconds
        && !(s > 0.0 && s.is_finite())
    {
        bail!("--seconds must be a positive number, got {s}");
    }
    if request.tiles == Some(0) {
        bail!("--tiles must be at least 1");
    }
    let max_duration = request
        .seconds
        .map(Duration::try_from_secs_f64)
        .transpose()
        .map_err(|_| anyhow::anyhow!("--seconds is too long: {:?}", request.seconds))?;
    let replay = match request.device.as_str() {
        "usb" | "sim" => None,
        other => match other.strip_prefix("replay:") {
            Some(file) if !file.is_empty() => Some(std::path::PathBuf::from(file)),
            _ => bail!("--device must be usb, sim or replay:FILE, got `{other}`"),
        },
    };
    if request.device == "sim" && request.scene.is_none() {
        bail!("--device sim needs --scene SCENE.toml (e.g. host/scenes/letters.toml)");
    }
    if request.unbounded_memory && request.device != "sim" {
        bail!("--unbounded-memory is for the virtual device (--device sim) only");
    }
    let frame_period = request.frame_rate.map(frame_period).transpose()?;
    if frame_period.is_some() && request.device != "sim" {
        bail!("--frame-rate is for the virtual device (--device sim) only");
    }
    let serve = request
        .serve
        .as_deref()
        .map(serve::parse_addr)
        .transpose()?;
    refuse_overwriting_inputs(request, replay.as_deref())?;
    Ok(Checked {
        replay,
        max_duration,
        serve,
        frame_period,
    })
}

/// Refuses, before the session, a run that would overwrite what it reads or records: the
/// recording (`--record`) or an input (the replayed recording, the scene, the model)
/// where the session writes its strip, its segments, its index or its manifest, or the
/// recording over an input.
fn refuse_overwriting_inputs(request: &Request, replay: Option<&Path>) -> anyhow::Result<()> {
    let mut inputs: Vec<(&str, &Path)> = Vec::new();
    inputs.extend(replay.map(|p| ("recording replayed", p)));
    inputs.extend(request.scene.as_deref().map(|p| ("scene", p)));
    inputs.extend(
        request
            .other_inputs
            .iter()
            .map(|(what, p)| (*what, p.as_path())),
    );
    let records = request.records.as_ref().map(|r| r.records.as_str());
    let records = records.filter(|r| !rollfuse_records::is_postgres(r));
    inputs.extend(records.map(|r| ("records", Path::new(r))));
    let session = stream::output_files(&request.out);
    let outputs: Vec<&Path> = session.iter().map(PathBuf::as_path).collect();
    crate::files::refuse_overwriting(&outputs, &inputs)?;
    let strip = &session[0];
    crate::strip_file::refuse_segment_names(strip, &inputs)?;
    if let Some(r) = request.record.as_deref() {
        crate::files::refuse_overwriting(&[r], &inputs)?;
        let at = crate::files::resolved(r);
        let session_writes = outputs.iter().any(|o| crate::files::resolved(o) == at)
            || crate::strip_file::is_segment_name(strip, r);
        ensure!(
            !session_writes,
            "--record {} is where the session writes its strip, index or manifest: record \
             to another file",
            r.display()
        );
    }
    Ok(())
}

/// `--frame-rate`'s period: a rate from 0.01 to 10 000 frames a second.
fn frame_period(rate: f64) -> anyhow::Result<Duration> {
    if !(0.01..=10_000.0).contains(&rate) {
        bail!("--frame-rate must be from 0.01 to 10000 frames a second, got {rate}");
    }
    Ok(Duration::from_secs_f64(1.0 / rate))
}

/// The roll's record as a session starts it: its source (a recording is one source
/// however often it is streamed; a device or the virtual device is a new one each
/// session), the configuration sent, the scale given or the scene's.
fn keep_roll(
    request: &Request,
    r: &RecordsRequest,
    checked: &Checked,
    config: Option<DeviceConfig>,
    scene_scale: Option<f64>,
) -> anyhow::Result<crate::records::KeepRoll> {
    if let Some(k) = r.mm_per_px {
        ensure!(
            k.is_finite() && k > 0.0,
            "--mm-per-px must be positive, got {k}"
        );
    }
    let absolute = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let now = humantime::format_rfc3339_millis(std::time::SystemTime::now());
    let source = match (&checked.replay, &request.scene) {
        (Some(file), _) => format!("recording {}", absolute(file).display()),
        (None, Some(scene)) => {
            format!(
                "virtual device, scene {}, at {now}",
                absolute(scene).display()
            )
        }
        (None, None) => format!("device on USB at {now}"),
    };
    Ok(crate::records::KeepRoll {
        records: r.records.clone(),
        start: rollfuse_records::RollStart {
            source,
            line: r.line.clone(),
            device: request.device.clone(),
            configuration: serde_json::to_string(&config)?,
            out: String::new(),
            mm_per_row: None,
        },
        mm_per_px: r.mm_per_px.or(scene_scale),
    })
}

/// An opened link: the transport, the configuration to send (none to a recording), and
/// the scene's belt millimetres a camera pixel (the virtual device).
type Link = (Box<dyn Transport>, Option<DeviceConfig>, Option<f64>);

/// The link the options name.
fn open_link(request: &Request, checked: &Checked) -> anyhow::Result<Link> {
    Ok(match checked.replay.as_deref() {
        Some(file) => (Box::new(Replay::open(file)?), None, None),
        None if request.device == "usb" => (
            Box::new(Usb::open()?),
            Some(
                request
                    .fusion
                    .config(DeviceConfig::default().frame_spacing_px),
            ),
            None,
        ),
        None => {
            let path = request
                .scene
                .as_ref()
                .context("--device sim needs --scene")?;
            let memory = if request.unbounded_memory {
                DeviceMemory::Unbounded
            } else {
                DeviceMemory::Firmware
            };
            let scene = Scene::load(path)?;
            let dev = SimDevice::start_paced(&scene, memory, checked.frame_period)?;
            let spacing = dev.default_config().frame_spacing_px;
            let scale = scene.sensor.mm_per_px;
            (
                Box::new(dev),
                Some(request.fusion.config(spacing)),
                Some(scale),
            )
        }
    })
}
