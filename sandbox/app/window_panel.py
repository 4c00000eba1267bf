"""The window's side panel (GGUI widgets): lesson, readouts, tools and sliders, and the help overlay."""

from __future__ import annotations

import math
import textwrap

import numpy as np

from ..config.resources import shipped_scenes
from ..measure.units import energy_unit, length_unit, pressure_unit
from .window_state import HELP, WindowState, lesson_text, pace_text, panel_characters, pick_scene, reading

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


def draw_panel(gui, sim, state: WindowState, stats, fps: float, window_width: int = 1280) -> None:
    """The panel for this frame: reads `stats`, and sets `state` from its widgets. While the lesson is open the
    panel shows the lesson and the readouts; closing it (button or l) shows the controls, so that either page fits
    a window 720 pixels tall."""
    chars = panel_characters(window_width, PANEL_WIDTH)
    with gui.sub_window(sim.scene.name.replace("_", " "), 0.0, 0.0, PANEL_WIDTH, 1.0):
        lesson = lesson_text(sim.scene.lesson, chars)
        if lesson and state.show_lesson:
            for line in lesson:
                gui.text(line)
            if gui.button("close the lesson: controls (l)"):
                state.show_lesson = False
        readouts(gui, chars, sim, state, stats, fps)
        if not (lesson and state.show_lesson):
            if lesson and gui.button("the lesson (l)"):
                state.show_lesson = True
            controls(gui, chars, sim, state)
        if state.log:
            say(gui, chars, state.log[-1])
    if state.show_help:
        with gui.sub_window("keys", 0.3, 0.05, 0.4, 0.9):
            for line in HELP:
                say(gui, chars, line)


def readouts(gui, chars: int, sim, state: WindowState, stats, fps: float) -> None:
    """What the simulation measures, in words and the scene's units; a temperature per body where there are
    several (a candle's flame and wax are not averaged into one number). ASCII only: GGUI's font has no degree
    sign."""
    say(gui, chars, f"time {stats.time:.2f} s   {fps:.0f} frames/s   {'PAUSED' if state.paused else ''}")
    springs = f"   broken bonds {stats.broken_springs}" if sim.state.springs is not None else ""
    say(gui, chars, f"particles {stats.particles}{springs}")
    if sim.terms.heat is not None:
        groups = thermometers(sim)
        melted = f"melted {100 * stats.molten_fraction:.0f}%"
        if any(material.boils for material in sim.model.material_list):
            solid, liquid, gas = (round(100 * share) for share in stats.phase_shares)
            melted = f"solid {solid}%, liquid {liquid}%, gas {gas}%"
        motion = ""
        if math.isfinite(stats.kinetic_temperature):  # temperature as motion: what the motion says
            motion = f"; the motion says {stats.kinetic_temperature:.0f} C"
        if len(groups) == 1:
            say(gui, chars, f"temperature {reading(groups[0][1], 'C')}   {melted}{motion}")
        else:
            each = ", ".join(f"{name.replace('_', ' ')} {temperature:.1f} C" for name, temperature in groups[:4])
            say(gui, chars, f"temperatures: {each}; {melted} in all{motion}")
    names = sim.material_names
    energy = f"energy ({energy_unit(names)}): moving {stats.kinetic_energy:.4g}, total {stats.total_energy:.4g}"
    say(gui, chars, energy)
    unit = pressure_unit(names, sim.dim)
    walls = f", on the walls {reading(stats.wall_pressure, digits=3)}" if sim.model.domain.wall_area else ""
    say(gui, chars, f"pressure ({unit}) {reading(stats.pressure, digits=3)}{walls}")
    say(gui, chars, f"under the cursor: {state.probe or '-'}")
    say(gui, chars, f"integrator {state.integrator} (i)   {pace_text(state)}")


def source_sliders(gui, sources, most: int = 2) -> None:
    """A slider for each of the first `most` heat sources: its temperature, or its power (positive heats, negative
    cools); moving one takes the source over from its schedule."""
    for k, src in enumerate(sources.specs[:most]):
        now = sources.value(k)
        if src.mode == "power":
            top = 2.0 * max([abs(src.power), *map(abs, src.schedule_values)]) or 1.0
            value = gui.slider_float(f"{src.name} (mJ/s)", now, -top, top)
        else:
            value = gui.slider_float(f"{src.name} C", now, -100.0, 1500.0)
        if value != now:
            sources.hold(k, value)


def controls(gui, chars: int, sim, state: WindowState) -> None:
    """Tools, run controls and settings: one widget per row (GGUI's panel has no rows of several)."""
    if state.tools_available:
        tools = state.tools_available
        spawn = f" {state.material} (m)" if state.tool == "spawn" else ""
        k = gui.slider_int(f"tool (Tab): {state.tool}{spawn}", tools.index(state.tool) + 1, 1, len(tools))
        state.tool = tools[min(max(k, 1), len(tools)) - 1]
        if sim.dim == 3:
            say(gui, chars, "3D: Shift + left button uses the tool")
        state.radius = gui.slider_float(f"brush ({length_unit(sim.material_names)})", state.radius, 0.5, 30.0)
        if gui.button("undo the stroke (z)"):
            state.undo = True
    if gui.button("reset to the start (r)"):
        state.reset = True
    if gui.button("leave full screen (x)" if state.full_screen else "full screen (x)"):
        state.full_screen = not state.full_screen
    state.paused = gui.checkbox("paused (space)", state.paused)
    if sim.terms.heat is not None:
        sources = sim.terms.heat.sources
        sources.ambient[None] = gui.slider_float("air C", float(sources.ambient[None]), -50.0, 300.0)
        source_sliders(gui, sources)
    if sim.scene.world.substeps != "auto":
        state.dt_scale = gui.slider_float("time step x", state.dt_scale, 0.1, 2.0)
        stable = f", springs stable below {state.stable_dt:.2g} s" if sim.state.springs else ""
        say(gui, chars, f"time step {sim.dt:.2g} s{stable}")
    if sim.dim == 2 and any(sim.scene.world.gravity):
        state.gravity_angle = gui.slider_float("gravity angle", state.gravity_angle, -180.0, 180.0)
    state.energy_plot = gui.checkbox("energy plot (e)", state.energy_plot)
    if sim.terms.pair is not None:
        state.potential = gui.checkbox("pair force (f)", state.potential)
        if state.potential:
            state.attraction = gui.slider_float("attraction x", state.attraction, 0.0, 4.0)
            state.repulsion = gui.slider_float("repulsion x", state.repulsion, 0.25, 4.0)
            r_eq = sim.terms.pair.r_eq_np[0, 0]
            say(gui, chars, f"at rest {r_eq:.3f} {length_unit(sim.material_names)} apart (the curve's zero)")
    state.recording = gui.checkbox("record MP4 (v)", state.recording)
    if gui.button("save the state (w)"):
        state.save = True
    if gui.button("load it back (o)"):
        state.load = True
    state.picking = gui.checkbox("switch scene (n)", state.picking)
    if state.picking:
        for path in shipped_scenes():
            if path.stem != sim.scene.name and gui.button(path.stem):
                pick_scene(state, path.stem)
