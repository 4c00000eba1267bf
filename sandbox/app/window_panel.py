"""The window's side panel (GGUI widgets): lesson, readouts, tools and sliders, and the help overlay."""

from __future__ import annotations

import textwrap

import numpy as np

from ..config.resources import shipped_scenes
from .window_state import (
    HELP,
    WindowState,
    energy_unit,
    lesson_text,
    pace_text,
    panel_characters,
    pick_scene,
    reading,
    tool_label,
)

PANEL_WIDTH = 0.28  # of the window's width: the panel's column, full height; the renderer draws right of it


def thermometers(sim) -> list[tuple[str, float]]:
    """(name, mean temperature) of each body and emitter that has particles now, for the panel's readout."""
    if sim.terms.heat is None:
        return []
    n = int(sim.particles.n[None])
    groups = sim.particles.group.to_numpy()[:n]
    temps = sim.particles.T.to_numpy()[:n]
    names = [g.name for g in sim.scene.groups] + ["spawned"]
    sums = np.bincount(groups, weights=temps, minlength=len(names))
    counts = np.bincount(groups, minlength=len(names))
    return [(names[k], float(sums[k] / counts[k])) for k in range(len(names)) if counts[k]]


def say(gui, chars: int, text: str) -> None:
    """A line of the panel, wrapped at `chars` characters so that no text runs past the panel's edge."""
    for line in textwrap.wrap(text, chars, subsequent_indent="  ", drop_whitespace=False) or [""]:
        gui.text(line)


def draw_panel(gui, sim, state: WindowState, stats, fps: float) -> None:
    """The panel for this frame: reads `stats`, and sets `state` from its widgets."""
    chars = panel_characters(sim.scene.render.width, PANEL_WIDTH)
    with gui.sub_window(sim.scene.name, 0.0, 0.0, PANEL_WIDTH, 1.0):
        lesson = lesson_text(sim.scene.lesson, chars)
        if lesson:
            state.show_lesson = gui.checkbox("lesson (l)", state.show_lesson)
            if state.show_lesson:
                for line in lesson:
                    gui.text(line)
        say(gui, chars, f"t = {stats.time:.2f} s   {fps:.0f} fps   {'paused' if state.paused else ''}")
        say(
            gui,
            chars,
            f"particles {stats.particles}"
            + (f"   broken springs {stats.broken_springs}" if sim.state.springs is not None else ""),
        )
        if sim.terms.heat is not None:
            molten = f"molten {100 * stats.molten_fraction:.0f}%"
            say(gui, chars, f"mean T {reading(stats.mean_temperature, 'C')}   {molten}")
            for name, temperature in thermometers(sim)[:6]:
                say(gui, chars, f"  {name}: {temperature:.1f} C")
            sim.terms.heat.sources.ambient[None] = gui.slider_float(
                "ambient C", float(sim.terms.heat.sources.ambient[None]), -50.0, 300.0
            )
        unit = energy_unit(sim)
        say(gui, chars, f"energy ({unit}): kinetic {stats.kinetic_energy:.4g}  total {stats.total_energy:.4g}")
        say(gui, chars, f"  per particle {reading(stats.total_energy_per_particle, digits=3)}")
        walls = f"  on walls {reading(stats.wall_pressure, digits=3)}" if sim.model.domain.wall_area else ""
        say(gui, chars, f"pressure {reading(stats.pressure, digits=3)}{walls}")
        say(gui, chars, f"under cursor: {state.probe or '-'}")
        say(gui, chars, f"integrator {state.integrator}")
        say(gui, chars, pace_text(state))
        if state.tools_available:
            say(gui, chars, f"tool: {state.tool}   radius {state.radius:.1f}   spawns {state.material} (m)")
            if sim.dim == 3:
                say(gui, chars, "3D: Shift + left button uses the tool")
            for name in state.tools_available:
                if gui.button(tool_label(name, state.tool)):
                    state.tool = name
            state.radius = gui.slider_float("radius", state.radius, 0.5, 30.0)
            if gui.button("undo stroke (z)"):
                state.undo = True
        state.picking = gui.checkbox("switch scene (n)", state.picking)
        if state.picking:
            for path in shipped_scenes():
                if path.stem != sim.scene.name and gui.button(path.stem):
                    pick_scene(state, path.stem)
        if gui.button("save state (w)"):
            state.save = True
        if gui.button("load state (o)"):
            state.load = True
        state.paused = gui.checkbox("paused", state.paused)
        state.energy_plot = gui.checkbox("energy plot (e)", state.energy_plot)
        if sim.scene.world.substeps != "auto":
            state.dt_scale = gui.slider_float("dt x", state.dt_scale, 0.1, 2.0)
            say(
                gui,
                chars,
                f"dt {sim.dt:.4g}  (stable for springs below {state.stable_dt:.3g})" if sim.state.springs else "",
            )
        state.recording = gui.checkbox("record MP4 (v)", state.recording)
        if sim.terms.pair is not None:
            state.potential = gui.checkbox("pair force (f)", state.potential)
            if state.potential:
                state.attraction = gui.slider_float("attraction x", state.attraction, 0.0, 4.0)
                state.repulsion = gui.slider_float("repulsion x", state.repulsion, 0.25, 4.0)
                r_eq = sim.terms.pair.r_eq_np[0, 0]
                say(gui, chars, f"equilibrium distance {r_eq:.3f} (curve crosses zero)")
        if sim.dim == 2 and any(sim.scene.world.gravity):
            state.gravity_angle = gui.slider_float("gravity angle", state.gravity_angle, -180.0, 180.0)
        if state.log:
            say(gui, chars, state.log[-1])
    if state.show_help:
        with gui.sub_window("keys", 0.3, 0.05, 0.4, 0.5):
            for line in HELP:
                say(gui, chars, line)
