#!/usr/bin/env python3
"""Reference implementation of rollfuse's fusion step in numpy + PyWavelets, for speed
comparison (host/bench/compare.sh). Same algorithm as `rollfuse fuse --align none
--levels 1` on gray frames: per level, the 4-neighbour Laplacian saliency of both inputs
(max-normalized, exp(x) - 1), 2x2 block sums as weights, pywt.dwt2(..., 'db2',
mode='periodization'), LL mean, high bands weighted, idwt2; cyclic over the frames.

    python3 host/bench/ref_fusion.py OUT.png FRAME.png...

Prints the fusion time in seconds (image loading excluded) on its last line.
"""
import sys
import time

import numpy as np
import pywt
from PIL import Image


def saliency_blocks(img):
    p = np.pad(img, 1, mode="reflect")
    lap = np.abs(p[:-2, 1:-1] + p[2:, 1:-1] + p[1:-1, :-2] + p[1:-1, 2:] - 4 * img)
    m = lap.max()
    s = np.zeros_like(img) if m <= 0 else np.exp(lap / m) - 1.0
    h, w = s.shape
    return s.reshape(h // 2, 2, w // 2, 2).sum(axis=(1, 3))


def fuse(a, b):
    sa, sb = saliency_blocks(a), saliency_blocks(b)
    tot = sa + sb
    w1 = np.where(tot > 0, sa / np.where(tot > 0, tot, 1), 0.5)
    ca, (ha, va, da) = pywt.dwt2(a, "db2", mode="periodization")
    cb, (hb, vb, db) = pywt.dwt2(b, "db2", mode="periodization")
    mix = lambda x, y: w1 * x + (1 - w1) * y
    return pywt.idwt2(((ca + cb) / 2, (mix(ha, hb), mix(va, vb), mix(da, db))), "db2", mode="periodization")


def main():
    out, paths = sys.argv[1], sys.argv[2:]
    frames = [np.asarray(Image.open(p).convert("L"), dtype=np.float32) for p in paths]
    t0 = time.perf_counter()
    fused = frames[0]
    for f in frames[1:]:
        fused = fuse(fused, f).astype(np.float32)
    elapsed = time.perf_counter() - t0
    Image.fromarray(np.clip(np.round(fused), 0, 255).astype(np.uint8)).save(out)
    print(f"{elapsed:.6f}")


if __name__ == "__main__":
    main()
