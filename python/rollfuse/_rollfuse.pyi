"""Type hints of the extension module (re-exported by ``rollfuse``)."""

from os import PathLike
from typing import Any, Literal, Optional, Sequence, Tuple, TypedDict, Union

import numpy as np
import numpy.typing as npt

ImageLike = npt.NDArray[Union[np.uint8, np.uint16, np.float32, np.float64]]
Frames = Union[ImageLike, Sequence[ImageLike]]
OutDtype = Literal["float32", "uint8", "uint16"]
Wavelet = Literal["haar", "db2"]
Ablation = Literal["none", "no-wavelet", "single-ll", "max-high"]
Precision = Literal["f32", "fixed"]
LlWeighting = Literal["paper", "equal"]

__version__: str

def fuse(
    frames: Frames,
    *,
    wavelet: Wavelet = "db2",
    levels: int = 1,
    align: Literal["template", "none", "offsets"] = "template",
    offsets: Optional[npt.NDArray[np.int64]] = None,
    template_rows: Tuple[float, float] = (1.0 / 3.0, 2.0 / 3.0),
    max_shift: Optional[int] = None,
    min_score: Optional[float] = None,
    ablation: Ablation = "none",
    precision: Precision = "f32",
    ll_weighting: LlWeighting = "paper",
    out_dtype: OutDtype = "float32",
    max_pixels: int = 33554432,
) -> Tuple[npt.NDArray[Any], npt.NDArray[np.float64]]:
    """Fuses frames into one image as ``rollfuse fuse --mode mosaic``; returns
    (image, offsets), offsets (N, 2) rows and columns, NaN for frames left out. A whole
    roll is ``fuse_roll``'s. A canvas over ``max_pixels`` (``--max-pixels``) is refused
    before it is allocated."""

class Geometry(TypedDict, total=False):
    roller_radius_mm: float
    press_depth_mm: float
    mm_per_px: float
    apex_row: float

class Placements(TypedDict):
    row: npt.NDArray[np.float64]
    col: npt.NDArray[np.int64]
    score: npt.NDArray[np.float64]
    source: list[Literal["first", "matched", "predicted", "manifest"]]

class RollReport(TypedDict):
    first_row: int
    window: Tuple[int, int]
    window_source: Literal["window_rows", "geometry", "measured", "default"]
    matched: int
    predicted: int
    bands: int
    bands_outside_window: int
    gap_bands: int
    frames_behind: int

def fuse_roll(
    frames: Frames,
    *,
    rows: Optional[npt.NDArray[np.float64]] = None,
    align: Literal["template", "motion"] = "template",
    window_rows: Optional[int] = None,
    geometry: Optional[Geometry] = None,
    band_rows: int = 32,
    blend_rows: int = 8,
    search_rows: Optional[int] = None,
    max_shift: Optional[int] = None,
    min_score: Optional[float] = None,
    subpixel: bool = True,
    max_drift_cols: int = 0,
    wavelet: Wavelet = "db2",
    levels: int = 1,
    ablation: Ablation = "none",
    precision: Precision = "f32",
    ll_weighting: LlWeighting = "paper",
    out_dtype: OutDtype = "float32",
) -> Tuple[npt.NDArray[Any], Placements, RollReport]:
    """Fuses a whole roll into a strip as ``rollfuse fuse --mode roll``; returns
    (strip, placements, report)."""

def fuse_pair(
    a: ImageLike,
    b: ImageLike,
    *,
    wavelet: Wavelet = "db2",
    levels: int = 1,
    ablation: Ablation = "none",
    precision: Precision = "f32",
    ll_weighting: LlWeighting = "paper",
    out_dtype: OutDtype = "float32",
) -> npt.NDArray[Any]:
    """Fuses two images of one size (one fuse step)."""

def dwt2(
    data: ImageLike, wavelet: Wavelet = "db2"
) -> Tuple[
    npt.NDArray[np.float32],
    Tuple[npt.NDArray[np.float32], npt.NDArray[np.float32], npt.NDArray[np.float32]],
]:
    """pywt.dwt2(data, wavelet, mode='periodization') in float32: (cA, (cH, cV, cD))."""

def idwt2(
    coeffs: Tuple[ImageLike, Tuple[ImageLike, ImageLike, ImageLike]],
    wavelet: Wavelet = "db2",
) -> npt.NDArray[np.float32]:
    """pywt.idwt2(coeffs, wavelet, mode='periodization') in float32."""

class Lights:
    """The image scale and the three LEDs' directions and gains (the light file)."""

    def __init__(
        self,
        mm_per_px: float,
        red: Sequence[float],
        green: Sequence[float],
        blue: Sequence[float],
        gains: Sequence[float] = (1.0, 1.0, 1.0),
    ) -> None: ...
    @staticmethod
    def load(path: Union[str, PathLike[str]]) -> "Lights":
        """Reads and checks a light file (TOML)."""
    @staticmethod
    def product(mm_per_px: float) -> "Lights":
        """The module's three LEDs at ``mm_per_px``."""
    def save(self, path: Union[str, PathLike[str]]) -> None:
        """Writes the light file."""
    def to_toml(self) -> str:
        """The light file's text."""
    def condition(self) -> float:
        """The light matrix's condition number."""
    @property
    def mm_per_px(self) -> float: ...
    @property
    def red(self) -> list[float]: ...
    @property
    def green(self) -> list[float]: ...
    @property
    def blue(self) -> list[float]: ...
    @property
    def gains(self) -> list[float]: ...

def depth(
    image: ImageLike, lights: Lights, *, background: Optional[ImageLike] = None
) -> npt.NDArray[np.float32]:
    """Height map in mm (float32, (H, W)) of an RGB tactile image, as ``rollfuse depth``."""

def calibrate(
    image: ImageLike,
    *,
    radius_mm: float,
    mm_per_px: float,
    background: Optional[ImageLike] = None,
    circle: Optional[Tuple[float, float, float]] = None,
) -> Tuple[Lights, Tuple[float, float, float]]:
    """Fits the light file from a pressed ball, as ``rollfuse calibrate``."""

def ie(img: ImageLike) -> float:
    """Information entropy of the gray-normalized image (bits)."""

def ms_ssim(img: ImageLike, ref: ImageLike) -> float:
    """MS-SSIM of ``img`` against ``ref``, both gray-normalized."""

class Report(TypedDict):
    ie: float
    ie_std: float
    ms_ssim: Optional[float]
    ms_ssim_std: Optional[float]
    strip_ie: list[float]
    strip_ms_ssim: Optional[list[float]]

def strip_std(
    img: ImageLike,
    reference: Optional[ImageLike] = None,
    *,
    strips: int = 10,
    axis: Literal["rows", "columns"] = "rows",
) -> Report:
    """Every figure of ``rollfuse metrics --json``."""

class Simulation(TypedDict):
    frames: npt.NDArray[np.uint8]
    offset_mm: npt.NDArray[np.float64]
    actual_offset_mm: npt.NDArray[np.float64]
    strip_row: npt.NDArray[np.float64]
    actual_strip_row: npt.NDArray[np.float64]
    height_mm: npt.NDArray[np.float32]
    ideal: npt.NDArray[np.uint8]
    lights: Optional[Lights]
    scene: str
    seed: int
    mm_per_px: float
    geometry: Geometry

def simulate(
    scene: Union[str, PathLike[str], dict[str, Any]],
    frames: Optional[int] = None,
    seed: Optional[int] = None,
) -> Simulation:
    """A scene's frames and ground truth as arrays, as ``rollfuse simulate``."""

class StreamTile(TypedDict):
    index: int
    observations: int
    pixels: npt.NDArray[np.uint8]

class Stream:
    """A streaming session; iterate it for its tiles as they arrive."""

    def __iter__(self) -> "Stream": ...
    def __next__(self) -> StreamTile: ...
    def stop_streaming(self) -> None:
        """Asks a live device to stop streaming (its last tiles still arrive)."""
    @property
    def manifest(self) -> Optional[dict[str, Any]]:
        """manifest.json as a dict, once the stream has ended."""
    @property
    def strip_files(self) -> list[str]:
        """The strip's files, once the stream has ended."""
    @property
    def stop_reason(self) -> Optional[
        Literal["tiles", "seconds", "device stopped", "link closed", "device silent"]
    ]:
        """Why the session ended, once it has."""
    @property
    def skipped(self) -> int:
        """Tiles a slow reader missed from a live device (the strip file has them)."""
    @property
    def out(self) -> str:
        """The session's folder."""

def stream(
    device: str,
    *,
    scene: Optional[Union[str, PathLike[str]]] = None,
    out: Optional[Union[str, PathLike[str]]] = None,
    tiles: Optional[int] = None,
    seconds: Optional[float] = None,
    record: Optional[Union[str, PathLike[str]]] = None,
    wavelet: Optional[Wavelet] = None,
    levels: Optional[int] = None,
    downsample: Optional[int] = None,
    tile_rows: Optional[int] = None,
    frames_per_tile: Optional[int] = None,
    spacing_px: Optional[int] = None,
    refine_rows: Optional[int] = None,
    norm: Optional[Literal["per-tile", "per-frame"]] = None,
    unbounded_memory: bool = False,
    frame_rate: Optional[float] = None,
    records: Optional[str] = None,
    line: str = "default",
    mm_per_px: Optional[float] = None,
    segment_rows: int = 4096,
) -> Stream:
    """Streams fused tiles from 'sim', 'usb' or 'replay:FILE' as ``rollfuse stream``."""
