#!/usr/bin/env python3
"""Reference implementation of `rollfuse depth` in numpy + scipy, for speed comparison
(host/bench/compare_depth.sh). The same steps: ratio to the background, normals from the
inverse light matrix, slopes clamped to 5, contact mask (5x5 mean slope above
max(0.02, 3 x median), grown by 3 px), slopes between pixel centres, the Neumann Poisson
equation solved by DCT-II (scipy.fft), baseline at the median off contact.

    python3 host/bench/ref_depth.py IMAGE.png LIGHTS.toml BACKGROUND.png OUT.npy
    python3 host/bench/ref_depth.py --make DIR   # a 640x480 ball, its background, lights

Prints the time of the computation in seconds (loading excluded) on its last line.
"""
import sys
import time
import tomllib

import numpy as np
from PIL import Image
from scipy import fft, ndimage


def depth(img, bg, lights):
    k = lights["mm_per_px"]
    L = np.array([lights["red"], lights["green"], lights["blue"]], dtype=np.float64)
    gains = np.array(lights.get("gains", [1.0, 1.0, 1.0]))
    s = img / np.maximum(bg, 4.0) * (L[:, 2] / gains)
    n = np.einsum("ij,hwj->hwi", np.linalg.inv(L), s)
    valid = n[..., 2] > 1e-3
    nz = np.where(valid, n[..., 2], 1.0)
    p = np.where(valid, -n[..., 0] / nz, 0.0)
    q = np.where(valid, -n[..., 1] / nz, 0.0)
    mag = np.hypot(p, q)
    over = mag > 5.0
    p = np.where(over, p * 5.0 / np.maximum(mag, 1e-12), p)
    q = np.where(over, q * 5.0 / np.maximum(mag, 1e-12), q)
    smooth = ndimage.uniform_filter(np.hypot(p, q), size=5, mode="nearest")
    thr = max(0.02, 3.0 * np.median(smooth))
    contact = ndimage.maximum_filter(smooth > thr, size=7, mode="nearest")
    h, w = p.shape
    gx = np.zeros((h, w))
    gy = np.zeros((h, w))
    cx = contact[:, :-1] | contact[:, 1:]
    cy = contact[:-1, :] | contact[1:, :]
    gx[:, :-1] = np.where(cx, 0.5 * (p[:, :-1] + p[:, 1:]) * k, 0.0)
    gy[:-1, :] = np.where(cy, 0.5 * (q[:-1, :] + q[1:, :]) * k, 0.0)
    f = np.zeros((h, w))
    f[:, 1:] += gx[:, :-1]
    f[:, :-1] -= gx[:, :-1]
    f[1:, :] += gy[:-1, :]
    f[:-1, :] -= gy[:-1, :]
    F = fft.dctn(f, type=2)
    mx = 2.0 - 2.0 * np.cos(np.pi * np.arange(w) / w)
    my = 2.0 - 2.0 * np.cos(np.pi * np.arange(h) / h)
    d = my[:, None] + mx[None, :]
    d[0, 0] = 1.0
    F /= d
    F[0, 0] = 0.0
    z = fft.idctn(F, type=2)
    base = np.median(z[~contact]) if (~contact).sum() * 10 >= z.size else z.min()
    return (z - base).astype(np.float32)


LIGHTS = {
    "mm_per_px": 0.025,
    "red": [0.0, 0.819152, 0.573576],
    "green": [-0.709406, -0.409576, 0.573576],
    "blue": [0.709406, -0.409576, 0.573576],
}


def make(out_dir):
    """A 2 mm ball pressed 0.8 mm into flat gel at 180 gray levels, 640x480."""
    w, h, k, r, press, flat = 640, 480, LIGHTS["mm_per_px"], 2.0, 0.8, 180.0
    y, x = np.mgrid[0:h, 0:w]
    rx, ry = (x - 300.0) * k, (y - 250.0) * k
    rho2 = rx**2 + ry**2
    inside = np.sqrt(np.maximum(r * r - rho2, 0.0)) - (r - press) > 0
    nz = np.sqrt(np.maximum(r * r - rho2, 0.0)) / r
    n = np.where(inside[..., None], np.stack([rx / r, ry / r, nz], -1), [0.0, 0.0, 1.0])
    L = np.array([LIGHTS["red"], LIGHTS["green"], LIGHTS["blue"]])
    img = flat * np.maximum(n @ L.T, 0.0) / L[:, 2]
    Image.fromarray(np.clip(np.round(img), 0, 255).astype(np.uint8)).save(f"{out_dir}/ball.png")
    Image.fromarray(np.full((h, w, 3), int(flat), np.uint8)).save(f"{out_dir}/background.png")
    with open(f"{out_dir}/lights.toml", "w") as fh:
        fh.write(f"mm_per_px = {LIGHTS['mm_per_px']}\n")
        for c in ("red", "green", "blue"):
            fh.write(f"{c} = {LIGHTS[c]}\n")


def main():
    if sys.argv[1] == "--make":
        make(sys.argv[2])
        return
    img_path, lights_path, bg_path, out = sys.argv[1:5]
    img = np.asarray(Image.open(img_path).convert("RGB"), dtype=np.float64)
    bg = np.asarray(Image.open(bg_path).convert("RGB"), dtype=np.float64)
    with open(lights_path, "rb") as fh:
        lights = tomllib.load(fh)
    t0 = time.perf_counter()
    z = depth(img, bg, lights)
    elapsed = time.perf_counter() - t0
    np.save(out, z)
    print(f"{elapsed:.6f}")


if __name__ == "__main__":
    main()
