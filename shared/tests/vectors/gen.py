#!/usr/bin/env python3
"""Generates the PyWavelets reference vectors the f32 transforms are tested against.

    pip install PyWavelets numpy
    python3 shared/tests/vectors/gen.py > shared/tests/vectors/pywt_dwt2.json

Each case: a seeded random image, pywt.dwt2(x, w, mode='periodization') and
pywt.idwt2 of those coefficients cropped to the input size. The output is committed so
`cargo test` needs no Python.
"""
import json
import sys

import numpy as np
import pywt

SIZES = [(8, 8), (9, 7), (16, 12), (5, 3), (2, 2), (6, 1), (1, 5), (33, 20)]


def main():
    rng = np.random.default_rng(20261121)
    cases = []
    for wavelet in ("haar", "db2"):
        for (w, h) in SIZES:
            x = rng.uniform(0.0, 255.0, size=(h, w))
            ca, (ch, cv, cd) = pywt.dwt2(x, wavelet, mode="periodization")
            rec = pywt.idwt2((ca, (ch, cv, cd)), wavelet, mode="periodization")[:h, :w]
            cases.append({
                "wavelet": wavelet,
                "width": w,
                "height": h,
                "input": x.ravel().tolist(),
                "cA": ca.ravel().tolist(),
                "cH": ch.ravel().tolist(),
                "cV": cv.ravel().tolist(),
                "cD": cd.ravel().tolist(),
                "idwt2": rec.ravel().tolist(),
            })
    json.dump({"pywt_version": pywt.__version__, "cases": cases}, sys.stdout)


if __name__ == "__main__":
    main()
