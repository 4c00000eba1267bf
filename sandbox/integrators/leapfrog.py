"""Velocity Verlet and position Verlet as leapfrog: one force evaluation a step, on every path symplectic Euler
runs on (many steps to a launch, a team of threads).

Both Verlet steps are symplectic Euler's kick-drift (v += dt a(x); x += dt v) on a staggered state: velocity Verlet
on the velocities of half steps (v_{n+1/2} = v_{n-1/2} + dt a(x_n); its closing half kick and the next step's
opening one use the same forces, so they merge), position Verlet on the positions of half steps (its closing half
drift and the next opening one merge). The state is staggered at the start of a Simulation.step call and
synchronised at its end, so everything outside stepping (measurements, pictures, tools, saves) sees x_n and v_n;
velocity Verlet's synchronisation costs one force evaluation (v_n = v_{n-1/2} + dt/2 a(x_n)), position Verlet's none
(x_n = x_{n+1/2} - dt/2 v_n). The next call restores the staggered values exactly when nothing changed the state in
between, so the trajectory does not depend on how the steps are split into calls; a state changed between calls
(positions, velocities or temperatures written by a tool, a reset, a restore, a particle added or removed) is
staggered afresh. Forces that depend on velocity see v_{n-1/2} (velocity Verlet) or v_n (position Verlet), as in the
textbook steps; walls act at the end of each kick-drift, on the staggered state.

With many worlds (core/worlds.py) the check is made world by world: the worlds whose state changed between calls (a
world put back, started again or moved: world_state.py; a tool used in it) are staggered afresh, the others restore
their staggered values, so each world steps as its lone run would, given what was done to it alone.
"""

import taichi as ti

from ..core.worlds import world_of
from .base import register
from .explicit import SymplecticEuler


class Leapfrog(SymplecticEuler):
    """What both leapfrog methods share: symplectic Euler's step (kick-drift, one update per particle) on the
    staggered state, and the bookkeeping that makes staggering exact."""

    order = 2
    staggered = ""  # which state the method keeps at half steps: "v" (velocity Verlet) or "x" (position Verlet)

    def __init__(self, rates, state):
        super().__init__(rates, state)
        self._stage_fields("held", "x_synced", "v_synced")  # held: the staggered value left at the last sync
        capacity = self.p.capacity
        self.ident_synced = ti.field(ti.i32, shape=capacity)
        self.has_heat = self.p.heat
        self.domain = rates.domain
        self.periodic = rates.domain.periodic
        self.t_synced = ti.field(float, shape=capacity if self.has_heat else 1)
        self.moving = getattr(self.p, self.staggered)  # the field that holds the staggered state
        self.synced_count = -1  # particles when last synchronised; -1: never
        self.synced_dt = 0.0
        self.worlds = self.p.world_count if self.p.worlds else 1
        if self.worlds > 1:
            self.world_changed = ti.field(ti.i32, shape=self.worlds)  # 1: world w is staggered afresh
        # What the last synchronisation left, saved with a state: a resumed run restores the staggered values exactly
        state.declare("integrator", self, ("held", "x_synced", "v_synced", "ident_synced", "t_synced"), physical=False)
        state.declare("integrator", self, ("synced_count", "synced_dt"), kind="value", physical=False)

    def begin(self, dt: float) -> None:
        """Stagger the synchronised state before a run of steps of `dt`: restore what the last sync held when
        nothing changed since, else stagger afresh."""
        if self.worlds > 1 and self.synced_count >= 0 and self.synced_dt == dt:
            if self._changed_worlds(self.synced_count) == 0:
                self._restore()
            else:
                self._stagger(dt, True)
        elif self.synced_count == int(self.p.n[None]) and self.synced_dt == dt and self._changed() == 0:
            self._restore()
        else:
            self._stagger(dt)

    def end(self, dt: float) -> None:
        """Synchronise after a run of steps of `dt`, holding the staggered value for the next begin."""
        self._synchronise(dt)
        self._record()
        self.synced_count, self.synced_dt = int(self.p.n[None]), dt

    def _stagger(self, dt: float, some: bool = False) -> None:
        """Stagger the state for steps of `dt`; `some`: only the worlds marked in `world_changed`, the others'
        staggered values restored."""
        raise NotImplementedError

    def _synchronise(self, dt: float) -> None:
        raise NotImplementedError

    @ti.kernel
    def _restore(self):
        """Put back the staggered values the last synchronisation held."""
        self.loops.light()
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            self.moving[i] = self.held[i]

    @ti.kernel
    def _record(self):
        self.loops.light()
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            self.v_synced[i] = self.p.v[i]
            self.x_synced[i] = self.p.x[i]
            self.ident_synced[i] = self.p.ident[i]
            if ti.static(self.has_heat):
                self.t_synced[i] = self.p.T[i]

    @ti.kernel
    def _changed(self) -> ti.i32:
        """Particles whose position, velocity, temperature or id is not what the last synchronisation left."""
        changed = 0
        self.loops.light()
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            if not self._same(i):
                changed += 1
        return changed

    @ti.kernel
    def _changed_worlds(self, synced: ti.i32) -> ti.i32:
        """Mark in `world_changed` the worlds with a particle whose state is not what the last synchronisation
        (of `synced` particles) left; returns how many."""
        for w in range(self.worlds):
            self.world_changed[w] = 0
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            if i >= synced or not self._same(i):
                self.world_changed[world_of(self.p, i)] = 1
        changed = 0
        for w in range(self.worlds):
            changed += self.world_changed[w]
        return changed

    @ti.func
    def _same(self, i):
        """Particle i's position, velocity, temperature and id are those the last synchronisation left."""
        same = self.p.ident[i] == self.ident_synced[i]
        if ti.static(self.has_heat):
            same = same and self.p.T[i] == self.t_synced[i]
        for a in ti.static(range(self.p.dim)):
            same = same and self.p.x[i][a] == self.x_synced[i][a] and self.p.v[i][a] == self.v_synced[i][a]
        return same

    @ti.func
    def _afresh(self, i, some: ti.template()):
        """Whether particle i is staggered afresh (True unless `some`, then where its world is marked changed)."""
        fresh = True
        if ti.static(some):
            fresh = self.world_changed[world_of(self.p, i)] != 0
        return fresh


@register("velocity_verlet")
class VelocityVerlet(Leapfrog):
    """Velocity Verlet (v += dt/2 a; x += dt v; a = f(x)/m; v += dt/2 a) as leapfrog on half-step velocities:
    second order, symplectic for position-only forces, one force evaluation a step plus one per Simulation.step
    call (the synchronisation)."""

    staggered = "v"

    def _stagger(self, dt: float, some: bool = False) -> None:
        self.rates.evaluate()
        self._kick(-0.5 * dt, False, some)

    def _synchronise(self, dt: float) -> None:
        self.rates.evaluate()
        self._kick(0.5 * dt, True, False)

    @ti.kernel
    def _kick(self, h: float, hold: ti.template(), some: ti.template()):
        """v += h a, keeping the velocity before the kick in `held` when `hold`; with `some`, only in the worlds
        marked changed (the others' staggered velocities restored)."""
        self.loops.light()
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            if ti.static(hold):
                self.held[i] = self.p.v[i]
            if self._afresh(i, some):
                self.p.v[i] = self.p.v[i] + h * self.f[i] / self.p.mass[i]
            else:
                self.p.v[i] = self.held[i]


@register("verlet")
class PositionVerlet(Leapfrog):
    """Position Verlet (x += dt/2 v; v += dt a(x); x += dt/2 v) as leapfrog on half-step positions: second order,
    symplectic, one force evaluation a step and none to synchronise; its positions obey Stormer's
    x_{n+1} = 2 x_n - x_{n-1} + dt^2 a(x_{n+1/2}) at the staggered points."""

    staggered = "x"

    def _stagger(self, dt: float, some: bool = False) -> None:
        self._drift(0.5 * dt, False, some)

    def _synchronise(self, dt: float) -> None:
        self._drift(-0.5 * dt, True, False)

    @ti.func
    def _wrap(self, i):
        if ti.static(self.periodic):  # a half drift back may leave a periodic box: wrap (walls stay as they act)
            self.p.x[i], self.p.v[i] = self.domain.enforce(self.p.x[i], self.p.v[i], self.p.radius[i], 0.0, 0)

    @ti.kernel
    def _drift(self, h: float, hold: ti.template(), some: ti.template()):
        """x += h v, keeping the position before the drift in `held` when `hold`; with `some`, only in the worlds
        marked changed (the others' staggered positions restored)."""
        self.loops.light()
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            if ti.static(hold):
                self.held[i] = self.p.x[i]
            if self._afresh(i, some):
                self.p.x[i] = self.p.x[i] + h * self.p.v[i]
                self._wrap(i)
            else:
                self.p.x[i] = self.held[i]
