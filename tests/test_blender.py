"""examples/blender_load.py (issue 76, item 4): a cached sequence loaded into Blender as an animation renders with the
sandbox's own colours. Debian's Blender 3.4 (`blender` on the PATH: PLY only, it has no USD) and PyPI's bpy (the
interpreter named by $BPY_PYTHON, or this one where it imports bpy: PLY and USD) each render a frame of a block
whose left end is 20 C and right end 200 C through the cache's camera, which is the pictures' camera: at the
particles' centres the hottest and coldest tenth are within 10 levels of the sandbox's own picture, pixel for pixel.
Each runner is skipped where it is not installed."""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import sandbox

pytestmark = [pytest.mark.long, pytest.mark.xdist_group("export")]

SCRIPT = Path(__file__).parents[1] / "examples" / "blender_load.py"
WIDTH, HEIGHT = 480, 270
BARE = {"title": False, "clock": False, "legend": False, "chart": []}


def bpy_python() -> str | None:
    """An interpreter that imports bpy: $BPY_PYTHON, or this one."""
    named = os.environ.get("BPY_PYTHON")
    if named:
        return named
    return sys.executable if importlib.util.find_spec("bpy") is not None else None


RUNNERS = {
    "blender-ply": (["blender", "-b", "--factory-startup", "-P", str(SCRIPT), "--"], shutil.which("blender"), "ply"),
    "bpy-ply": ([bpy_python() or "", str(SCRIPT)], bpy_python(), "ply"),
    "bpy-usd": ([bpy_python() or "", str(SCRIPT)], bpy_python(), "usd"),
}


@pytest.fixture(scope="module")
def block(tmp_path_factory):
    """melting_block, cold at its left and hot at its right, cached in PLY and USD at frames 0 and 2 (the render is
    of frame 0); the sandbox's own picture of frame 0, and each particle's pixel in it."""
    folder = tmp_path_factory.mktemp("blender")
    sim = sandbox.load("melting_block", arch="cpu")
    x = sim.positions()[:, 0]
    sim.set_temperatures(20.0 + 180.0 * (x - x.min()) / (x.max() - x.min()))
    picture = sim.picture(WIDTH, HEIGHT, **BARE)
    painter = sim._picture_renderer[1].painter
    pixels = np.asarray(painter.offset.to_list()) + painter.px_per_unit * sim.particles()["position"]
    temperature = sim.particles()["temperature"]
    with sandbox.Cache(folder / "block.ply") as ply, sandbox.Cache(folder / "block.usd") as usd:
        for _ in range(2):
            ply.write(sim), usd.write(sim)
            sim.run(2)
    return folder, picture, pixels, temperature


@pytest.mark.parametrize("runner", RUNNERS)
def test_a_loaded_sequence_renders_in_the_sandboxs_colours(block, tmp_path, runner):
    command, found, kind = RUNNERS[runner]
    if found is None:
        pytest.skip(f"{runner}: not installed (apt-get install blender; python3 -m pip install bpy, $BPY_PYTHON)")
    folder, picture, pixels, temperature = block
    out = tmp_path / "render.png"
    args = [str(folder / f"block.{kind}"), "--render", str(out), "--frame", "0", "--look", "flat"]
    done = subprocess.run(
        [*command, *args, "--height", str(HEIGHT)], capture_output=True, text=True, timeout=600, cwd=tmp_path
    )
    assert done.returncode == 0 and out.exists(), done.stdout[-2000:] + done.stderr[-2000:]
    assert "loaded" in done.stdout and "frames 0 to 2" in done.stdout
    from PIL import Image

    render = np.asarray(Image.open(out).convert("RGB"), dtype=int)
    assert render.shape == picture.shape
    col = np.floor(pixels[:, 0]).astype(int)
    row = HEIGHT - 1 - np.floor(pixels[:, 1]).astype(int)
    inside = (row > 2) & (row < HEIGHT - 3) & (col > 2) & (col < WIDTH - 3)  # not the picture's edge
    cold = inside & (temperature <= np.quantile(temperature, 0.1))
    hot = inside & (temperature >= np.quantile(temperature, 0.9))
    assert cold.sum() > 20 and hot.sum() > 20
    for end in (cold, hot):
        apart = np.abs(render[row[end], col[end]] - picture[row[end], col[end]].astype(int)).max(axis=1)
        assert np.median(apart) <= 10 and np.quantile(apart, 0.9) <= 10, np.quantile(apart, [0.5, 0.9, 1.0])
    blue_minus_red = picture[row[cold], col[cold], 2].astype(int) - picture[row[cold], col[cold], 0]
    assert blue_minus_red.mean() > 50  # the ends are the colour map's: blue at 20 C
