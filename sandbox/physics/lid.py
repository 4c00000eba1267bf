"""A lid (piston) for the molecular model: a horizontal wall across the box at height h that the atoms push up and an
outside pressure P pushes down ([molecular.lid]: pressure, mass M, starting height; the pressure may follow a
schedule, as the heater's power does, until a slider sets it by hand).

An atom that crosses the lid bounces off it as in an elastic collision of masses m and M (the relative speed
v_y - u reverses about their centre of mass, u the lid's speed at the step's start), and the momentum it gives the
lid, J_i = 2 m M / (m + M) (v_y - u), is summed over the step; with at most one hit a step this keeps the energy of
atoms and lid exactly. After each step the lid moves by the symplectic Euler step of

    M du/dt = J / dt - P A - M g,    dh/dt = u

(J the momentum the atoms gave it that step, A its area: the box's width in 2D, width times depth in 3D, g the
scene's gravity along y). At rest on average, the atoms press on it with exactly P: a sealed pot is a lid held in
place, an open pot a light lid at one atmosphere, a pressure cooker a heavy one. The lid stops at the top of the box
and cannot go below a tenth of the box's height. Its height and speed are part of the state (saved, undone, reset).
The lid's update runs between steps (the long way)."""

import taichi as ti

from ..config.molecular_table import Lid as LidTable
from ..config.schema import key_check
from ..core import transfer
from ..core.oriented import data_oriented
from .heat_sources import schedule_flag, scheduled_value, set_by_hand
from .term import Measure, Slider, Term, register


@register
@data_oriented
class Lid(Term):
    """The molecular model's lid (module docstring); its outside pressure is a live control (`lid.pressure`)."""

    key = "lid"
    stage = "thermal_walls"
    finishes = True
    measures = (
        Measure("lid_height", "sum", "value"),
        Measure("lid_impulse", "sum", "value"),  # momentum per area the atoms gave the lid since the gauge restarted
        Measure("lid_since", "sum", "value"),  # the time the gauge restarted
    )

    @staticmethod
    def wanted(parts) -> bool:
        molecular = parts.scene.molecular
        return bool(molecular and molecular.lid)

    @staticmethod
    def host_work(scene) -> str | None:
        if scene.molecular and scene.molecular.lid:
            return "the lid moves between steps by the momentum the atoms gave it"
        return None

    def __init__(self, parts):
        spec = parts.scene.molecular.lid
        world = parts.scene.world
        self.p = parts.state.particles
        self.dim = parts.model.dim
        self.mass = float(spec.mass)
        box = [h - l for l, h in zip(world.lo, world.hi)]
        self.area = box[0] * (box[2] if self.dim == 3 else 1.0)
        self.gravity = float(world.gravity[1]) if world.gravity else 0.0
        self.lowest = world.lo[1] + 0.1 * box[1]
        self.highest = float(world.hi[1])
        self.height = ti.field(float, shape=())  # h (length)
        self.speed = ti.field(float, shape=())  # u (length / time)
        self.pushed = ti.field(float, shape=())  # momentum the atoms gave the lid this step
        self.gauge = ti.field(ti.f64, shape=())  # momentum per area the atoms gave it since the gauge restarted
        self.since = ti.field(ti.f64, shape=())  # ... and when it restarted (time)
        self.spec = spec
        self.pressure = scheduled_value(spec, spec.pressure, 0.0)
        self.by_hand = not spec.schedule_times  # set by hand (or never scheduled): the schedule no longer applies
        # the scene's: the slider's range follows it, not the value it sets
        self.scene_pressure = max([float(spec.pressure), *map(float, spec.schedule_values)])
        transfer.upload([(self.height, float(spec.height))])

    def declare(self, state) -> None:
        state.declare("lid", self, ("height", "speed"))
        state.declare("lid", self, ("pushed", "gauge", "since"), physical=False)

    def restart_gauge(self, time: float) -> None:
        """Zero the lid's pressure gauge at `time` (Simulation.advance_frame restarts it every frame)."""
        transfer.upload([(self.gauge, 0.0), (self.since, float(time))])

    def after_restore(self, state) -> None:
        self.restart_gauge(state.time)

    def controls(self) -> dict:
        """The outside pressure, and whether it still follows the scene's schedule (1) or was set by hand (0)."""
        return {"pressure": self.pressure, "scheduled": 0.0 if self.by_hand else 1.0}

    def sliders(self) -> list[Slider]:
        """The weight on the lid, as the outside pressure: up to four times the scene's (0.2 at least)."""
        top = max(0.2, 4.0 * self.scene_pressure)
        return [Slider("lid", "lid pressure", "pressure", 0.0, top, "pressure", top / 200)]

    def control_checks(self) -> dict:
        return {"pressure": key_check(LidTable, "pressure"), "scheduled": schedule_flag}

    def apply_controls(self, values: dict) -> None:
        """Set the pressure; without "scheduled": 1 (a state file's record) it is set by hand and the schedule
        stops."""
        if "pressure" in values:
            value = float(values["pressure"])
            if not value >= 0.0:
                raise ValueError(f"lid pressure {value!r}; expected a number of at least 0")
            self.pressure = value
        self.by_hand = set_by_hand(self.spec, values)

    def words(self, where: str) -> list[str]:
        if where == "finish":
            return [f"lid: atoms bounce off it (outside pressure {self.pressure:g}, mass {self.mass:g})"]
        if where == "after":
            return ["lid: moves by the momentum the atoms gave it"]
        return []

    def after_step(self, state) -> None:
        if not self.by_hand:  # the pressure in force at the start of the step just taken (the clock moves on after)
            self.pressure = scheduled_value(self.spec, self.spec.pressure, state.time)
        self._move(state.dt, self.pressure * self.area)

    @ti.kernel
    def _move(self, dt: float, load: float):
        for _ in range(1):
            u = self.speed[None] + (self.pushed[None] - (load + self.mass * -self.gravity) * dt) / self.mass
            h = self.height[None] + u * dt
            if h > self.highest:
                h, u = self.highest, ti.min(u, 0.0)
            elif h < self.lowest:
                h, u = self.lowest, ti.max(u, 0.0)
            self.gauge[None] += ti.cast(self.pushed[None] / self.area, ti.f64)
            self.height[None], self.speed[None], self.pushed[None] = h, u, 0.0

    @ti.func
    def finish(self, i, dt, rates: ti.template()):
        p = self.p
        top = self.height[None] - p.radius[i]
        if p.x[i][1] > top and p.mass[i] > 0.0:
            u = self.speed[None]
            x, v = p.x[i], p.v[i]
            x[1] = ti.max(2.0 * top - x[1], top - 1.0)
            if v[1] > u:  # an elastic hit of masses m and M: the relative speed reverses about their centre of mass
                hit = 2.0 * p.mass[i] * self.mass / (p.mass[i] + self.mass) * (v[1] - u)
                self.pushed[None] += hit
                v[1] -= hit / p.mass[i]
            p.x[i], p.v[i] = x, v

    @ti.func
    def measure_value(self, w):
        return self.height[None], self.gauge[None], self.since[None]
