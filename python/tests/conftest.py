"""Shared fixtures: the ``rollfuse`` command line the results are compared against, and
small scenes it simulates once per session."""

import json
import os
import shutil
import subprocess
from pathlib import Path
from typing import Callable, Dict

import numpy as np
import pytest
from PIL import Image

REPO = Path(__file__).resolve().parents[2]
SCENES = REPO / "host" / "scenes"


def _find_cli() -> Path:
    """The built ``rollfuse`` binary: $ROLLFUSE_CLI, else target/{debug,release}/rollfuse
    (the newer), else one on PATH."""
    given = os.environ.get("ROLLFUSE_CLI")
    if given:
        return Path(given)
    target = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    built = [p for p in (target / "debug" / "rollfuse", target / "release" / "rollfuse") if p.is_file()]
    if built:
        return max(built, key=lambda p: p.stat().st_mtime)
    on_path = shutil.which("rollfuse")
    if on_path:
        return Path(on_path)
    raise RuntimeError("no rollfuse binary: run `cargo build` or set ROLLFUSE_CLI")


@pytest.fixture(scope="session")
def cli() -> Callable[..., str]:
    """Runs the command line with the given arguments; returns its standard output."""
    exe = _find_cli()

    def run(*args: object) -> str:
        done = subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        return done.stdout

    return run


def read_png(path: Path) -> np.ndarray:
    """A PNG's samples as stored: uint8, or uint16 for 16-bit gray."""
    with Image.open(path) as im:
        return np.array(im)


def _small_scene(name: str, tmp: Path, size: str) -> Path:
    """host/scenes/NAME.toml at a smaller size (w×h), so a debug build is quick."""
    w, h = size.split("x")
    lines = []
    for line in (SCENES / f"{name}.toml").read_text().splitlines():
        key = line.split("=")[0].strip()
        if key == "width_px":
            line = f"width_px = {w}"
        elif key == "height_px":
            line = f"height_px = {h}"
        lines.append(line)
    out = tmp / f"{name}_{size}.toml"
    out.write_text("\n".join(lines) + "\n")
    return out


@pytest.fixture(scope="session")
def simulated(tmp_path_factory: pytest.TempPathFactory, cli: Callable[..., str]) -> Callable[..., Dict]:
    """Simulates a scene with the command line once a session: its scene file, output
    folder, manifest and frame paths."""
    cache: Dict[tuple, Dict] = {}

    def get(name: str, frames: int, size: str = "160x120") -> Dict:
        key = (name, frames, size)
        if key not in cache:
            tmp = tmp_path_factory.mktemp(f"{name}_{frames}")
            scene = _small_scene(name, tmp, size)
            out = tmp / "sim"
            cli("simulate", scene, "--out", out, "--frames", frames)
            manifest = json.loads((out / "manifest.json").read_text())
            paths = [out / f["file"] for f in manifest["frames"]]
            cache[key] = {"scene": scene, "out": out, "manifest": manifest, "paths": paths}
        return cache[key]

    return get
