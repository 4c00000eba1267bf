"""What a class sees in a picture (issue 43): a top band holding the title, clock, legend and charts in a real font,
with units; the scene's content framed below it, never under them; legends that say what every colour means."""

from types import SimpleNamespace

import numpy as np
import pytest

from sandbox.config.scene import load_scene
from sandbox.render.chart import COLORS, Chart, nice_range
from sandbox.render.plan import plan_picture
from sandbox.render.raster import Renderer
from sandbox.render.text import GREY, LIGHT, draw_text, font, line_height, text_size, text_width
from sandbox.render.video import read_png
from sandbox.simulation import Simulation

from .conftest import SCENES

pytestmark = pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)


def ink_at(img: np.ndarray, text: str, x: int, y: int, size: int, color=LIGHT) -> bool:
    """Whether `img` holds `color` (within the blending's rounding) on every pixel that `text` drawn at (x, y)
    nearly covers (its strokes' cores)."""
    mask = np.zeros_like(img)
    draw_text(mask, text, x, y, size, (255, 255, 255), outline=False)
    core = mask[:, :, 0] >= 240
    near = np.abs(img[core].astype(int) - np.asarray(color)).max(axis=1) <= 16
    return core.sum() >= len(text.replace(" ", "")) and bool(near.all())


def disjoint(a, b) -> bool:
    """Whether rectangles (x0, x1, row0, row1) a and b share no pixel."""
    return a[1] <= b[0] or b[1] <= a[0] or a[3] <= b[2] or b[3] <= a[2]


def test_text_is_a_real_anti_aliased_font_with_every_character_the_labels_use():
    from sandbox.measure import units

    missing = np.asarray(font(18).getmask("\uffff"))
    labels = ["temperature (°C)", "t = 2.40 s", "molten (%)", "pJ/mm^2", "eps/sigma^3", "mm/s", "ice melt"]
    labels += [units.series_words(name, ["wax"])[0] for name in units.SERIES]
    for ch in set("".join(labels)) - {" "}:
        glyph = np.asarray(font(18).getmask(ch))
        assert glyph.shape != missing.shape or not np.array_equal(glyph, missing), ch
    img = np.zeros((40, 300, 3), np.uint8)
    draw_text(img, "mean temperature 45.2 °C", 2, 2, 18)
    levels = np.unique(img[:, :, 0])
    assert levels.max() == LIGHT[0] and len(levels) > 10  # smooth edges, not a 3 x 5 bitmap
    assert text_size(720) == 18 and text_size(1080) == 27 and text_size(200) == 11


@pytest.mark.parametrize("scene", ["melting_block", "ice_cube", "candle", "sandbox"])
@pytest.mark.parametrize("size", [(512, 384), (640, 360), (960, 540)])
def test_the_scene_is_framed_below_the_band_and_nothing_written_covers_it(scene, size):
    """Every particle's disc lies inside the picture below the band; the title, legend and charts lie inside the
    band, inside the picture, and apart from each other."""
    sim = Simulation(load_scene(SCENES / f"{scene}.toml"))
    sim.run(5)
    plan = plan_picture(sim.model, sim.state, *size, sim.scene.render)  # what the renderer draws by
    w, h = size
    band = plan.layout.band
    n = int(sim.state.particles.n[None])
    radius = sim.state.particles.radius.to_numpy()[:n] * plan.view[0]
    centres = plan.pixels(sim.state.particles.x.to_numpy()[:n])
    rows = centres[:, 1]
    assert (rows - radius >= band - 1).all() and (rows + radius <= h + 1).all()
    assert (centres[:, 0] - radius >= -1).all() and (centres[:, 0] + radius <= w + 1).all()
    rects = plan.overlays.rects()
    if sim.scene.render.chart:
        chart = Chart(tuple(sim.scene.render.chart), plan.chart_rect(), plan.layout.size, sim.model.material_names)
        assert chart.fits  # the scene's chart has room in the band at each size
        rects.append(chart.drawn_rect())
    for k, r in enumerate(rects):
        assert 0 <= r[0] < r[1] <= w and 0 <= r[2] < r[3] <= band, r
        assert all(disjoint(r, other) for other in rects[k + 1 :])


def test_the_content_fills_the_frame_it_is_given():
    """melting_block's block on its plate spans most of the picture's width (it used to fill a third)."""
    sim = Simulation(load_scene(SCENES / "melting_block.toml"))
    ren = Renderer(sim.model, sim.state, 640, 360, sim.scene.render)
    x = sim.particles()["position"][:, 0] * ren.painter.px_per_unit + ren.painter.offset.to_list()[0]
    assert x.max() - x.min() > 0.35 * 640
    candle = Simulation(load_scene(SCENES / "candle.toml"))
    ren = Renderer(candle.model, candle.state, 640, 360, candle.scene.render)
    rows = 360 - (candle.particles()["position"][:, 1] * ren.painter.px_per_unit + ren.painter.offset.to_list()[1])
    assert rows.max() - rows.min() > 0.4 * (360 - ren.layout.band)  # the candle stands tall in its frame


def test_the_title_clock_and_colour_bar_are_written_where_the_layout_puts_them():
    sim = Simulation(load_scene(SCENES / "melting_block.toml"))
    sim.run(3)
    ren = Renderer(sim.model, sim.state, 640, 360, sim.scene.render)
    img = ren.frame()
    size = ren.layout.size
    x, row = ren.layout.text_origin()
    assert ink_at(img, "melting block", x, row, round(size * 1.2))
    assert ink_at(img, f"t = {sim.time:.2f} s", x, row + round(round(size * 1.2) * 1.3), size)
    x0, r0, bar_w, bar_h = ren.overlays.bar_geometry()
    caption = "temperature (°C)"
    top = ren.overlays.legend_rect()[2]
    assert ink_at(img, caption, x0 + bar_w - text_width(caption, size), top, size)
    bar = ren.overlays.legend_colors(bar_w) * 255 + 0.5
    assert np.array_equal(img[r0 + bar_h // 2, x0 : x0 + bar_w], bar.astype(np.uint8))


def test_a_particles_colour_in_phase_mode_is_one_of_the_legends_swatches():
    """ice_cube draws by phase: the legend names each colour (ice solid, melt, vapour), the swatches are drawn in those
    colours, and the pixel under a solid particle's centre is the solid swatch's colour."""
    sim = Simulation(load_scene(SCENES / "ice_cube.toml"))
    ren = Renderer(sim.model, sim.state, 640, 360, sim.scene.render)
    img = ren.frame()
    entries = ren.overlays.entries
    assert [label for label, _ in entries] == ["ice solid", "ice melt", "ice vapour"]  # water boils at 100 °C
    solid = (np.asarray(entries[0][1]) * 255 + 0.5).astype(np.uint8)
    x0, x1, r0, r1 = ren.overlays.legend_rect()
    assert (np.all(img[r0:r1, x0:x1] == solid, axis=2)).sum() > 20  # its swatch
    centres = sim.particles()["position"] * ren.painter.px_per_unit + np.asarray(ren.painter.offset.to_list())
    x, y = centres[len(centres) // 2]
    assert np.abs(img[int(360 - y), int(x)].astype(int) - solid).max() <= 2


def test_no_overlays_gives_the_bare_picture(tmp_path):
    from sandbox.app.cli import main

    args = ["run", "lj_box", "--headless", "--quiet", "--frames", "2", "--width", "320", "--height", "180"]
    assert main([*args, "--out", str(tmp_path / "a.png")]) == 0
    assert main([*args, "--no-overlays", "--out", str(tmp_path / "b.png")]) == 0
    with_text, bare = read_png(tmp_path / "a.png"), read_png(tmp_path / "b.png")
    sim = Simulation(load_scene(SCENES / "lj_box.toml"))
    ren = Renderer(sim.model, sim.state, 320, 180, sim.scene.render)
    x, row = ren.layout.text_origin()
    assert ink_at(with_text, "lj box", x, row, round(ren.layout.size * 1.2))  # a run's pictures carry the title
    assert not ink_at(bare, "lj box", x, row, round(ren.layout.size * 1.2))
    top = bare[: ren.layout.band // 2]
    assert top.std() < with_text[: ren.layout.band // 2].std()


def test_chart_panels_group_series_by_unit_with_round_axes():
    sim = Simulation(load_scene(SCENES / "melting_block.toml"))
    ren = Renderer(sim.model, sim.state, 960, 540, sim.scene.render)
    chart = ren.chart
    assert [(p.title, p.unit) for p in chart.panels] == [("mean temperature (rule)", "°C"), ("molten (rule)", "%")]
    energies = Chart(("kinetic_energy", "potential_energy", "total_energy"), (0, 600, 0, 200), 12, ["wax"])
    assert [(p.title, p.unit) for p in energies.panels] == [("kinetic energy, potential energy, total energy", "pJ")]
    for k in range(11):  # temperature 20 -> 120, melt 0 -> 50 %
        ren.record(SimpleNamespace(mean_temperature=20.0 + 10 * k, molten_fraction=0.05 * k, time=0.1 * k))
    temperature, melt = chart.panels
    assert chart.data_range(temperature) == (0.0, 150.0) and chart.data_range(melt) == (0.0, 100.0)
    assert nice_range(0.013, 0.0871) == pytest.approx((0.0, 0.1))
    assert nice_range(5.0, 5.0)[0] < 5.0 < nice_range(5.0, 5.0)[1]
    img = ren.frame()
    for panel, rect, color in zip(chart.panels, chart.panel_rects(), COLORS):
        lo, hi = chart.data_range(panel)
        x0, x1, r0, r1 = chart.plot_box(rect, lo, hi)
        end = chart.xy(panel, panel.names[0], (x0, x1, r0, r1))[-1]
        near = img[round(end[1]) - 2 : round(end[1]) + 3, round(end[0]) - 3 : round(end[0]) + 1].reshape(-1, 3)
        assert (np.abs(near.astype(int) - color).max(axis=1) <= 2).any()  # the line ends where its last value is
        size, zero = chart.size, f"{lo:.3g}"
        assert ink_at(img, zero, x0 - 6 - text_width(zero, size), r1 - line_height(size) // 2, size, GREY)
    ren.set_chart(())
    plain = Renderer(sim.model, sim.state, 960, 540, sim.scene.render)
    plain.set_chart(())
    assert np.array_equal(ren.frame(), plain.frame())


def test_the_pair_force_panel_shares_the_band_and_goes_away():
    sim = Simulation(load_scene(SCENES / "lj_box.toml"))
    ren = Renderer(sim.model, sim.state, 960, 540, sim.scene.render, room_for_charts=True)
    plain = ren.frame().copy()
    r, force = sim.terms.pair.curve()
    ren.set_potential(force, (float(r[0]), float(r[-1])))
    shown = ren.frame()
    changed = np.abs(shown.astype(int) - plain.astype(int)).sum(axis=2) > 0
    ys, xs = np.nonzero(changed)
    x0, x1, r0, r1 = ren.potential.drawn_rect()
    assert changed.sum() > 500 and xs.min() >= x0 and xs.max() < x1 and ys.max() < r1 <= ren.layout.band
    assert ink_at(shown, "pair force (+ attracts)", x0 + 2, r0, ren.layout.size, tuple(COLORS[0]))
    ren.set_potential(None)
    assert np.array_equal(ren.frame(), plain)


def test_right_to_left_words_are_laid_out_right_to_left_with_their_latin_runs():
    """An Arabic chart title with a unit in parentheses is laid out as an Arabic reader expects: right to left as a
    paragraph, so the Latin unit, which ends the text, stands at its left end with both parentheses (laid out left to
    right it split as "(pJ/mm^2" at the right). Latin-first words keep the default direction."""
    from PIL import ImageFont

    from sandbox.render.text import direction_of, wide_font_path

    if wide_font_path() is None:
        pytest.skip("no DejaVu Sans (matplotlib or the system's)")
    assert direction_of("ماء: الضغط (pJ/mm^2)") in ("rtl", None) and direction_of("température (°C)") is None
    if direction_of("ماء") is None:
        pytest.skip("Pillow without Raqm lays out no right-to-left text")
    face = ImageFont.truetype(str(wide_font_path()), 18, layout_engine=ImageFont.Layout.RAQM)
    title, unit = "ماء: الضغط (pJ/mm^2)", "(pJ/mm^2)"
    whole = face.getmask(title, direction="rtl")
    left = face.getmask(unit)
    # the whole title's first columns are the unit's own glyphs, parentheses and all: their ink column by column
    # follows the unit's drawn alone (laid out left to right, the title begins with its Arabic instead)

    def start_likeness(mask) -> float:
        ink = np.array(mask).reshape(mask.size[1], mask.size[0]).sum(axis=0)[: left.size[0]].astype(float)
        alone = np.array(left).reshape(left.size[1], left.size[0]).sum(axis=0).astype(float)
        return float(np.corrcoef(ink[: len(alone)], alone[: len(ink)])[0, 1])

    assert start_likeness(whole) > 0.9
    assert start_likeness(face.getmask(title, direction="ltr")) < 0.5
