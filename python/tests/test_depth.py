"""rollfuse.depth, calibrate and Lights against `rollfuse depth` and `rollfuse calibrate`:
the float32 height map bit for bit, the light file to the byte."""

import numpy as np
import pytest

import rollfuse
from conftest import read_png


@pytest.fixture(scope="module")
def spheres(simulated):
    return simulated("spheres", 16)


def test_depth_matches_the_cli_bit_for_bit(cli, spheres, tmp_path):
    frame = spheres["paths"][7]
    lights_file = spheres["out"] / "lights.toml"
    cli("depth", frame, "--lights", lights_file, "--out", tmp_path / "d")
    want = np.load(tmp_path / "d.npy")
    got = rollfuse.depth(read_png(frame), rollfuse.Lights.load(lights_file))
    assert got.dtype == np.float32 and want.dtype == np.float32
    assert got.shape == want.shape == read_png(frame).shape[:2]
    assert np.array_equal(got, want)
    assert got.max() > 0.1, "a sphere is pressed in this frame"


def test_depth_with_a_background_matches_the_cli(cli, spheres, tmp_path):
    frame, background = spheres["paths"][7], spheres["paths"][0]
    lights_file = spheres["out"] / "lights.toml"
    cli("depth", frame, "--lights", lights_file, "--background", background, "--out", tmp_path / "b")
    got = rollfuse.depth(read_png(frame), rollfuse.Lights.load(lights_file), background=read_png(background))
    assert np.array_equal(got, np.load(tmp_path / "b.npy"))


def test_simulated_lights_are_the_light_file(spheres):
    sim = rollfuse.simulate(spheres["scene"], frames=2)
    assert sim["lights"] == rollfuse.Lights.load(spheres["out"] / "lights.toml")


def test_calibrate_writes_the_cli_light_file(cli, spheres, tmp_path):
    frame = spheres["paths"][7]
    out = cli("calibrate", frame, "--radius-mm", 2, "--mm-per-px", 0.05, "--out", tmp_path / "l.toml")
    lights, (x, y, r) = rollfuse.calibrate(read_png(frame), radius_mm=2, mm_per_px=0.05)
    assert lights.to_toml() == (tmp_path / "l.toml").read_text()
    assert f"contact disc at ({x:.1f}, {y:.1f}), radius {r:.1f} px" in out
    lights.save(tmp_path / "again.toml")
    assert rollfuse.Lights.load(tmp_path / "again.toml") == lights


def test_lights_values_and_checks():
    l = rollfuse.Lights.product(0.05)
    assert l.mm_per_px == 0.05 and len(l.red) == 3 and list(l.gains) == [1.0, 1.0, 1.0]
    assert rollfuse.Lights(0.05, l.red, l.green, l.blue) == l
    assert 1.0 <= l.condition() < 30.0
    with pytest.raises(ValueError):
        rollfuse.Lights(0.05, l.red, l.red, l.blue)


def test_bad_input_raises(spheres, tmp_path):
    lights = rollfuse.Lights.load(spheres["out"] / "lights.toml")
    with pytest.raises(ValueError, match="gray"):
        rollfuse.depth(np.zeros((40, 50), np.uint8), lights)
    with pytest.raises(ValueError, match="uint8, uint16, float32 or float64"):
        rollfuse.depth([[1, 2], [3, 4]], lights)
    with pytest.raises(OSError, match="cannot read light file"):
        rollfuse.Lights.load(tmp_path / "missing.toml")
    (tmp_path / "bad.toml").write_text("mm_per_px = 'x'\n")
    with pytest.raises(ValueError, match="not a valid light file"):
        rollfuse.Lights.load(tmp_path / "bad.toml")
    with pytest.raises(ValueError, match="circle"):
        rollfuse.calibrate(np.zeros((40, 50, 3), np.uint8), radius_mm=2, mm_per_px=0.05, circle=(1, 2, -3))
