"""The window's side panel (GGUI widgets): lesson, readouts, tools and sliders, and the help overlay."""

from __future__ import annotations

import math
import textwrap

from ..config.resources import shipped_scenes
from ..measure.units import length_unit
from .panel import marks_sources
from .window_state import WindowState, help_lines, lesson_text, pace_text, panel_characters, pick_scene

PANEL_WIDTH = 0.28  # of the window's width: the panel's column, full height; the renderer draws right of it


def say(gui, chars: int, text: str) -> None:
    """A line of the panel, wrapped at `chars` characters so that no text runs past the panel's edge."""
    for line in textwrap.wrap(text, chars, subsequent_indent="  ", drop_whitespace=False) or [""]:
        gui.text(line)


def draw_panel(gui, control, state: WindowState, stats, fps: float, window_width: int = 1280) -> None:
    """The panel for this frame: reads `stats`, and sets `state` from its widgets. While the lesson is open the
    panel shows the lesson and the readouts; closing it (button or l) shows the controls, so that either page fits
    a window 720 pixels tall."""
    chars = panel_characters(window_width, PANEL_WIDTH)
    sim = control.sim
    with gui.sub_window(sim.scene.name.replace("_", " "), 0.0, 0.0, PANEL_WIDTH, 1.0):
        lesson = lesson_text(sim.scene.lesson, chars)
        if lesson and state.show_lesson:
            for line in lesson:
                gui.text(line)
            if gui.button("close the lesson: controls (l)"):
                state.show_lesson = False
        readouts(gui, chars, control, state, stats, fps)
        if not (lesson and state.show_lesson):
            if lesson and gui.button("the lesson (l)"):
                state.show_lesson = True
            controls(gui, chars, control, state)
        if state.log:
            say(gui, chars, state.log[-1])
    if state.show_help:
        with gui.sub_window("keys", 0.3, 0.05, 0.4, 0.9):
            for line in help_lines():
                say(gui, chars, line)


def readouts(gui, chars: int, control, state: WindowState, stats, fps: float) -> None:
    """The shared description's measurements (panel.py), packed into as few lines as the panel's width allows, then
    the probe and the integrator. Where some are set by the model's rule, those follow "rule:" and the rest
    "measured:" (the clock and the drawing rate first, unmarked). ASCII only: GGUI's font has no degree sign."""
    items = control.readouts(stats, fps)
    groups = [("", items)]
    if marks_sources(items):  # the clock first, unmarked; then each source under its heading
        groups = [("", [item for item in items if item.source not in ("rule", "measured")])]
        for source in ("rule", "measured"):  # (the bonds after the heat: fewer lines)
            of_source = sorted((item for item in items if item.source == source), key=lambda item: item.key == "broken")
            groups.append((f"{source}:", of_source))
    # each group's first reading carries its heading, so a heading never ends a line
    texts = [
        f"{heading if k == 0 else ''} {item.words} {item.text()}".strip()
        for heading, group in groups
        for k, item in enumerate(group)
    ]
    line = "PAUSED" if control.paused else ""
    for text in texts:
        if line and len(line) + 3 + len(text) > chars:
            say(gui, chars, line)
            line = ""
        line = f"{line}   {text}" if line else text
    if line:
        say(gui, chars, line)
    say(gui, chars, f"under the cursor: {state.probe or '-'}")
    say(gui, chars, f"integrator {control.sim.integrator.name} (i)   {pace_text(state)}")


def setting_sliders(gui, control) -> None:
    """A slider for each setting the controller offers (the page offers the same ones)."""
    for item in control.settings():
        value = gui.slider_float(
            f"{item.words} ({item.unit})" if item.unit else item.words, item.value, item.lo, item.hi
        )
        if value != item.value:
            control.set(item.key, value)


def controls(gui, chars: int, control, state: WindowState) -> None:
    """Tools, run controls and settings: one widget per row (GGUI's panel has no rows of several)."""
    sim = control.sim
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
    if gui.checkbox("paused (space)", control.paused) != control.paused:
        state.toggle_pause = True
    setting_sliders(gui, control)
    if sim.scene.world.substeps != "auto":  # its scale is one of the settings above
        finite = sim.state.springs and math.isfinite(state.stable_dt)  # (no springs yet: no limit to say)
        stable = f", springs stable below {state.stable_dt:.2g} s" if finite else ""
        say(gui, chars, f"time step {sim.dt:.2g} s{stable}")
    state.energy_plot = gui.checkbox("energy plot (e)", state.energy_plot)
    if sim.terms.pair is not None:
        state.potential = gui.checkbox("pair force (f)", state.potential)
        if state.potential:  # the attraction and repulsion sliders are among the settings above
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
