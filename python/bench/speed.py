#!/usr/bin/env python3
"""Times rollfuse.fuse in-process on frames read from PNG files: the fusion of
`rollfuse fuse FRAMES --align none --levels 1`, best of REPS calls (reading the files
excluded, as the command line's own "fusion took" excludes it). Prints the best time in
seconds on its last line.

    python3 python/bench/speed.py REPS FRAME.png...
"""
import sys
import time
from typing import List

import numpy as np
from PIL import Image

import rollfuse


def main(argv: List[str]) -> None:
    """Reads the frames, fuses them REPS times, prints the best time."""
    reps, paths = int(argv[1]), argv[2:]
    frames = np.stack([np.asarray(Image.open(p).convert("L")) for p in paths])
    best = float("inf")
    for _ in range(reps):
        t0 = time.perf_counter()
        rollfuse.fuse(frames, align="none", levels=1)
        best = min(best, time.perf_counter() - t0)
    print(f"{best:.6f}")


if __name__ == "__main__":
    main(sys.argv)
