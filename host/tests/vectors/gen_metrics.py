#!/usr/bin/env python3
"""Reference values for the metrics, from implementations independent of rollfuse.

    pip install numpy scikit-image
    python3 host/tests/vectors/gen_metrics.py

writes host/tests/vectors/metrics/*.png (8-bit gray) and metrics.json beside them.

IE: skimage.measure.shannon_entropy(img, base=2) on 8-bit images.
MS-SSIM: a plain numpy transcription of Wang, Simoncelli & Bovik 2003 with the
conventions of docs/metrics.md: gray-normalize both images to 0..255, 11x11 Gaussian
(sigma 1.5) 'valid' filtering, K1 0.01, K2 0.03, L 255, weights 0.0448 0.2856 0.3001
0.2363 0.1333, 2x2 average downsampling with edge-repeat padding for odd sizes, negative
contrast-structure terms clipped to 0, fewer scales (weights renormalized) for images
smaller than 161 px. The committed JSON lets `cargo test` run without Python.
"""
import json
import os

import numpy as np
from PIL import Image
from skimage.measure import shannon_entropy

WEIGHTS = np.array([0.0448, 0.2856, 0.3001, 0.2363, 0.1333])


def gauss():
    x = np.arange(11) - 5.0
    g = np.exp(-(x ** 2) / (2 * 1.5 ** 2))
    return g / g.sum()


def filt(img, g):
    rows = np.array([np.convolve(r, g[::-1], mode="valid") for r in img])
    return np.array([np.convolve(c, g[::-1], mode="valid") for c in rows.T]).T


def down(img):
    h, w = img.shape
    img = np.pad(img, ((0, h % 2), (0, w % 2)), mode="edge")
    return (img[0::2, 0::2] + img[1::2, 0::2] + img[0::2, 1::2] + img[1::2, 1::2]) / 4.0


def norm(img):
    lo, hi = img.min(), img.max()
    return np.zeros_like(img) if hi <= lo else (img - lo) * 255.0 / (hi - lo)


def ms_ssim(a, b):
    a, b = norm(a.astype(np.float64)), norm(b.astype(np.float64))
    c1, c2 = (0.01 * 255) ** 2, (0.03 * 255) ** 2
    side, m = min(a.shape), 0
    while m < 5 and side >= 11:
        m += 1
        side = (side + 1) // 2
    w = WEIGHTS[:m] / WEIGHTS[:m].sum()
    g = gauss()
    out = 1.0
    for j in range(m):
        ma, mb = filt(a, g), filt(b, g)
        va, vb, cov = filt(a * a, g) - ma ** 2, filt(b * b, g) - mb ** 2, filt(a * b, g) - ma * mb
        lum = np.mean((2 * ma * mb + c1) / (ma ** 2 + mb ** 2 + c1))
        cs = np.mean((2 * cov + c2) / (va + vb + c2))
        out *= max(cs, 0.0) ** w[j]
        if j == m - 1:
            out *= max(lum, 0.0) ** w[j]
        else:
            a, b = down(a), down(b)
    return out


def main():
    out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "metrics")
    os.makedirs(out, exist_ok=True)
    rng = np.random.default_rng(8)
    cases = []
    plan = [((180, 176), ("noisy", "blurred")), ((257, 193), ("random",)), ((64, 48), ("noisy",)),
            ((31, 90), ("blurred",)), ((12, 12), ("noisy",))]
    for (w, h), kinds in plan:
        yy, xx = np.mgrid[0:h, 0:w]
        ref = 128 + 60 * np.sin(xx / 7.0) * np.cos(yy / 5.0) + 30 * (xx > w / 2)
        variants = {
            "noisy": ref + rng.normal(0, 12, size=ref.shape),
            "blurred": (ref + np.roll(ref, 1, 0) + np.roll(ref, 1, 1) + np.roll(ref, -1, 0)) / 4,
            "random": rng.uniform(0, 255, ref.shape),
        }
        r8 = np.clip(np.round(ref), 0, 255).astype(np.uint8)
        ref_file = f"ref_{w}x{h}.png"
        Image.fromarray(r8).save(os.path.join(out, ref_file))
        for name in kinds:
            x8 = np.clip(np.round(variants[name]), 0, 255).astype(np.uint8)
            file = f"{name}_{w}x{h}.png"
            Image.fromarray(x8).save(os.path.join(out, file))
            cases.append({
                "image": file,
                "reference": ref_file,
                "ie": float(shannon_entropy(x8, base=2)),
                "ms_ssim": float(ms_ssim(x8, r8)),
            })
    with open(os.path.join(out, "metrics.json"), "w") as f:
        json.dump({"cases": cases}, f, indent=1)


if __name__ == "__main__":
    main()
