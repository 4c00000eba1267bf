"""A lid (piston) for the molecular model: a horizontal wall across the box at height h that the atoms push up and an
outside pressure P pushes down ([molecular.lid]: pressure, mass M, starting height; the pressure may follow a
schedule, as the heater's power does, until a slider sets it by hand).

An atom that crosses the lid bounces off it as in an elastic collision of masses m and M (the relative speed
v_y - u reverses about their centre of mass, u the lid's speed at the step's start), and the momentum it gives the
lid, J_i = 2 m M / (m + M) (v_y - u), is summed over the step (each atom's J kept, then added in the atoms' storage
order: the same sum in any thread order); with at most one hit a step this keeps the energy of atoms and lid
exactly. After each step the lid moves by the symplectic Euler step of

    M du/dt = J / dt - P A - M g,    dh/dt = u

(J the momentum the atoms gave it that step, A its area: the box's width in 2D, width times depth in 3D, g the
scene's gravity along y). At rest on average, the atoms press on it with exactly P: a sealed pot is a lid held in
place, an open pot a light lid at one atmosphere, a pressure cooker a heavy one. The lid stops at the top of the box
and cannot go below a tenth of the box's height. Its height and speed are part of the state (saved, undone, reset).
The lid's update runs between steps (the long way). With many worlds (core/worlds.py) each world has its own lid:
its height, speed and gauge, and its outside pressure (its slider; its schedule on the world's own clock)."""

import numpy as np
import taichi as ti

from ..config.molecular_table import Lid as LidTable
from ..config.schema import key_check
from ..core import transfer
from ..core.oriented import data_oriented
from ..core.state import WORLDS
from ..core.worlds import add_at, at, per_world, put_at, world_entry, world_of
from .heat_sources import ScheduledSetting, schedule_flag
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
        self.state, self.loops = parts.state, parts.model.loops
        self.worlds = worlds = parts.model.worlds
        self.height = per_world(worlds, float)  # h (length), per world
        self.speed = per_world(worlds, float)  # u (length / time)
        self.hit = ti.field(float, shape=parts.model.capacity)  # the momentum each atom gave the lid this step
        self.gauge = per_world(worlds, ti.f64)  # momentum per area the atoms gave it since the gauge restarted
        self.since = per_world(worlds, ti.f64)  # ... and when it restarted (the world's own time)
        self.load = per_world(worlds, float) if worlds > 1 else None  # P A of each world this step (force)
        self.setting = ScheduledSetting(spec, "pressure", worlds)  # each world's outside pressure
        # the scene's: the slider's range follows it, not the value it sets
        self.scene_pressure = max([float(spec.pressure), *map(float, spec.schedule_values)])
        height = float(spec.height)
        transfer.upload([(self.height, height if worlds == 1 else np.full(worlds, height))])  # a copy, not a kernel

    pressure = property(lambda self: self.setting.values[0], doc="the outside pressure of a lone run (world 0's)")

    def height_of(self, world: int = 0) -> float:
        """The lid's height (length) in world `world` now (a host read)."""
        return float(world_entry(self.height, self.worlds, world))

    def declare(self, state) -> None:
        rows = WORLDS if self.worlds > 1 else ""
        state.declare("lid", self, ("height", "speed"), rows=rows)
        state.declare("lid", self, ("gauge", "since"), physical=False, rows=rows)

    def restart_gauge(self, time: float, world: int | None = None) -> None:
        """Zero the lid's pressure gauge at `time` (the simulation's clock; each world's gauge restarts at its own
        time) in world `world` (None: every world). Simulation.advance_frame restarts it every frame."""
        if self.worlds == 1:
            transfer.upload([(self.gauge, 0.0), (self.since, float(time))])
            return
        gauge, since = self.gauge.to_numpy(), self.since.to_numpy()
        started = np.asarray(self.state.world_started, dtype=float)
        rows = slice(None) if world is None else world
        gauge[rows], since[rows] = 0.0, (time - started)[rows]
        transfer.upload([(self.gauge, gauge), (self.since, since)])

    def after_restore(self, state) -> None:
        self.restart_gauge(state.time)

    world_controls = True  # each world's lid has its own outside pressure (core/worlds.py)

    def controls(self, world: int = 0) -> dict:
        """The outside pressure, and whether it still follows the scene's schedule (1) or was set by hand (0), in
        world `world`."""
        return self.setting.controls(world)

    def sliders(self) -> list[Slider]:
        """The weight on the lid, as the outside pressure: up to four times the scene's (0.2 at least)."""
        top = max(0.2, 4.0 * self.scene_pressure)
        return [Slider("lid", "lid pressure", "pressure", 0.0, top, "pressure", top / 200)]

    def control_checks(self) -> dict:
        return {"pressure": key_check(LidTable, "pressure"), "scheduled": schedule_flag}

    def apply_controls(self, values: dict, world: int | None = None) -> None:
        """Set the pressure in world `world` (None: every world); without "scheduled": 1 (a state file's record) it
        is set by hand and the schedule stops."""
        if "pressure" in values:
            value = float(values["pressure"])
            if not value >= 0.0:
                raise ValueError(f"lid pressure {value!r}; expected a number of at least 0")
        self.setting.apply(values, world)

    def words(self, where: str) -> list[str]:
        if where == "finish":
            return [f"lid: atoms bounce off it (outside pressure {self.pressure:g}, mass {self.mass:g})"]
        if where == "after":
            return ["lid: moves by the momentum the atoms gave it"]
        return []

    def after_step(self, state) -> None:
        self.setting.follow(state.world_times())  # the pressure in force at the start of the step just taken
        if self.worlds == 1:
            self._move(state.dt, self.pressure * self.area)
            return
        self.setting.write(self.load, self.area)
        self._move_worlds(state.dt)

    @ti.kernel
    def _move(self, dt: float, load: float):
        ti.loop_config(serialize=True)  # one item: waking the thread pool would cost more than the step itself
        for _ in range(1):
            self._move_one(0, 0, self.p.n[None], dt, load)

    @ti.kernel
    def _move_worlds(self, dt: float):
        self.loops.light()
        for w in range(self.p.n[None] // self.p.world_size):  # the worlds in use, a world to a thread
            first, end = self.p.world_slots(w)  # its live atoms (an emitter's world has empty slots after them)
            self._move_one(w, first, end, dt, self.load[w])

    @ti.func
    def _move_one(self, w, first, last, dt, load):
        """World w's lid moved by a step: the momentum its atoms (first .. last - 1) gave it, summed in their order,
        against the load `load` (P A) and gravity."""
        pushed = 0.0
        for i in range(first, last):
            pushed += self.hit[i]
        u = at(self.speed, w) + (pushed - (load + self.mass * -self.gravity) * dt) / self.mass
        h = at(self.height, w) + u * dt
        if h > self.highest:
            h, u = self.highest, ti.min(u, 0.0)
        elif h < self.lowest:
            h, u = self.lowest, ti.max(u, 0.0)
        add_at(self.gauge, w, ti.cast(pushed / self.area, ti.f64))
        put_at(self.height, w, h)
        put_at(self.speed, w, u)

    @ti.func
    def finish(self, i, dt, rates: ti.template()):
        p = self.p
        w = world_of(p, i)
        top = at(self.height, w) - p.radius[i]
        hit = 0.0
        if p.x[i][1] > top and p.mass[i] > 0.0:
            u = at(self.speed, w)
            x, v = p.x[i], p.v[i]
            x[1] = ti.max(2.0 * top - x[1], top - 1.0)
            if v[1] > u:  # an elastic hit of masses m and M: the relative speed reverses about their centre of mass
                hit = 2.0 * p.mass[i] * self.mass / (p.mass[i] + self.mass) * (v[1] - u)
                v[1] -= hit / p.mass[i]
            p.x[i], p.v[i] = x, v
        self.hit[i] = hit

    @ti.func
    def measure_value(self, w):
        return at(self.height, w), at(self.gauge, w), at(self.since, w)
