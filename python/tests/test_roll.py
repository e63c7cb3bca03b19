"""rollfuse.fuse_roll against `rollfuse fuse --mode roll` on the same frames: the 16-bit
strip bit for bit, its first belt row, the placements as the frame report records them."""

import csv
import json
from pathlib import Path

import numpy as np
import pytest

import rollfuse
from conftest import read_png

ROLL_FRAMES = 12


def cli_roll(cli, paths, out: Path, *options: object) -> tuple:
    """`rollfuse fuse --mode roll` of `paths`: its strip (one segment), index and frame
    report."""
    cli("fuse", *paths, "--out", out, "--mode", "roll", "--out-bits", 16, *options)
    index = json.loads(out.with_suffix(".json").read_text())
    assert len(index["segments"]) == 1
    strip = read_png(out.parent / index["segments"][0]["file"])
    with open(out.with_suffix(".frames.csv")) as f:
        report = list(csv.DictReader(f))
    return strip, index, report


def geometry_of(manifest: dict) -> dict:
    """The roller geometry the command line reads from a manifest."""
    sensor = manifest["scene_file"]["sensor"]
    return {k: sensor[k] for k in ("roller_radius_mm", "press_depth_mm", "mm_per_px")}


@pytest.mark.parametrize("with_rows", [False, True])
def test_a_tracked_roll_fuses_as_the_cli_bit_for_bit(cli, simulated, tmp_path, with_rows):
    sim = simulated("letters", ROLL_FRAMES)
    manifest_rows = np.array([f["strip_row"] for f in sim["manifest"]["frames"]])
    # With --manifest the commanded rows predict each match; without, the manifest beside
    # the frames still gives the roller's geometry.
    options = ["--manifest", sim["out"] / "manifest.json"] if with_rows else []
    want, index, report = cli_roll(cli, sim["paths"], tmp_path / "roll.png", *options)
    frames = np.stack([read_png(p) for p in sim["paths"]])
    got, placements, summary = rollfuse.fuse_roll(
        frames,
        rows=manifest_rows if with_rows else None,
        geometry=geometry_of(sim["manifest"]),
        out_dtype="uint16",
    )
    assert got.dtype == np.uint16 and got.shape == want.shape
    assert np.array_equal(got, want)
    assert summary["first_row"] == index["segments"][0]["first_row"]
    details = index["details"]
    assert summary["window"] == (details["window"]["top"], details["window"]["rows"])
    assert summary["window_source"] == "geometry"
    assert summary["bands"] == details["summary"]["bands"]
    placement = details["placement"]
    assert (summary["matched"], summary["predicted"]) == (placement["matched"], placement["predicted"])
    assert summary["trusted"] == details["trusted"]
    assert placements["source"] == [r["source"] for r in report]
    assert np.allclose(placements["row"], [float(r["row"]) for r in report], atol=5e-4)
    assert placements["col"].tolist() == [int(r["col"]) for r in report]
    assert np.isnan(placements["score"][0]) and (placements["score"][1:] > 0).all()
    assert got.shape[0] > frames.shape[1], "the strip is longer than a frame"


def test_rows_as_given_fuse_as_the_cli_motion_alignment(cli, simulated, tmp_path):
    sim = simulated("letters", ROLL_FRAMES)
    want, index, _ = cli_roll(cli, sim["paths"], tmp_path / "m.png", "--align", "motion")
    rows = np.array([f["strip_row"] for f in sim["manifest"]["frames"]])
    frames = [read_png(p) for p in sim["paths"]]
    got, placements, summary = rollfuse.fuse_roll(
        frames, align="motion", rows=rows, geometry=geometry_of(sim["manifest"]), out_dtype="uint16"
    )
    assert np.array_equal(got, want)
    assert summary["first_row"] == index["segments"][0]["first_row"]
    assert placements["row"].tolist() == rows.tolist()
    assert set(placements["source"]) == {"manifest"}


def test_a_simulated_roll_fuses_without_files_as_from_its_pngs(cli, simulated):
    sim = simulated("letters", ROLL_FRAMES)
    made = rollfuse.simulate(sim["scene"], frames=ROLL_FRAMES)
    # What the notebook does: simulate, then fuse the roll with the truth's rows and geometry.
    got, _, summary = rollfuse.fuse_roll(
        made["frames"], rows=made["strip_row"], geometry=made["geometry"]
    )
    from_files, _, _ = rollfuse.fuse_roll(
        [read_png(p) for p in sim["paths"]],
        rows=np.array([f["strip_row"] for f in sim["manifest"]["frames"]]),
        geometry=geometry_of(sim["manifest"]),
    )
    assert got.dtype == np.float32 and np.array_equal(got, from_files)
    assert made["geometry"]["apex_row"] == made["frames"].shape[1] / 2
    # The strip covers the truth's rows from its first: the fused letters lie where the
    # ideal image has them.
    ideal = made["ideal"].astype(np.float64)
    first = summary["first_row"]
    rows = min(got.shape[0], ideal.shape[0] - first)
    a, b = got[:rows].astype(np.float64), ideal[first : first + rows]
    assert np.corrcoef(a.ravel(), b.ravel())[0, 1] > 0.5


def test_the_window_and_bands_can_be_set_and_are_checked(simulated):
    frames = np.stack([read_png(p) for p in simulated("letters", ROLL_FRAMES)["paths"]])
    _, _, summary = rollfuse.fuse_roll(frames, window_rows=40, band_rows=16, blend_rows=4)
    assert summary["window_source"] == "window_rows" and summary["window"][1] <= 40
    _, _, measured = rollfuse.fuse_roll(frames)
    assert measured["window_source"] in ("measured", "default")
    bad = [
        (dict(window_rows=0), "window_rows must be at least 1"),
        (dict(blend_rows=5), "cannot be cross-faded"),
        (dict(align="motion"), "align='motion' needs rows="),
        (dict(align="sideways"), "align must be one of 'template', 'motion'"),
        (dict(rows=np.zeros(3)), f"rows has 3 values for {ROLL_FRAMES} frames"),
        (dict(min_score=2.0), "min_score must be in 0..=1"),
        (dict(geometry={"mm_per_px": 0.05}), "geometry has no 'roller_radius_mm'"),
        (dict(levels=4, band_rows=64), "too short for bands"),
    ]
    for kwargs, message in bad:
        with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
            rollfuse.fuse_roll(frames, **kwargs)
    with pytest.raises(ValueError, match=r"must be an array of shape \(N, H, W\)"):
        rollfuse.fuse_roll(frames[:, 0])


def test_a_belt_that_jumps_is_refused_with_the_rows_named(simulated):
    sim = simulated("letters", ROLL_FRAMES)
    frames = np.stack([read_png(p) for p in sim["paths"]])
    rows = np.array([f["strip_row"] for f in sim["manifest"]["frames"]])
    rows[6:] += 10_000  # the second half far down the belt: nothing covers the rows between
    with pytest.raises(ValueError, match="the belt jumps from row"):
        rollfuse.fuse_roll(frames, align="motion", rows=rows)
