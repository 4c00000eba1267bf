"""Rendering: each technique's defining property, computed on the image, and golden images with a tolerance.

Regenerate the stored images after an intended change with `python3 -m pytest tests/test_render.py --regen-golden`.
"""

import math

import numpy as np
import pytest

from sandbox.config.scene import load_scene
from sandbox.render.raster import Renderer
from sandbox.render.video import read_png, write_png
from sandbox.simulation import Simulation

from .conftest import ROOT, SCENES, make_scene, scene_dict

GOLDEN = ROOT / "tests" / "golden"


BARE = {"frame": "domain", "title": False, "clock": False, "legend": False}  # no top band, no content framing


def dot_scene(bodies, dim=2, render=None, hi=100.0):
    data = scene_dict(
        dim=dim,
        world={"dim": dim, "lo": [0.0] * dim, "hi": [hi] * dim, "dt": 0.001},
        materials={
            "red": {"based_on": "jelly", "color": [1.0, 0.0, 0.0]},
            "blue": {"based_on": "jelly", "color": [0.0, 0.0, 1.0]},
        },
        bodies=bodies,
        # the whole box, filling the picture: the geometry tests place particles by the domain
        render={"color_by": "material", "background": [0.0, 0.0, 0.0], **BARE, **(render or {})},
    )
    return Simulation(make_scene(data))


def splat_light(ren):
    """Splat a 2D frame and return (the additive light before tone mapping, the finished image)."""
    ren.painter.draw()
    light = ren.canvas.light.to_numpy().copy()
    ren.painter.composite(1, ren.out)  # composites, writes the 8-bit picture and zeroes the accumulators
    return light, ren.image.to_numpy()


def one(at, material="red", spacing=1.0, **style):
    """A body of exactly one particle at `at` (any dimension)."""
    lo = [c - 0.5 * spacing for c in at]
    hi = [c + 0.5 * spacing for c in at]
    return {"material": material, "shape": "box", "lo": lo, "hi": hi, "spacing": spacing, "springs": False, **style}


def test_additive_light_adds_up():
    single = dot_scene([one([50.0, 50.0], blend="additive")])
    light1, img1 = splat_light(Renderer(single.model, single.state, 100, 100, single.scene.render))
    double = dot_scene([one([50.0, 50.0], blend="additive"), one([50.0, 50.0], blend="additive")])
    light2, img2 = splat_light(Renderer(double.model, double.state, 100, 100, double.scene.render))
    assert np.allclose(light2, 2 * light1, rtol=1e-6)
    assert light1.sum() > 0
    # tone mapping saturates gracefully: brighter, never past white, never clipped flat at the centre
    assert img2.max() <= 1.0 and np.all(img2 >= img1 - 1e-7) and img2[..., 0].max() > img1[..., 0].max()


@pytest.mark.parametrize("x", [50.0, 50.37, 50.81])
def test_sub_pixel_additive_particle_deposits_its_full_intensity(x):
    # radius 0.05 units = 0.049 px: far below a pixel; the energy opacity * pi r^2 lands whole wherever it falls
    sim = dot_scene([one([x, 50.3], spacing=0.1, blend="additive", opacity=5.0)])
    ren = Renderer(sim.model, sim.state, 100, 100, sim.scene.render)
    light, _ = splat_light(ren)
    r_px = 0.05 * ren.painter.px_per_unit
    assert light[..., 0].sum() == pytest.approx(5.0 * math.pi * r_px**2, rel=1e-5)


def test_small_opaque_particles_fade_rather_than_vanish():
    sim = dot_scene([one([50.4, 50.6], spacing=0.2)])
    ren = Renderer(sim.model, sim.state, 100, 100, sim.scene.render)
    ren.render()
    red = ren.image.to_numpy()[5:-5, 5:-5, 0]  # away from the wall frame
    assert red.max() > 0.2 and (red > 0).sum() >= 1  # a 0.1 px particle still shows at a quarter strength


def blurred_pair(motion_blur, move_by):
    sim = dot_scene([one([30.0, 50.0], spacing=2.0, blend="additive")], render={"motion_blur": motion_blur})
    ren = Renderer(sim.model, sim.state, 100, 100, sim.scene.render)
    ren.begin_frame()
    x = sim.particles.x.to_numpy()
    x[0, 0] += move_by
    sim.particles.x.from_numpy(x)
    ren.light_before_tone_map, ren.picture = splat_light(ren)
    return ren


def test_motion_blur_streak_has_the_length_of_the_displacement():
    ren = blurred_pair(True, 30.0)
    light = ren.light_before_tone_map[..., 0]
    cols = np.flatnonzero(light.sum(axis=1) > 1e-6)
    length_px = 30.0 * ren.painter.px_per_unit
    radius_px = 1.0 * ren.painter.px_per_unit
    assert cols.max() - cols.min() + 1 == pytest.approx(length_px + 2 * radius_px, abs=2.0)
    # the same energy as the still particle, brightest at the head
    still = blurred_pair(False, 30.0)
    assert light.sum() == pytest.approx(still.light_before_tone_map[..., 0].sum(), rel=1e-5)
    profile = light.sum(axis=1)
    assert profile[cols.max() - 3] > profile[cols.min() + 3]


def test_a_still_particle_is_identical_with_and_without_motion_blur():
    a = blurred_pair(True, 0.0).picture
    b = blurred_pair(False, 0.0).picture
    assert np.array_equal(a, b)


def arc_streak(motion_path):
    """A particle that went (30, 50) -> (50, 70) -> (70, 50) over the frame (a bounce), drawn additive."""
    sim = dot_scene(
        [one([30.0, 50.0], spacing=2.0, blend="additive")], render={"motion_blur": True, "motion_path": motion_path}
    )
    ren = Renderer(sim.model, sim.state, 100, 100, sim.scene.render)

    def move_to(p):
        x = sim.particles.x.to_numpy()
        x[0] = p
        sim.particles.x.from_numpy(x)

    ren.begin_frame()
    move_to([50.0, 70.0])
    ren.mid_frame()
    move_to([70.0, 50.0])
    light, _ = splat_light(ren)
    return ren, light[..., 0]


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_a_spline_streak_bends_through_the_middle_position_with_the_energy_of_a_still_particle():
    spline, curve = arc_streak("spline")
    line, straight = arc_streak("line")

    def pixel(p):  # (column, row) of a domain point in the [x, y] image
        q = np.asarray(p) * spline.painter.px_per_unit + spline.painter.offset.to_numpy()
        return int(q[0]), int(q[1])

    top = pixel([50.0, 70.0])
    assert curve[top] > 0 and straight[top] == 0  # the curve passes where the particle was half-way through
    assert straight[pixel([50.0, 50.0])] > 0 and curve[pixel([50.0, 50.0])] == 0  # the chord is not drawn
    assert curve.sum() == pytest.approx(straight.sum(), rel=1e-5)  # the same light, spread along a longer path
    # a symmetric bounce: the middle position is the curve's apex, so nothing is drawn above it (plus the radius)
    rows = np.flatnonzero(curve.sum(axis=0) > 1e-6)
    apex = 70.0 * spline.painter.px_per_unit + spline.painter.offset.to_numpy()[1]
    assert rows.max() == pytest.approx(apex + 1.0 * spline.painter.px_per_unit, abs=2.0)


def alpha_pair_3d(red_in_front: bool):
    z_red, z_blue = (30.0, 20.0) if red_in_front else (20.0, 30.0)
    render = {
        "camera_position": [25.0, 25.0, 80.0],
        "camera_target": [25.0, 25.0, 0.0],
        "fov": 30.0,
        "ground": False,
        "background": [0.0, 0.0, 0.0],
    }
    sim = dot_scene(
        [
            one([25.0, 25.0, z_red], "red", spacing=4.0, draw="splat", blend="alpha", opacity=0.5),
            one([25.0, 25.0, z_blue], "blue", spacing=4.0, draw="splat", blend="alpha", opacity=0.5),
        ],
        dim=3,
        render=render,
        hi=50.0,
    )
    ren = Renderer(sim.model, sim.state, 64, 64, sim.scene.render)
    ren.render()
    return ren.image.to_numpy()[32, 32]


def test_alpha_compositing_blends_in_depth_order():
    red_front = alpha_pair_3d(True)
    blue_front = alpha_pair_3d(False)
    # back to front "over": (0 * 0.5 + back * 0.5) * 0.5 + front * 0.5
    assert np.allclose(red_front, [0.5, 0.0, 0.25], atol=1e-5)
    assert np.allclose(blue_front, [0.25, 0.0, 0.5], atol=1e-5)


def test_the_colour_bar_samples_each_map_as_the_particles_colour_ramp_does():
    """The bar's colours (three NumPy calls a frame) are those of the per-point ramp, exactly."""
    from sandbox.render.colormaps import SPEED_STOPS, TEMPERATURE_STOPS, ramp_np, ramp_np_many

    ts = np.r_[-0.5, np.linspace(0.0, 1.0, 213), 1.5]
    for stops in (TEMPERATURE_STOPS, SPEED_STOPS):
        assert np.array_equal(ramp_np_many(stops, ts), np.array([ramp_np(stops, t) for t in ts]))


def golden(request, name, img):
    path = GOLDEN / f"{name}.png"
    if request.config.getoption("--regen-golden") or not path.exists():
        write_png(path, img)
        if not request.config.getoption("--regen-golden"):
            pytest.fail(f"stored a new golden image {path}; rerun")
    ref = read_png(path)
    mse = float((((img.astype(float) - ref.astype(float)) / 255.0) ** 2).mean())
    assert mse < 2e-4, f"{name}: mean squared error {mse:.2e} against {path}"


@pytest.mark.parametrize("scene", ["melting_block", "melting_block_3d", "fireworks"])
def test_golden_images(request, scene):
    sim = Simulation(load_scene(SCENES / f"{scene}.toml"))
    ren = Renderer(sim.model, sim.state, 192, 108, sim.scene.render)
    for _ in range(30 if scene == "fireworks" else 3):  # the first shells go off at 0.1 and 0.6 s
        ren.begin_frame()
        sim.advance_frame(midway=ren.mid_frame)
    golden(request, scene, ren.frame())


@pytest.mark.parametrize("scene", ["melting_block", "melting_block_3d"])
def test_every_output_gives_the_same_picture_and_rgba_is_ggui_packed_layout(scene):
    """The float image packed on request, the 8-bit picture written directly (video) and GGUI's packed RGBA (the
    window on the CPU) are one picture, chart included; the packed one is (W, H) uint32, R in the low byte, y up."""
    from types import SimpleNamespace

    over = ["render.chart=['mean_temperature']", "render.legend=false", "render.title=false", "render.clock=false"]
    sim = Simulation(load_scene(SCENES / f"{scene}.toml", over))
    w, h = 160, 90
    renderers = {
        output: Renderer(sim.model, sim.state, w, h, sim.scene.render, output)
        for output in ("image", "picture", "rgba")
    }
    for k in range(3):
        for ren in renderers.values():
            ren.begin_frame()
        sim.advance_frame()
        pictures = {}
        for output, ren in renderers.items():
            ren.record(SimpleNamespace(mean_temperature=float(k), time=0.1 * k))
            pictures[output] = ren.frame().copy()
        assert np.array_equal(pictures["picture"], pictures["image"])
        assert np.array_equal(pictures["rgba"], pictures["image"])
    for ren in renderers.values():  # without the chart's labels, drawn on the host (as the legend would be)
        ren.set_chart(())
    picture = renderers["image"].frame()
    renderers["rgba"].render()
    packed = renderers["rgba"].out
    assert packed.shape == (w, h) and packed.dtype == np.uint32
    rgba = packed.view(np.uint8).reshape(w, h, 4)
    assert np.array_equal(rgba[:, :, :3], picture[::-1].transpose(1, 0, 2)) and (rgba[:, :, 3] == 255).all()
    assert picture.std() > 5  # a picture, not a blank


@pytest.mark.parametrize("output", ["image", "rgba"])
def test_the_brush_outline_is_a_ring_of_its_radius_and_leaves_no_trace(output):
    """The window's tool cursor: a ring of the brush radius about the cursor, drawn into the picture, and gone
    from the next picture once moved away or removed (its tiles are composited again)."""
    sim = dot_scene([one([50.0, 50.0])])
    ren = Renderer(sim.model, sim.state, 200, 200, sim.scene.render, output)
    plain = ren.frame().copy()
    ren.set_brush((100.0, 60.0), 30.0)
    ringed = ren.frame().copy()
    ys, xs = np.nonzero(np.abs(ringed.astype(int) - plain.astype(int)).sum(axis=2) > 30)
    distance = np.hypot(xs + 0.5 - 100.0, (199 - ys) + 0.5 - 60.0)  # rows are counted from the top
    assert len(xs) > 2 * math.pi * 30 and np.abs(distance - 30.0).max() < 1.5
    ren.set_brush((20.0, 20.0), 5.0)
    moved = ren.frame().copy()
    ys, xs = np.nonzero(np.abs(moved.astype(int) - plain.astype(int)).sum(axis=2) > 0)
    assert len(xs) > 0 and np.hypot(xs + 0.5 - 20.0, (199 - ys) + 0.5 - 20.0).max() < 7.5
    ren.set_brush(None)
    assert np.array_equal(ren.frame(), plain)


def test_a_frame_calls_its_midway_hook_once_half_way_and_a_single_step_has_none():
    sim = dot_scene([one([50.0, 50.0])])
    seen = []
    sim.advance_frame(5, midway=lambda: seen.append(sim.step_count))
    assert seen == [2] and sim.step_count == 5
    sim.advance_frame(1, midway=lambda: seen.append(sim.step_count))  # no middle: a spline streak is drawn straight
    assert seen == [2] and sim.step_count == 6


@pytest.mark.parametrize("output", ["image", "picture", "rgba"])
def test_compositing_only_the_dirty_tiles_gives_the_full_picture(output):
    """A particle that moves leaves no trace, and overlays whose content changes (chart values and their labels,
    which run right of the box and change length, the pair-force panel, legend, clock) are redrawn: every frame
    equals the picture of a renderer that composites every pixel every frame."""
    from types import SimpleNamespace

    sim = dot_scene(
        [one([20.0, 50.0], spacing=4.0), one([80.0, 20.0], spacing=4.0, blend="additive")],
        render={"legend": True, "color_by": "speed", "chart": ["kinetic_energy", "max_speed"], "clock": True},
    )
    cfg = sim.scene.render
    tiled, full = (
        Renderer(sim.model, sim.state, 480, 120, cfg, output),
        Renderer(sim.model, sim.state, 480, 120, cfg, output),
    )
    for ren in (tiled, full):
        ren.set_potential(np.linspace(-1.0, 1.0, 50), (0.5, 2.5))
    for k in range(6):
        x = sim.particles.x.to_numpy()
        x[0] += (9.0, 4.0 * (-1) ** k)  # crosses tiles, back and forth
        sim.particles.x.from_numpy(x)
        sim.state.time = 10.0 ** (k - 2)  # the clock's text changes length
        for ren in (tiled, full):
            ren.record(SimpleNamespace(kinetic_energy=7.0 ** (k * k % 7), max_speed=1.0 / (k + 3), time=0.1 * k))
            ren.set_potential(np.linspace(-1.0, 1.0 + 10.0**k, 50), (0.5, 2.5 + k))
        full.full_refresh = True
        a, b = tiled.frame().copy(), full.frame()
        assert np.array_equal(a, b), f"frame {k}"
        for ren in (tiled, full):
            ren.label_window_output()  # the window's text, drawn on its packed picture in place (rgba only)
        if output == "image":
            assert np.array_equal(tiled.image.to_numpy(), full.image.to_numpy())
    assert (
        tiled.canvas.stamp[None] == 6 and np.count_nonzero(tiled.canvas.tile_stamp.to_numpy() >= 4) < 40
    )  # few tiles drawn


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_splatting_strip_by_strip_without_atomics_gives_the_picture_of_atomic_splatting():
    """Particles binned by screen strip are drawn two strips apart in parallel with plain adds; those reaching
    beyond their strip (a big disc, long motion-blur streaks) and additive light by atomic adds. The picture equals
    the one drawn with atomic adds throughout, to float rounding (the order of the sums differs)."""
    from sandbox.render.strips import STRIP

    bodies = [
        {"material": "red", "shape": "box", "lo": [2.0, 10.0], "hi": [98.0, 40.0], "spacing": 1.5, "springs": False},
        {"material": "blue", "shape": "box", "lo": [10.0, 45.0], "hi": [90.0, 60.0], "spacing": 2.0, "blend": "alpha"},
        one([60.0, 80.0], spacing=30.0),  # a disc wider than a strip
        one([30.0, 80.0], spacing=3.0, blend="additive"),
    ]
    sim = dot_scene(bodies, render={"motion_blur": True})
    cfg = sim.scene.render
    strips, atomic = (
        Renderer(sim.model, sim.state, 320, 240, cfg),
        Renderer(sim.model, sim.state, 320, 240, cfg, strip_splat=False),
    )
    for ren in (strips, atomic):
        ren.begin_frame()
    v = np.zeros_like(sim.particles.v.to_numpy())
    n = sim.particles.n[None]
    v[:n, 0] = np.where(np.arange(n) % 7 == 0, 400.0, 3.0)  # every 7th particle streaks across several strips
    sim.particles.v.from_numpy(v)
    sim.step(20)
    a, b = strips.frame().copy(), atomic.frame()
    assert np.abs(strips.image.to_numpy() - atomic.image.to_numpy()).max() < 1e-5
    assert np.abs(a.astype(int) - b.astype(int)).max() <= 1
    count = strips.painter.strips.count.to_numpy()
    wide = count[strips.painter.strips.wide]
    assert count.sum() == n and 0 < wide < n // 5 + 3  # most particles drawn strip by strip
    assert strips.painter.strips.n_strips == 320 // STRIP and atomic.painter.strips.count.to_numpy()[-1] == n


def moved_sphere_3d(motion_blur, move_by):
    """A shaded opaque sphere of radius 3 seen head-on from z = 200 that moved `move_by` along x over the frame."""
    camera = {"camera_position": [50.0, 50.0, 200.0], "camera_target": [50.0, 50.0, 50.0], "ground": False}
    sim = dot_scene([one([48.0, 48.0, 48.0], spacing=6.0)], dim=3, render={"motion_blur": motion_blur, **camera})
    ren = Renderer(sim.model, sim.state, 200, 150, sim.scene.render)
    ren.begin_frame()
    x = sim.particles.x.to_numpy()
    x[0, 0] += move_by
    sim.particles.x.from_numpy(x)
    return ren, ren.frame().astype(int)


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_a_blurred_opaque_sphere_stays_solid_and_leaves_a_fading_streak_of_its_displacement():
    ren, blurred = moved_sphere_3d(True, 20.0)
    _, sharp = moved_sphere_3d(False, 20.0)
    _, background = moved_sphere_3d(False, 500.0)  # out of the picture
    sphere = np.abs(sharp - background).sum(axis=2) > 0
    streak = (np.abs(blurred - background).sum(axis=2) > 0) & ~sphere
    assert np.array_equal(blurred[sphere], sharp[sphere])  # the sphere itself is drawn as without motion blur
    rows, cols = np.nonzero(sphere | streak)
    ppu = ren.painter.focal_field[None] / (200.0 - 48.0)  # pixels per unit of length at the sphere's depth
    assert cols.max() - cols.min() + 1 == pytest.approx((20.0 + 2 * 3.0) * ppu, abs=2.5)  # displacement + diameter
    row = int(np.median(rows))
    red = (blurred - background)[row, :, 0]
    streak_cols = np.flatnonzero(streak[row])
    ahead = streak_cols > np.flatnonzero(sphere[row]).max()
    assert ahead.sum() <= 1  # behind the sphere (it moved to +x), but for the anti-aliased rim
    streak_cols = streak_cols[~ahead]
    assert red[streak_cols[-1]] > 2 * red[streak_cols[0] + 2] > 0  # fading towards where it was


def test_a_still_opaque_sphere_is_identical_with_and_without_motion_blur_3d():
    assert np.array_equal(moved_sphere_3d(True, 0.0)[1], moved_sphere_3d(False, 0.0)[1])


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_a_chart_or_colour_bar_too_big_for_the_picture_is_left_out(tmp_path):
    """A 48 x 48 picture cannot hold the chart box (64 x 40 and its margins) or the colour bar: they are not drawn
    (drawing them wrote out of bounds and crashed the process), and the picture is the one without them."""
    from sandbox.app.cli import main

    pictures = []
    for extra in (["render.chart=['mean_temperature']", "render.legend=true"], ["render.chart=[]"]):
        out = tmp_path / f"{len(pictures)}.png"
        sets = [a for x in extra for a in ("--set", x)]
        args = ["run", "ice_cube", "--headless", "--quiet", "--frames", "2", "--width", "48", "--height", "48"]
        assert main([*args, *sets, "--out", str(out)]) == 0
        pictures.append(read_png(out))
    assert pictures[0].shape == (48, 48, 3)
    assert np.array_equal(pictures[0], pictures[1])


@pytest.mark.parametrize("size", [(1280, 720), (640, 360), (320, 180)])
def test_the_colour_bar_fits_at_every_common_size(size):
    sim = Simulation(load_scene(SCENES / "melting_block.toml", ["render.legend=true"]))
    ren = Renderer(sim.model, sim.state, *size, sim.scene.render)
    assert ren.overlays.legend_shown()  # the bar and its labels inside the picture


def test_a_particles_colour_read_against_the_bar_gives_its_temperature():
    """Issue 43: cream wax at 20 °C used to read as about 200 °C on the bar. Now every particle drawn by temperature
    takes the bar's colour for its temperature, whatever its material: the bar's nearest colour to the pixel under
    a particle's centre gives back its temperature within one bar step."""
    sim = Simulation(load_scene(SCENES / "melting_block.toml", ["render.legend=true", "render.motion_blur=false"]))
    sim.run(40)  # the bottom has heated: a spread of temperatures
    ren = Renderer(sim.model, sim.state, 640, 360, sim.scene.render)
    img = ren.frame().astype(float)
    lo, hi = sim.scene.render.temperature_range
    steps = 64
    bar = ren.overlays.legend_colors(steps) * 255  # the bar as drawn, one colour a step
    table = sim.particles()
    view = ren.painter  # the 2D view: pixels from the bottom left
    centres = table["position"] * view.px_per_unit + np.asarray(view.offset.to_list())
    pixels = np.stack([centres[:, 0], 360 - centres[:, 1]], axis=1)  # rows from the top
    temps = table["temperature"]
    rng = np.random.default_rng(0)
    checked = 0
    for k in rng.permutation(len(temps))[:200]:
        x, y = int(pixels[k, 0]), int(pixels[k, 1])
        if not (0 <= x < 640 and 0 <= y < 360):
            continue
        nearest = np.argmin(((bar - img[y, x]) ** 2).sum(axis=1))
        read = lo + (hi - lo) * nearest / (steps - 1)
        assert abs(read - np.clip(temps[k], lo, hi)) <= (hi - lo) / (steps - 1) * 1.5, (k, read, temps[k])
        checked += 1
    assert checked > 100 and temps.max() - temps.min() > 0.3 * (hi - lo)
