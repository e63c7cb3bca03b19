"""rollfuse.fuse and fuse_pair against `rollfuse fuse` on the same frames: the 16-bit
output bit for bit, the offsets as it records them."""

import json
import warnings
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import rollfuse
from conftest import read_png


def cli_fuse(cli, paths, out: Path, *options: object) -> tuple:
    """`rollfuse fuse` of `paths` as a mosaic; its image and its offsets file."""
    cli("fuse", *paths, "--out", out, "--mode", "mosaic", *options)
    offsets = json.loads(out.with_suffix(".offsets.json").read_text())
    return read_png(out), offsets


@pytest.mark.parametrize(
    "align,wavelet,levels",
    [("none", "db2", 1), ("template", "db2", 1), ("template", "haar", 2), ("none", "db2", 3)],
)
def test_gray_frames_fuse_as_the_cli_bit_for_bit(cli, simulated, tmp_path, align, wavelet, levels):
    sim = simulated("letters", 5)
    paths = sim["paths"]
    want, record = cli_fuse(
        cli, paths, tmp_path / "f.png", "--align", align, "--wavelet", wavelet,
        "--levels", levels, "--out-bits", 16,
    )
    frames = np.stack([read_png(p) for p in paths])
    got, offsets = rollfuse.fuse(frames, align=align, wavelet=wavelet, levels=levels, out_dtype="uint16")
    assert got.dtype == np.uint16 and want.dtype == np.uint16
    assert got.shape == want.shape
    assert np.array_equal(got, want)
    assert offsets.shape == (len(paths), 2) and offsets.dtype == np.float64
    assert offsets.tolist() == [[f["at"]["dy"], f["at"]["dx"]] for f in record["frames"]]
    if align == "template":
        assert offsets[:, 0].max() > 0, "the frames moved along the belt"


def test_float_output_is_the_unrounded_fusion(simulated):
    frames = [read_png(p) for p in simulated("letters", 5)["paths"]]
    f32, _ = rollfuse.fuse(frames)
    u16, _ = rollfuse.fuse(frames, out_dtype="uint16")
    u8, _ = rollfuse.fuse(frames, out_dtype="uint8")
    assert f32.dtype == np.float32 and f32.ndim == 2
    assert np.abs(f32.astype(np.float64) * (65535 / 255) - u16).max() <= 0.5 + 1e-3
    assert np.abs(f32.astype(np.float64) - u8).max() <= 0.5 + 1e-4
    assert not np.array_equal(f32, np.round(f32)), "fusion leaves fractions of gray levels"


def test_motion_offsets_fuse_as_the_cli(cli, simulated, tmp_path):
    sim = simulated("letters", 5)
    want, record = cli_fuse(cli, sim["paths"], tmp_path / "m.png", "--align", "motion", "--out-bits", 16)
    rows = np.array([f["strip_row"] for f in sim["manifest"]["frames"]])
    frames = np.stack([read_png(p) for p in sim["paths"]])
    # The manifest's rows are positive: rounding half up is Rust's rounding there.
    got, offsets = rollfuse.fuse(frames, align="offsets", offsets=np.floor(rows + 0.5).astype(np.int64), out_dtype="uint16")
    assert np.array_equal(got, want)
    assert offsets[:, 0].tolist() == [f["at"]["dy"] for f in record["frames"]]


def test_rgb_and_16_bit_frames_fuse_as_the_cli(cli, simulated, tmp_path):
    sim = simulated("spheres", 4)
    want, _ = cli_fuse(cli, sim["paths"], tmp_path / "rgb.png", "--align", "none")
    frames = [read_png(p) for p in sim["paths"]]
    got, _ = rollfuse.fuse(frames, align="none", out_dtype="uint8")
    assert got.shape == want.shape and got.shape[2] == 3 and got.dtype == np.uint8
    assert np.array_equal(got, want)
    # 16-bit gray files: the CLI scales them by 255/65535 as the package does uint16.
    gray16 = [(read_png(p).astype(np.uint16) * 257 + k) for k, p in enumerate(simulated("letters", 5)["paths"][:3])]
    paths16 = []
    for k, g in enumerate(gray16):
        paths16.append(tmp_path / f"g16_{k}.png")
        Image.fromarray(g).save(paths16[-1])
    want16, _ = cli_fuse(cli, paths16, tmp_path / "f16.png", "--align", "none", "--out-bits", 16)
    got16, _ = rollfuse.fuse(np.stack(gray16), align="none", out_dtype="uint16")
    assert np.array_equal(got16, want16)


def test_the_integer_path_fuses_as_the_cli(cli, simulated, tmp_path):
    sim = simulated("letters", 5)
    want, _ = cli_fuse(cli, sim["paths"], tmp_path / "x.png", "--align", "none", "--precision", "fixed", "--out-bits", 16)
    got, _ = rollfuse.fuse([read_png(p) for p in sim["paths"]], align="none", precision="fixed", out_dtype="uint16")
    assert np.array_equal(got, want)


def test_a_flat_frame_is_left_out_with_a_warning_as_the_cli_does(cli, simulated, tmp_path):
    sim = simulated("letters", 5)
    frames = [read_png(p) for p in sim["paths"]]
    frames[2] = np.full_like(frames[2], 120)
    paths = []
    for k, f in enumerate(frames):
        paths.append(tmp_path / f"frame_{k}.png")
        Image.fromarray(f).save(paths[-1])
    want, record = cli_fuse(cli, paths, tmp_path / "skip.png", "--out-bits", 16)
    with pytest.warns(RuntimeWarning, match="skipped frame 2: no texture"):
        got, offsets = rollfuse.fuse(frames, out_dtype="uint16")
    assert np.array_equal(got, want)
    assert np.isnan(offsets[2]).all() and not np.isnan(np.delete(offsets, 2, 0)).any()
    assert len(record["skipped"]) == 1


def test_inputs_of_every_kind_give_one_result(simulated):
    frames = np.stack([read_png(p) for p in simulated("letters", 5)["paths"]])
    base, _ = rollfuse.fuse(frames, align="none")
    assert np.array_equal(rollfuse.fuse(list(frames), align="none")[0], base)
    assert np.array_equal(rollfuse.fuse(frames.astype(np.float32), align="none")[0], base)
    assert np.array_equal(rollfuse.fuse(tuple(frames.astype(np.float64)), align="none")[0], base)
    # A strided view reads as its contiguous copy.
    flipped = frames[:, ::-1, ::2]
    assert np.array_equal(
        rollfuse.fuse(flipped, align="none")[0],
        rollfuse.fuse(np.ascontiguousarray(flipped), align="none")[0],
    )
    # (H, W, 1) is gray.
    assert np.array_equal(rollfuse.fuse(frames[..., None], align="none")[0], base)


def test_fuse_pair_is_one_fuse_step(simulated):
    a, b = (read_png(p) for p in simulated("letters", 5)["paths"][:2])
    pair = rollfuse.fuse_pair(a, b, wavelet="haar", levels=2)
    assert pair.dtype == np.float32 and pair.shape == a.shape
    assert np.array_equal(pair, rollfuse.fuse([a, b], align="none", wavelet="haar", levels=2)[0])
    assert not np.array_equal(pair, a.astype(np.float32))


@pytest.mark.parametrize(
    "call,message",
    [
        (lambda f: rollfuse.fuse(f.astype(np.int32)), "uint8, uint16, float32 or float64, got an array of int32"),
        (lambda f: rollfuse.fuse(f[0]), r"shape \(N, H, W\)"),
        (lambda f: rollfuse.fuse(f[:1]), "at least two frames, got 1"),
        (lambda f: rollfuse.fuse([f[0], f[1, :50]]), "all must have one size"),
        (lambda f: rollfuse.fuse(f, levels=5), "levels must be 1..=4"),
        (lambda f: rollfuse.fuse(f, wavelet="db4"), "wavelet must be one of"),
        (lambda f: rollfuse.fuse(f, align="motion"), "align must be"),
        (lambda f: rollfuse.fuse(f, align="offsets"), "needs offsets"),
        (lambda f: rollfuse.fuse(f, align="offsets", offsets=np.zeros(2, np.int64)), "offsets has 2 rows for 5 frames"),
        (lambda f: rollfuse.fuse(f, template_rows=(0.6, 0.3)), "template_rows"),
        (lambda f: rollfuse.fuse(f, out_dtype="int8"), "out_dtype"),
        (lambda f: rollfuse.fuse(np.where(f > 100, np.nan, f.astype(np.float32))), "not finite"),
        (lambda f: rollfuse.fuse(f[:, :, :, None].repeat(2, axis=3)), r"\(H, W\) or \(H, W, 3\)"),
        (lambda f: rollfuse.fuse_pair(f[0], f[1, :10]), "one size"),
        # A canvas over the caller's limit, refused before it is allocated.
        (lambda f: rollfuse.fuse(f, align="none", max_pixels=1000), "larger than the limit of 1000"),
    ],
)
def test_bad_input_raises_value_error(simulated, call, message):
    frames = np.stack([read_png(p) for p in simulated("letters", 5)["paths"]])
    with pytest.raises(ValueError, match=message):
        call(frames)


def test_the_fused_canvas_covers_every_frame(simulated):
    frames = np.stack([read_png(p) for p in simulated("letters", 5)["paths"]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        img, offsets = rollfuse.fuse(frames, align="offsets", offsets=np.array([[0, 0], [10, 3], [20, 6], [30, 9], [40, 12]]))
    assert img.shape == (frames.shape[1] + 40, frames.shape[2] + 12)
    assert offsets.tolist() == [[0, 0], [10, 3], [20, 6], [30, 9], [40, 12]]


def test_max_pixels_bounds_the_canvas_not_the_frames(simulated):
    frames = np.stack([read_png(p) for p in simulated("letters", 5)["paths"]])
    h, w = frames.shape[1:3]
    offsets = np.array([[0, 0], [10, 0], [20, 0], [30, 0], [40, 0]])
    img, _ = rollfuse.fuse(frames, align="offsets", offsets=offsets, max_pixels=(h + 40) * w)
    assert img.shape == (h + 40, w)
    with pytest.raises(ValueError, match="larger than the limit"):
        rollfuse.fuse(frames, align="offsets", offsets=offsets, max_pixels=(h + 40) * w - 1)
