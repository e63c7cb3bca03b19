"""rollfuse.dwt2/idwt2 against PyWavelets' periodization: the committed reference vectors
(shared/tests/vectors/pywt_dwt2.json, made by PyWavelets), and PyWavelets itself where it
is installed."""

import json

import numpy as np
import pytest

import rollfuse
from conftest import REPO

CASES = json.loads((REPO / "shared" / "tests" / "vectors" / "pywt_dwt2.json").read_text())["cases"]


@pytest.mark.parametrize("case", CASES, ids=lambda c: f"{c['wavelet']}-{c['width']}x{c['height']}")
def test_dwt2_and_idwt2_match_pywavelets_vectors(case):
    h, w = case["height"], case["width"]
    x = np.array(case["input"]).reshape(h, w)
    ca, (ch, cv, cd) = rollfuse.dwt2(x, case["wavelet"])
    bands = {"cA": ca, "cH": ch, "cV": cv, "cD": cd}
    for name, band in bands.items():
        assert band.dtype == np.float32 and band.shape == ((h + 1) // 2, (w + 1) // 2)
        np.testing.assert_allclose(band.ravel(), case[name], rtol=1e-5, atol=2e-4, err_msg=name)
    rec = rollfuse.idwt2((ca, (ch, cv, cd)), case["wavelet"])
    assert rec.shape == (2 * ((h + 1) // 2), 2 * ((w + 1) // 2))
    np.testing.assert_allclose(rec[:h, :w].ravel(), case["idwt2"], rtol=1e-5, atol=2e-4)


def test_against_pywavelets_itself():
    pywt = pytest.importorskip("pywt")
    x = np.random.default_rng(7).uniform(0, 255, (37, 52))
    for wavelet in ("haar", "db2"):
        want = pywt.dwt2(x, wavelet, mode="periodization")
        got = rollfuse.dwt2(x.astype(np.float32), wavelet)
        np.testing.assert_allclose(got[0], want[0], atol=2e-3)
        for g, wnt in zip(got[1], want[1]):
            np.testing.assert_allclose(g, wnt, atol=2e-3)


def test_bad_input_raises():
    with pytest.raises(ValueError, match="must be 2-D"):
        rollfuse.dwt2(np.zeros((2, 3, 4)))
    with pytest.raises(ValueError, match="wavelet must be one of"):
        rollfuse.dwt2(np.zeros((4, 4)), "sym4")
    with pytest.raises(ValueError, match="one shape"):
        z = np.zeros((2, 2))
        rollfuse.idwt2((z, (z, z, np.zeros((3, 2)))))
    with pytest.raises(ValueError, match=r"\(cA, \(cH, cV, cD\)\)"):
        rollfuse.idwt2((np.zeros((2, 2)),))
