//! `rollfuse.stream`: the fused tiles of a streaming session (the module over USB, the
//! virtual device, or a recording played back) as numpy arrays, as they arrive. The
//! session runs on its own thread, exactly as `rollfuse stream` runs it, and writes the
//! same strip and manifest to its folder.

use crate::errors::{OrPy, value_error};
use crate::fuse::choice;
use numpy::PyArray;
use numpy::ndarray::Array2;
use pyo3::exceptions::PyStopIteration;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rollfuse::progress::Silent;
use rollfuse::session::{Fusion, Opened, RecordsRequest, Request, open};
use rollfuse::stream::{Outcome, StopReason, StreamRecord, Watch, run_watched};
use rollfuse::strip_file::DEFAULT_SEGMENT_ROWS;
use rollfuse_core::protocol::{Command, Tile};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

/// Tiles waiting for Python. From a recording or the virtual device the session waits
/// for Python when they are all taken; from the module it cannot (the device does not
/// wait), so tiles past these are skipped for Python (the strip file still has them).
const WAITING_TILES: usize = 1024;

/// A tile handed to Python.
struct TileOut {
    index: u32,
    observations: u8,
    pixels: Array2<u8>,
}

/// Hands each tile to the Python side; asks a live device to stop when told to.
struct Handoff {
    tiles: SyncSender<TileOut>,
    /// Whether the session may wait for Python (not for a live device).
    wait: bool,
    skipped: Arc<AtomicU64>,
    stop: Arc<AtomicBool>,
    stop_sent: bool,
}

impl Watch for Handoff {
    fn tile(&mut self, tile: &Tile<'_>, _: &StreamRecord) {
        let shape = (usize::from(tile.height), usize::from(tile.width));
        let Ok(pixels) = Array2::from_shape_vec(shape, tile.pixels.to_vec()) else {
            return;
        };
        let out = TileOut {
            index: tile.index,
            observations: tile.observations,
            pixels,
        };
        let full = if self.wait {
            // Fails only when Python has let go of the stream: nothing to hand over.
            self.tiles.send(out).is_err()
        } else {
            matches!(self.tiles.try_send(out), Err(TrySendError::Full(_)))
        };
        if full {
            self.skipped.fetch_add(1, Ordering::Relaxed);
        }
    }

    fn command(&mut self) -> Option<Command> {
        if self.stop.load(Ordering::Relaxed) && !self.stop_sent {
            self.stop_sent = true;
            return Some(Command::StreamStop);
        }
        None
    }
}

/// A streaming session, iterated for its tiles: each a dict of index (the belt index),
/// observations (frames fused into it) and pixels (uint8, (rows, width)).
///
/// After the last tile, `manifest` holds the session's manifest.json as a dict,
/// `strip_files` its strip's files and `stop` why it ended. `skipped` counts tiles a
/// slow reader missed from a live device (they are in the strip file all the same).
/// `stop_streaming()` asks a live device to stop; its flush still arrives.
#[pyclass(module = "rollfuse")]
pub struct Stream {
    /// The tiles' receiver, out of it while a call waits on it (a Python object must be
    /// shareable between threads; a receiver is not).
    tiles: Mutex<Option<Receiver<TileOut>>>,
    session: Option<JoinHandle<anyhow::Result<Outcome>>>,
    skipped: Arc<AtomicU64>,
    stop: Arc<AtomicBool>,
    /// The folder, removed when the stream is dropped if it was made for it.
    folder: Folder,
    #[pyo3(get)]
    manifest: Option<Py<PyAny>>,
    #[pyo3(get)]
    strip_files: Vec<PathBuf>,
    #[pyo3(get)]
    stop_reason: Option<&'static str>,
}

/// Where the session writes.
enum Folder {
    Given(PathBuf),
    Temporary(tempfile::TempDir),
}

impl Folder {
    fn path(&self) -> PathBuf {
        match self {
            Folder::Given(p) => p.clone(),
            Folder::Temporary(t) => t.path().to_path_buf(),
        }
    }
}

fn stop_name(stop: StopReason) -> &'static str {
    match stop {
        StopReason::TileLimit => "tiles",
        StopReason::TimeLimit => "seconds",
        StopReason::DeviceStopped => "device stopped",
        StopReason::LinkClosed => "link closed",
        StopReason::Silent => "device silent",
    }
}

#[pymethods]
impl Stream {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__(&mut self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let taken = self.tiles.lock().ok().and_then(|mut t| t.take());
        if let Some(rx) = taken
            && let (rx, Ok(tile)) = py.detach(move || {
                let tile = rx.recv();
                (rx, tile)
            })
        {
            if let Ok(mut t) = self.tiles.lock() {
                *t = Some(rx);
            }
            let d = PyDict::new(py);
            d.set_item("index", tile.index)?;
            d.set_item("observations", tile.observations)?;
            d.set_item("pixels", PyArray::from_owned_array(py, tile.pixels))?;
            return Ok(d.into_any().unbind());
        }
        self.finish(py)?;
        Err(PyStopIteration::new_err(()))
    }

    /// Asks a live device to stop streaming (its last tiles and status still arrive).
    fn stop_streaming(&self) {
        self.stop.store(true, Ordering::Relaxed);
    }

    /// Tiles a slow reader missed from a live device.
    #[getter]
    fn skipped(&self) -> u64 {
        self.skipped.load(Ordering::Relaxed)
    }

    /// The session's folder (a temporary one, removed with the stream, unless `out` was
    /// given).
    #[getter]
    fn out(&self) -> PathBuf {
        self.folder.path()
    }
}

impl Stream {
    /// Waits for the session's end and keeps its outcome; its error, raised.
    fn finish(&mut self, py: Python<'_>) -> PyResult<()> {
        let Some(session) = self.session.take() else {
            return Ok(());
        };
        let outcome = py
            .detach(|| session.join())
            .map_err(|_| value_error("the streaming session failed unexpectedly"))?
            .or_py()?;
        let json = outcome
            .manifest
            .to_json()
            .map_err(|e| value_error(format!("manifest: {e}")))?;
        let manifest = py.import("json")?.call_method1("loads", (json,))?;
        self.manifest = Some(manifest.unbind());
        let folder = self.folder.path();
        self.strip_files = outcome.strip_files.iter().map(|f| folder.join(f)).collect();
        self.stop_reason = Some(stop_name(outcome.stop));
        Ok(())
    }
}

impl Drop for Stream {
    fn drop(&mut self) {
        // A reader that lets go stops a live device; the session ends on its own thread.
        self.stop.store(true, Ordering::Relaxed);
    }
}

/// Streams fused tiles, as `rollfuse stream` does, and yields each as it arrives.
///
/// device: 'sim' (the virtual device, with `scene`), 'usb' (the module) or
///     'replay:FILE' (a recording made with `record`).
/// out: the folder for strip.png and manifest.json (default: a temporary folder, removed
///     with the stream). tiles, seconds: stop a live device after so many tiles or
///     seconds. record: record every message to this file. The fusion options are the
///     command line's (--wavelet … --norm); frame_rate paces the virtual device.
///     records: keep the roll in these inspection records (a SQLite file or a
///     'postgres://' URL), from production line `line`, its scale `mm_per_px` belt
///     millimetres a camera pixel (with 'sim', default the scene's); segment_rows: most
///     rows per strip segment.
/// Unset, the fusion options are the module's defaults (db2, 1 level, 1×).
/// Returns a Stream: iterate it for the tiles; its `manifest` once it has ended.
#[pyfunction]
#[pyo3(signature = (device, *, scene=None, out=None, tiles=None, seconds=None, record=None,
    wavelet=None, levels=None, downsample=None, tile_rows=None, frames_per_tile=None,
    spacing_px=None, refine_rows=None, norm=None, unbounded_memory=false, frame_rate=None,
    records=None, line="default".to_owned(), mm_per_px=None, segment_rows=DEFAULT_SEGMENT_ROWS))]
pub fn stream(
    py: Python<'_>,
    device: String,
    scene: Option<PathBuf>,
    out: Option<PathBuf>,
    tiles: Option<u64>,
    seconds: Option<f64>,
    record: Option<PathBuf>,
    wavelet: Option<&str>,
    levels: Option<u8>,
    downsample: Option<u8>,
    tile_rows: Option<u16>,
    frames_per_tile: Option<u8>,
    spacing_px: Option<u16>,
    refine_rows: Option<u8>,
    norm: Option<&str>,
    unbounded_memory: bool,
    frame_rate: Option<f64>,
    records: Option<String>,
    line: String,
    mm_per_px: Option<f64>,
    segment_rows: usize,
) -> PyResult<Stream> {
    let folder = match out {
        Some(p) => Folder::Given(p),
        None => Folder::Temporary(tempfile::tempdir().map_err(|e| {
            pyo3::exceptions::PyOSError::new_err(format!("cannot make a temporary folder: {e}"))
        })?),
    };
    // Unset, each fusion option is the module's own default.
    let module = Fusion::default();
    let request = Request {
        device,
        scene,
        out: folder.path(),
        record,
        tiles,
        seconds,
        fusion: Fusion {
            wavelet: wavelet.map_or(Ok(module.wavelet), |w| choice("wavelet", w))?,
            levels: levels.unwrap_or(module.levels),
            downsample: downsample.unwrap_or(module.downsample),
            tile_rows: tile_rows.unwrap_or(module.tile_rows),
            frames_per_tile: frames_per_tile.unwrap_or(module.frames_per_tile),
            spacing_px,
            refine_rows: refine_rows.unwrap_or(module.refine_rows),
            norm: norm.map_or(Ok(module.norm), |n| choice("norm", n))?,
        },
        unbounded_memory,
        frame_rate,
        serve: None,
        other_inputs: Vec::new(),
        segment_rows,
        records: records.map(|records| RecordsRequest {
            records,
            line,
            mm_per_px,
        }),
    };
    let Opened { mut link, opts, .. } = py.detach(|| open(&request)).or_py()?;
    let (tx, rx) = sync_channel(WAITING_TILES);
    let skipped = Arc::new(AtomicU64::new(0));
    let stop = Arc::new(AtomicBool::new(false));
    let mut handoff = Handoff {
        tiles: tx,
        wait: !link.is_live() || request.device == "sim",
        skipped: skipped.clone(),
        stop: stop.clone(),
        stop_sent: false,
    };
    let session = std::thread::Builder::new()
        .name("rollfuse-stream".into())
        .spawn(move || run_watched(link.as_mut(), &opts, &Silent, &mut handoff))
        .map_err(|e| value_error(format!("cannot start the session's thread: {e}")))?;
    Ok(Stream {
        tiles: Mutex::new(Some(rx)),
        session: Some(session),
        skipped,
        stop,
        folder,
        manifest: None,
        strip_files: Vec::new(),
        stop_reason: None,
    })
}
