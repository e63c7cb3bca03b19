"""Type hints of the extension module (re-exported by ``rollfuse``)."""

from os import PathLike
from typing import Any, Literal, Optional, Sequence, Tuple, TypedDict, Union

import numpy as np
import numpy.typing as npt

ImageLike = npt.NDArray[Union[np.uint8, np.uint16, np.float32, np.float64]]
Frames = Union[ImageLike, Sequence[ImageLike]]
OutDtype = Literal["float32", "uint8", "uint16"]

__version__: str

def fuse(
    frames: Frames,
    *,
    wavelet: Literal["haar", "db2"] = "db2",
    levels: int = 1,
    align: Literal["template", "none", "offsets"] = "template",
    offsets: Optional[npt.NDArray[np.int64]] = None,
    template_rows: Tuple[float, float] = (1.0 / 3.0, 2.0 / 3.0),
    max_shift: Optional[int] = None,
    min_score: Optional[float] = None,
    ablation: Literal["none", "no-wavelet", "single-ll", "max-high"] = "none",
    precision: Literal["f32", "fixed"] = "f32",
    ll_weighting: Literal["paper", "equal"] = "paper",
    out_dtype: OutDtype = "float32",
) -> Tuple[npt.NDArray[Any], npt.NDArray[np.float64]]:
    """Fuses frames into one image as ``rollfuse fuse --mode mosaic``; returns
    (image, offsets), offsets (N, 2) rows and columns, NaN for frames left out."""

def fuse_pair(
    a: ImageLike,
    b: ImageLike,
    *,
    wavelet: Literal["haar", "db2"] = "db2",
    levels: int = 1,
    ablation: Literal["none", "no-wavelet", "single-ll", "max-high"] = "none",
    precision: Literal["f32", "fixed"] = "f32",
    ll_weighting: Literal["paper", "equal"] = "paper",
    out_dtype: OutDtype = "float32",
) -> npt.NDArray[Any]:
    """Fuses two images of one size (one fuse step)."""

def dwt2(
    data: ImageLike, wavelet: Literal["haar", "db2"] = "db2"
) -> Tuple[
    npt.NDArray[np.float32],
    Tuple[npt.NDArray[np.float32], npt.NDArray[np.float32], npt.NDArray[np.float32]],
]:
    """pywt.dwt2(data, wavelet, mode='periodization') in float32: (cA, (cH, cV, cD))."""

def idwt2(
    coeffs: Tuple[ImageLike, Tuple[ImageLike, ImageLike, ImageLike]],
    wavelet: Literal["haar", "db2"] = "db2",
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

def simulate(
    scene: Union[str, PathLike[str], dict[str, Any]],
    frames: Optional[int] = None,
    seed: Optional[int] = None,
) -> Simulation:
    """A scene's frames and ground truth as arrays, as ``rollfuse simulate``."""
