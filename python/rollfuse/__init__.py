"""rollfuse for Python: cyclic wavelet fusion, photometric-stereo depth, the paper's
metrics and the roller simulator on numpy arrays, at the speed of the Rust library behind
the ``rollfuse`` command line (and with its results, bit for bit).

Images are (H, W) gray or (H, W, 3) RGB arrays of uint8, uint16 (scaled by 255/65535, as
16-bit PNGs are read) or float32/float64 on the 0–255 scale. Bad input raises
``ValueError`` and file trouble ``OSError``, with the command line's messages. Every
function releases the GIL while it works.
"""

import os
from typing import Optional, Union

from . import metrics
from ._rollfuse import (
    Lights,
    __version__,
    calibrate,
    depth,
    dwt2,
    fuse,
    fuse_pair,
    fuse_roll,
    idwt2,
    simulate,
    Stream,
    stream,
)



def replay(
    path: Union[str, "os.PathLike[str]"], *, out: Optional[Union[str, "os.PathLike[str]"]] = None
) -> Stream:
    """Plays back a recording made with ``stream(..., record=FILE)`` (or ``rollfuse stream
    --record FILE``): a Stream of its tiles as they were received, whose strip and
    manifest are the ones the recorded session wrote."""
    return stream(f"replay:{os.fspath(path)}", out=out)


__all__ = [
    "Lights",
    "__version__",
    "calibrate",
    "depth",
    "dwt2",
    "fuse",
    "fuse_pair",
    "fuse_roll",
    "idwt2",
    "metrics",
    "replay",
    "simulate",
    "Stream",
    "stream",
]
