"""rollfuse.stream and rollfuse.replay against `rollfuse stream`: the same tiles, strip
and manifest from the virtual device and from a recording played back."""

import json
from pathlib import Path

import numpy as np
import pytest

import rollfuse
from conftest import read_png


def tiles_strip(tiles: list) -> np.ndarray:
    """The tiles in index order, stacked: the strip when none is missing."""
    ordered = sorted(tiles, key=lambda t: t["index"])
    assert [t["index"] for t in ordered] == list(range(ordered[0]["index"], ordered[-1]["index"] + 1))
    return np.concatenate([t["pixels"] for t in ordered])


@pytest.fixture(scope="module")
def recorded(tmp_path_factory, simulated, cli):
    """`rollfuse stream --device sim` of a small scene, recorded: its folder and recording."""
    scene = simulated("letters", 12)["scene"]
    tmp = tmp_path_factory.mktemp("stream")
    cli("stream", "--device", "sim", "--scene", scene, "--out", tmp / "cli", "--record", tmp / "rec.bin")
    return {"scene": scene, "out": tmp / "cli", "recording": tmp / "rec.bin", "tmp": tmp}


def test_the_virtual_device_streams_the_cli_tiles(recorded, tmp_path):
    s = rollfuse.stream("sim", scene=recorded["scene"], out=tmp_path / "py")
    tiles = list(s)
    assert tiles and all(t["pixels"].dtype == np.uint8 and t["pixels"].ndim == 2 for t in tiles)
    want = read_png(recorded["out"] / "strip.png")
    assert np.array_equal(tiles_strip(tiles), want)
    assert s.stop_reason == "device stopped"
    assert s.manifest == json.loads((recorded["out"] / "manifest.json").read_text())
    assert [Path(f).name for f in s.strip_files] == ["strip.png"]
    assert np.array_equal(read_png(Path(s.strip_files[0])), want)
    assert s.skipped == 0
    # The module's defaults, named in the manifest by the tiles they made.
    [configured] = s.manifest["configurations"]
    assert configured["config"]["wavelet"] == "Db2"
    assert (configured["config"]["levels"], configured["config"]["downsample"]) == (1, 1)
    assert configured["tile_size"] == [want.shape[1], 16] == s.manifest["tile_size"]


def test_a_recording_plays_back_as_it_was_received(recorded):
    s = rollfuse.replay(recorded["recording"])
    tiles = list(s)
    assert np.array_equal(tiles_strip(tiles), read_png(recorded["out"] / "strip.png"))
    assert s.stop_reason == "device stopped", "the recording holds the final status"
    assert s.manifest["tiles_received"] == len(tiles)
    # Without `out` the session's folder is a temporary one, there while the stream is.
    assert Path(s.out).is_dir() and Path(s.strip_files[0]).is_file()
    folder = Path(s.out)
    del s
    assert not folder.exists()


def test_a_tile_limit_stops_the_device_and_its_flush_arrives(recorded):
    s = rollfuse.stream("sim", scene=recorded["scene"], tiles=2)
    tiles = list(s)
    assert s.stop_reason == "tiles"
    assert len(tiles) >= 2 and s.manifest["device_stopped"]
    assert s.manifest["tiles_received"] == len(tiles)


def test_a_reader_that_stops_early_leaves_the_session_to_end(recorded, tmp_path):
    s = rollfuse.stream("sim", scene=recorded["scene"], out=tmp_path / "early")
    first = next(s)
    assert first["pixels"].shape[0] == 16
    s.stop_streaming()
    rest = list(s)
    assert s.stop_reason in ("device stopped", "tiles")
    assert s.manifest["tiles_received"] == 1 + len(rest)


def test_bad_options_raise_with_the_cli_messages(recorded, tmp_path):
    cases = [
        (dict(device="bluetooth"), ValueError, "--device must be usb, sim or replay:FILE"),
        (dict(device="sim"), ValueError, "--device sim needs --scene"),
        (dict(device="sim", scene=recorded["scene"], tiles=0), ValueError, "--tiles must be at least 1"),
        (dict(device="sim", scene=recorded["scene"], wavelet="sym4"), ValueError, "wavelet must be one of"),
        (dict(device="replay:" + str(tmp_path / "none.bin")), OSError, "none.bin"),
        (dict(device="sim", scene=recorded["scene"], downsample=1, levels=2, tile_rows=64,
              frames_per_tile=8), ValueError, "the device refused"),
    ]
    for kwargs, error, message in cases:
        with pytest.raises(error, match=message):
            list(rollfuse.stream(**kwargs))


def test_a_recording_played_back_into_records_is_one_roll_however_often(recorded, tmp_path, cli):
    db = tmp_path / "records.db"
    for _ in range(2):
        s = rollfuse.stream(f"replay:{recorded['recording']}", out=tmp_path / "roll",
                            records=str(db), line="7", segment_rows=64)
        tiles = list(s)
    rolls = json.loads(cli("rolls", "list", "--records", db, "--json"))
    assert [(r["line"], r["status"]) for r in rolls] == [("7", "complete")]
    assert rolls[0]["segments"] == len(s.strip_files) > 1
    assert rolls[0]["belt_rows"] == 16 * len(tiles)
