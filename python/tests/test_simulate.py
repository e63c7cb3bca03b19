"""rollfuse.simulate against `rollfuse simulate`: the frames its PNGs hold, its height
map and its manifest's positions, equal."""

import numpy as np
import pytest

import rollfuse
from conftest import SCENES, read_png


@pytest.mark.parametrize("name,frames", [("letters", 5), ("spheres", 3)])
def test_frames_and_truth_equal_the_cli(simulated, name, frames):
    sim = simulated(name, frames)
    got = rollfuse.simulate(sim["scene"], frames=frames)
    want = np.stack([read_png(p) for p in sim["paths"]])
    assert got["frames"].dtype == np.uint8 and got["frames"].shape == want.shape
    assert np.array_equal(got["frames"], want)
    assert np.array_equal(got["height_mm"], np.load(sim["out"] / "truth" / "height.npy"))
    assert np.array_equal(got["ideal"], read_png(sim["out"] / "truth" / "ideal.png"))
    records = sim["manifest"]["frames"]
    for key in ("offset_mm", "actual_offset_mm", "strip_row", "actual_strip_row"):
        assert got[key].tolist() == [f[key] for f in records], key
    assert got["scene"] == sim["manifest"]["scene"] and got["seed"] == sim["manifest"]["seed"]


def test_a_dict_scene_is_read_as_its_file():
    tomllib = pytest.importorskip("tomllib")
    path = SCENES / "letters.toml"
    table = tomllib.loads(path.read_text())
    from_dict = rollfuse.simulate(table, frames=2, seed=5)
    from_file = rollfuse.simulate(path, frames=2, seed=5)
    assert np.array_equal(from_dict["frames"], from_file["frames"])
    assert from_dict["frames"].shape[0] == 2 and from_dict["seed"] == 5
    other_seed = rollfuse.simulate(path, frames=2, seed=6)
    assert not np.array_equal(other_seed["frames"], from_file["frames"]), "the seed moves the noise"


def test_bad_scenes_raise(tmp_path):
    with pytest.raises(OSError, match="cannot read scene file"):
        rollfuse.simulate(tmp_path / "none.toml")
    with pytest.raises(ValueError, match="scene must be a path"):
        rollfuse.simulate(42)
    with pytest.raises(ValueError):
        rollfuse.simulate({"effects": ["contact"], "object": {"kind": "nothing"}})
    with pytest.raises(ValueError):
        rollfuse.simulate(SCENES / "letters.toml", frames=0)
