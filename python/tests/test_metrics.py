"""rollfuse.metrics against `rollfuse metrics --json`: every figure equal."""

import json

import numpy as np
import pytest
from PIL import Image

import rollfuse
from conftest import read_png


@pytest.mark.parametrize("axis,strips", [("rows", 10), ("columns", 4)])
def test_metrics_equal_the_cli(cli, simulated, axis, strips):
    sim = simulated("letters", 5)
    frame, ideal = sim["paths"][2], sim["out"] / "truth" / "ideal.png"
    img = read_png(frame)
    # The ideal image spans the whole strip: its first rows make a reference of one size.
    ref = read_png(ideal)[: img.shape[0]]
    ref_path = sim["out"] / f"ref_{axis}.png"
    Image.fromarray(ref).save(ref_path)
    want = json.loads(cli("metrics", frame, "--reference", ref_path, "--json", "--strips", strips, "--axis", axis))
    got = rollfuse.metrics.strip_std(img, ref, strips=strips, axis=axis)
    assert got == want
    assert rollfuse.metrics.ie(img) == want["ie"]
    assert rollfuse.metrics.ms_ssim(img, ref) == want["ms_ssim"]
    alone = rollfuse.metrics.strip_std(img, strips=strips, axis=axis)
    assert alone["ms_ssim"] is None and alone["ie_std"] == want["ie_std"]


def test_rgb_and_float_images(cli, simulated):
    frame = simulated("spheres", 16)["paths"][7]
    want = json.loads(cli("metrics", frame, "--json"))
    rgb = read_png(frame)
    assert rollfuse.metrics.ie(rgb) == want["ie"]
    assert rollfuse.metrics.ie(rgb.astype(np.float64)) == want["ie"]


def test_bad_input_raises():
    with pytest.raises(ValueError, match="at least 11×11"):
        rollfuse.metrics.ms_ssim(np.zeros((8, 8), np.uint8), np.zeros((8, 8), np.uint8))
    with pytest.raises(ValueError, match="reference is"):
        rollfuse.metrics.ms_ssim(np.zeros((20, 20), np.uint8), np.zeros((20, 21), np.uint8))
    with pytest.raises(ValueError, match="strips"):
        rollfuse.metrics.strip_std(np.zeros((20, 20), np.uint8), strips=0)
    with pytest.raises(ValueError, match="axis must be one of"):
        rollfuse.metrics.strip_std(np.zeros((20, 20), np.uint8), axis="diagonal")
