"""The window as a class sees it (issue 43): screenshots of hidden GGUI windows at 1024 x 768, 1280 x 720 and
1920 x 1080 for the scenes a class starts with. Each shows the headless renderer's picture right of the panel (whose
layout keeps the band's text and charts off the scene, tests/test_picture_layout.py), every particle lies right of
the panel and below the band, and a particle's colour read against the colour bar gives its temperature. (That the
window shows the headless renderer's picture is tested in tests/test_window.py.)"""

import subprocess
import sys

import numpy as np
import pytest

from sandbox.config.scene import load_scene
from sandbox.render.video import read_png
from sandbox.simulation import Simulation

from .conftest import ROOT, SCENES

pytestmark = pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)

SCENES_FOR_A_CLASS = ("sandbox", "melting_block", "ice_cube", "candle")
SIZES = ((1024, 768), (1280, 720), (1920, 1080))
FRAMES = 3

SCRIPT = """
import sys
from sandbox.app.controller import open_scene
from sandbox.app.window import run_window
out, frames = sys.argv[1], int(sys.argv[2])
for name in sys.argv[3].split(","):
    sim = open_scene(name)  # a fresh runtime per scene, as the scene picker does
    for size in sys.argv[4].split(","):
        w, h = map(int, size.split("x"))
        sim.reset()  # each window from the scene's start
        run_window(sim, frames=frames, screenshot=f"{out}/{name}_{w}x{h}.png", show=False, steady=False, size=(w, h))
print("done")
"""


@pytest.fixture(scope="module")
def screenshots(tmp_path_factory):
    out = tmp_path_factory.mktemp("screens")
    sizes = ",".join(f"{w}x{h}" for w, h in SIZES)
    args = [sys.executable, "-c", SCRIPT, str(out), str(FRAMES), ",".join(SCENES_FOR_A_CLASS), sizes]
    proc = subprocess.run(args, capture_output=True, text=True, cwd=ROOT, timeout=900)
    if "Vulkan must be available" in proc.stdout + proc.stderr:
        pytest.skip("no Vulkan driver: apt-get install mesa-vulkan-drivers libvulkan1 (.ci/run does)")
    assert proc.returncode == 0 and "done" in proc.stdout, proc.stderr[-2000:]
    return out


def after_the_windows_frames(name: str):
    """The simulation after the window's frames (fixed substeps, as run_window with steady=False)."""
    sim = Simulation(load_scene(SCENES / f"{name}.toml"))
    for _ in range(FRAMES):
        sim.advance_frame()
    return sim


def window_plan(sim, size: tuple[int, int]):
    """Where the window put things: the picture plan of the window's renderer (its panel, its band for charts)."""
    from sandbox.app.window_panel import PANEL_WIDTH
    from sandbox.app.window_state import make_state, view_config
    from sandbox.render.plan import plan_picture

    view = view_config(sim.scene.render, make_state(sim, None))
    return plan_picture(sim.model, sim.state, *size, view, round(PANEL_WIDTH * size[0]), room_for_charts=True)


@pytest.mark.parametrize("name", SCENES_FOR_A_CLASS)
def test_the_window_shows_the_scene_clear_of_panel_band_and_charts_at_every_size(screenshots, name):
    sim = after_the_windows_frames(name)
    n = int(sim.state.particles.n[None])
    x = sim.state.particles.x.to_numpy()[:n]
    for size in SIZES:
        width, height = size
        img = read_png(screenshots / f"{name}_{width}x{height}.png")
        assert img.shape[:2] == (height, width)
        plan = window_plan(sim, size)
        px = plan.pixels(x)
        r = sim.state.particles.radius.to_numpy()[:n] * plan.view[0]
        panel, band = plan.layout.panel_px, plan.layout.band
        assert (px[:, 0] - r >= panel - 1).all() and (px[:, 0] + r <= width + 1).all(), (name, size)
        assert (px[:, 1] - r >= band - 1).all() and (px[:, 1] + r <= height + 1).all(), (name, size)
        # the picture right of the panel is the scene's: below the band, what is drawn there is particles and
        # backdrop, not text (the band's items are tested to stay in the band, tests/test_picture_layout.py)
        below = img[band:, panel + 2 :, :3].astype(int)
        assert below.std() > 3 or n == 0
        if sim.scene.render.color_by == "temperature" and n:
            check_colours_read_back(sim, plan, img, px)


def check_colours_read_back(sim, plan, img, px) -> None:
    """Under the centre of each body particle (not the emitted flame, which adds light), the screenshot's colour
    nearest on the bar gives the particle's temperature within one bar step (64 steps)."""
    lo, hi = sim.scene.render.temperature_range
    steps = 64
    bar = plan.overlays.legend_colors(steps) * 255
    n = len(px)
    temps = sim.state.particles.T.to_numpy()[:n]
    groups = sim.state.particles.group.to_numpy()[:n]
    bodies = len(sim.scene.bodies)
    brush = np.array([0.5 * plan.layout.width, 0.5 * plan.layout.height])  # the tool's ring at the hidden cursor
    checked = 0
    for k in np.flatnonzero(groups < bodies)[::7]:
        x, row = int(px[k, 0]), int(px[k, 1])
        if np.hypot(*(px[k] - brush)) < 60:
            continue
        nearest = np.argmin(((bar - img[row, x, :3]) ** 2).sum(axis=1))
        read = lo + (hi - lo) * nearest / (steps - 1)
        assert abs(read - np.clip(temps[k], lo, hi)) <= (hi - lo) / (steps - 1) * 1.5, (k, read, temps[k])
        checked += 1
    assert checked > 20
