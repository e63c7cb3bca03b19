#!/usr/bin/env python3
"""Reference implementation of rollfuse's contact-window roll fusion in numpy +
PyWavelets, for speed comparison (host/bench/compare_roll.sh). Known offsets (the
manifest's commanded rows, as `rollfuse fuse --align motion`), the same bands (32 rows,
cross-faded over 8, fused with a margin of 10 rows either side), the same window (rows
where the gel lies within half the press depth of the apex), the fuse step of
ref_fusion.py cyclically over each band's frames. A whole process: decode, fuse, write.

    python3 host/bench/ref_roll.py OUT.png FRAME_FOLDER
"""
import json
import math
import os
import sys

import numpy as np
from PIL import Image

from ref_fusion import fuse

BAND, BLEND = 32, 8
MARGIN = BLEND // 2 + (3 << 1)  # one level


def main():
    out, folder = sys.argv[1], sys.argv[2]
    manifest = json.load(open(os.path.join(folder, "manifest.json")))
    sensor = manifest["scene_file"]["sensor"]
    w, h = manifest["image_size"]
    r, p, s = sensor["roller_radius_mm"], sensor["press_depth_mm"], sensor["mm_per_px"]
    rows = round(2 * math.sqrt(r * r - (r - p / 2) ** 2) / s)
    reach = BAND // 2 + MARGIN
    top = max(round(h / 2 - rows / 2), reach)
    bottom = min(top + rows, h - reach)
    frames = [(round(f["strip_row"]), os.path.join(folder, f["file"])) for f in manifest["frames"]]
    held, strip, prev, first_band = [], [], None, None
    last_top = frames[-1][0]

    def band_of(b):
        c = b * BAND + BAND // 2
        region = b * BAND - MARGIN
        use = [(t, img) for t, img in held
               if t + top <= c < t + bottom and t <= region and region + BAND + 2 * MARGIN <= t + h]
        if not use:
            return None
        fused = use[0][1][region - use[0][0]:region - use[0][0] + BAND + 2 * MARGIN]
        for t, img in use[1:]:
            fused = fuse(fused, img[region - t:region - t + BAND + 2 * MARGIN]).astype(np.float32)
        return region, fused

    def emit(b, cur):
        nonlocal prev
        lo, hi = b * BAND - BLEND // 2, b * BAND + BLEND // 2
        if prev is None:
            strip.append(cur[1][b * BAND - cur[0]:b * BAND + BLEND // 2 - cur[0]])
        else:
            t = ((np.arange(lo, hi) - lo + 0.5) / BLEND)[:, None]
            a = prev[1][lo - prev[0]:hi - prev[0]]
            c = cur[1][lo - cur[0]:hi - cur[0]]
            strip.append(a + t * (c - a))
        strip.append(cur[1][hi - cur[0]:(b + 1) * BAND - BLEND // 2 - cur[0]])
        prev = cur

    next_band = None
    for t, path in frames:
        img = np.asarray(Image.open(path).convert("L"), dtype=np.float32)
        held.append((t, img))
        if next_band is None:
            start = t + top - BAND // 2
            next_band = -(-start // BAND)
        while next_band * BAND + BAND // 2 < t + top:
            emit(next_band, band_of(next_band))
            next_band += 1
            c = next_band * BAND + BAND // 2
            while len(held) > 2 and held[0][0] + bottom <= c:
                held.pop(0)
    while next_band * BAND + BAND // 2 < last_top + bottom:
        emit(next_band, band_of(next_band))
        next_band += 1
    end = next_band * BAND
    strip.append(prev[1][end - BLEND // 2 - prev[0]:end - prev[0]])
    image = np.concatenate(strip)
    Image.fromarray(np.clip(np.round(image), 0, 255).astype(np.uint8)).save(out)


if __name__ == "__main__":
    main()
