"""What a scene's panel shows and offers, described once as data: the readouts with their units, the settings a
lesson asks students to change, the tools, and a sentence saying what the scene is doing. The desktop window
(window_panel.py) draws it with GGUI widgets, the browser page (serve.py, web/app.js) with HTML; neither decides
for itself what to show, so they never disagree. Words here are English; the page translates by `key`."""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field, fields

import numpy as np

from ..config.quantities import BY_NAME
from ..core.transfer import download
from ..measure.units import shown


@dataclass(frozen=True)
class Readout:
    """One measurement: `key` names it (the page's message catalogue), `words` in English, `value` in `unit`
    (nan: nothing to measure), shown with `digits` decimals; `source`: what the number is (config/quantities.SOURCES:
    "measured", "rule" or "clock"; "" for the drawing rate)."""

    key: str
    words: str
    value: float
    unit: str = ""
    digits: int = 1
    source: str = ""

    def text(self) -> str:
        """The value with its unit, or "-" (ASCII: the window's font has no en dash)."""
        if not math.isfinite(self.value):
            return "-"
        return f"{self.value:.{self.digits}f}{' ' + self.unit if self.unit else ''}"


@dataclass(frozen=True)
class Setting:
    """A slider: `key` names it, `words` in English; its `value` between `lo` and `hi` in `unit`; `apply(value)`
    sets it (clamped to the range by the controller). Declared once, in controller.Controller.settings."""

    key: str
    words: str
    value: float
    lo: float
    hi: float
    unit: str = ""
    step: float = 1.0
    apply: Callable[[float], None] | None = field(default=None, compare=False, repr=False)


def thermometers(sim, world: int | None = None) -> list[tuple[str, float]]:
    """(name, mean temperature) of each body and emitter that has particles now (in world `world` alone where the
    simulation holds several, core/worlds.py)."""
    if sim.terms.heat is None:
        return []
    first, n = sim.state.particles.block(world)
    rows = slice(first, first + n)
    # one copy of both fields, whole: a copy of the live rows only compiles a kernel for every count of them (a
    # scene whose emitters add and retire particles compiled one at every readout)
    groups, temps = (values[rows] for values in download([sim.particles.group, sim.particles.T]))
    names = [g.name for g in sim.scene.groups] + ["spawned"]
    sums = np.bincount(groups, weights=temps, minlength=len(names))
    counts = np.bincount(groups, minlength=len(names))
    return [(names[k], float(sums[k] / counts[k])) for k in range(len(names)) if counts[k]]


def measured(key: str, name: str, sim, stats, digits: int = 1) -> Readout:
    """The panel's row `key` for the declared quantity `name` (config/quantities.py): its words, its value in the
    scene's units (fractions in percent; temperatures as "C": the window's font has no degree sign)."""
    q = BY_NAME[name]
    scale, unit = shown(q.unit, sim.material_names, sim.dim)  # a real substance's scene: in its units
    value = float(getattr(stats, name)) * scale
    if unit == "%":
        value *= 100.0
    unit = {"°C": "C", "count": ""}.get(unit, unit)
    return Readout(key, q.words, value, unit, digits, q.source)


def marks_sources(items: list[Readout]) -> bool:
    """Whether a scene's readouts say what each number is: where some are set by the model's rule (a mesoscale
    scene's heat and phases), each is marked measured or rule; where all are measured (atoms, a cold lattice), none
    needs the mark."""
    return any(item.source == "rule" for item in items)


def readouts(sim, stats, fps: float | None = None, world: int | None = None) -> list[Readout]:
    """The panel's measurements of `sim` now (`stats`: its Stats, of world `world` where it holds several; `fps`:
    frames drawn per wall second)."""
    out = [measured("time", "time", sim, stats, 2)]
    if fps is not None:
        out.append(Readout("fps", "frames per second", fps, "", 0))
    out.append(measured("particles", "particles", sim, stats, 0))
    if sim.state.springs is not None:
        out.append(measured("broken", "broken_springs", sim, stats, 0))
    if sim.terms.heat is not None:
        out.append(measured("temperature", "mean_temperature", sim, stats))
        # a world's groups are its scene's (no tool adds one): one group has no thermometers but the mean's
        groups = thermometers(sim, world) if sim.worlds == 1 or len(sim.scene.groups) > 1 else []
        if len(groups) > 1:  # a temperature per body: a candle's flame and wax are not averaged into one number
            out += [Readout("temperature_of", name.replace("_", " "), t, "C", 1, "rule") for name, t in groups[:4]]
        if any(material.boils for material in sim.model.material_list):
            solid, liquid, gas = stats.phase_shares
            out += [
                Readout("solid", "solid", 100 * solid, "%", 0, "rule"),
                Readout("liquid", "liquid", 100 * liquid, "%", 0, "rule"),
                Readout("gas", "gas", 100 * gas, "%", 0, "rule"),
            ]
        else:
            out.append(measured("melted", "molten_fraction", sim, stats, 0))
        if math.isfinite(stats.kinetic_temperature):
            out.append(measured("motion", "kinetic_temperature", sim, stats, 0))
    if sim.terms.structure is not None:  # the molecular model: temperature from motion, phases from structure
        out.append(measured("motion", "motion_temperature", sim, stats, 3))
        out += [measured(kind, f"structure_{kind}", sim, stats, 0) for kind in ("solid", "liquid", "gas")]
        if sim.terms.thermal_walls is not None:
            out.append(measured("wall_heat", "wall_heat", sim, stats, 1))
        if sim.terms.heater is not None:
            out.append(measured("heater_heat", "heater_heat", sim, stats, 1))
        if sim.terms.lid is not None:  # (its height is a chart series: the panel fits 768 pixels)
            out.append(measured("lid_pressure", "lid_pressure", sim, stats, 4))
    out.append(measured("energy", "total_energy", sim, stats, 1))
    if sim.terms.structure is None or not sim.model.domain.wall_area:  # atoms in a box: the walls' gauge says it
        out.append(measured("pressure", "pressure", sim, stats, 3))
    if sim.model.domain.wall_area and sim.terms.lid is None:  # under a lid, the lid's gauge is the pressure
        out.append(measured("wall_pressure", "wall_pressure", sim, stats, 3))
    return out


def summary(sim, stats, previous: float | None) -> dict:
    """What the scene is doing, for a screen reader: {"key": sentence key, values...}; e.g. ("the block is 40%
    molten, mean temperature 58 C, rising"). `previous`: the mean temperature a few seconds ago (None: unknown; the
    kinetic temperature kT in the molecular model)."""
    if sim.terms.structure is not None and math.isfinite(stats.motion_temperature):  # atoms: phases by structure
        return {
            "key": "summary_atoms",
            "solid": round(100 * stats.structure_solid),
            "molten": round(100 * stats.structure_liquid),  # (the page speaks again when a share moves by a quarter)
            "gas": round(100 * stats.structure_gas),
            "temperature": round(stats.motion_temperature, 3),
            "trend": trend_word(stats.motion_temperature, previous, 0.01),
        }
    if sim.terms.heat is None or not math.isfinite(stats.mean_temperature):
        return {"key": "summary_motion", "particles": stats.particles, "speed": round(stats.max_speed, 2)}
    trend = trend_word(stats.mean_temperature, previous)
    shares = stats.phase_shares
    return {
        "key": "summary_heat",
        "molten": round(100 * stats.molten_fraction),
        "gas": round(100 * shares[2]),
        "temperature": round(stats.mean_temperature),
        "trend": trend,
    }


def trend_word(now: float, previous: float | None, step: float = 0.5) -> str:
    """ "rising", "falling" or "steady": `now` against `previous`, the value a trend window ago, by more than `step`
    (degrees; a hundredth of the well depth for the atoms' kT)."""
    if previous is None or not math.isfinite(previous) or not math.isfinite(now):
        return "steady"
    change = now - previous
    return "rising" if change > step else "falling" if change < -step else "steady"


class Trend:
    """A value's samples over the last `window` simulated seconds, for summary()'s trend: add() returns the value
    about a window ago (None until the samples span half a window), sliding with every sample."""

    def __init__(self, window: float = 2.0) -> None:
        self.window = window
        self.samples: deque[tuple[float, float]] = deque()

    def add(self, time: float, value: float) -> float | None:
        """Record `value` at simulated `time` (s); the value about a window before it."""
        if self.samples and time < self.samples[-1][0]:  # a reset or a new scene: time went back
            self.samples.clear()
        self.samples.append((time, value))
        while len(self.samples) > 1 and time - self.samples[1][0] >= self.window:
            self.samples.popleft()
        first_time, first_value = self.samples[0]
        return first_value if time - first_time >= self.window / 2 else None


def as_json(items) -> list[dict]:
    """Readouts or settings as plain dicts (nan as None) for the page."""
    out = []
    for item in items:
        d = {f.name: getattr(item, f.name) for f in fields(item) if f.name != "apply"}  # what a slider does stays
        d["value"] = d["value"] if math.isfinite(d["value"]) else None
        out.append(d)
    return out
