"""rollfuse for Python: cyclic wavelet fusion, photometric-stereo depth, the paper's
metrics and the roller simulator on numpy arrays, at the speed of the Rust library behind
the ``rollfuse`` command line (and with its results, bit for bit).

Images are (H, W) gray or (H, W, 3) RGB arrays of uint8, uint16 (scaled by 255/65535, as
16-bit PNGs are read) or float32/float64 on the 0–255 scale. Bad input raises
``ValueError`` and file trouble ``OSError``, with the command line's messages. Every
function releases the GIL while it works.
"""

from . import metrics
from ._rollfuse import (
    Lights,
    __version__,
    calibrate,
    depth,
    dwt2,
    fuse,
    fuse_pair,
    idwt2,
    simulate,
)

__all__ = [
    "Lights",
    "__version__",
    "calibrate",
    "depth",
    "dwt2",
    "fuse",
    "fuse_pair",
    "idwt2",
    "metrics",
    "simulate",
]
