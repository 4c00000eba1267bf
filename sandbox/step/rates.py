"""The rates of a step: forces (p.f) and heat rates (p.dhdt) of every term the scene has, over its neighbour
structure (half lists, full lists or the cell grid), and each particle's end-of-step work (walls, the enthalpy
update). A mixin of Simulation: the integrators call eval_rates() and, inside their update kernels,
finish_particle(); the fused step and the team call the loops below inside their own launches.

Per evaluation: the cheap per-step passes (_prestep: has a particle moved half the skin, the springs' thermoelastic
update and breaking, power sources' masses), the neighbour lists rebuilt when stale, then one kernel: the half-list
pair pass (each pair once, into per-chunk buffer rows) and the per-particle gather (the body forces, the pair
terms, the springs, heat sources), optionally with the integrator's update of each particle in the same loop.
"""

import warnings

import taichi as ti

from ..config.scene_tables import COUPLINGS
from ..core.loops import SPREAD_STRIDE, spread_item
from ..physics.emitters import NEVER_BONDS
from ..physics.neighbours import LIST_ARRAY
from ..physics.phase import LIQUID

NO_COUPLING, KINEMATIC = (COUPLINGS.index(c) for c in ("none", "kinematic"))


class Rates:
    """Simulation's rate evaluation (see the module docstring)."""

    def _lists(self, use: bool):
        """The neighbour lists to hand a kernel: the lists when the step uses them, else the 1 x 1 stand-in."""
        return self.neighbours.ids if use else self.no_lists

    def eval_rates(self, then_update: float | None = None, stage: int = 0) -> None:
        """Forces (p.f) and heat rates (p.dhdt) at the current state. `then_update`: a step dt for the integrator's
        per-particle update of `stage` (`update_particle`), run in the same kernel launch as the forces (one launch
        less per step: a launch costs about 30 us on the CPU backend)."""
        use_list = False
        moved = bool(self._prestep()) if (self.has_neighbours or self.has_springs or self.has_power) else False
        if self.neighbours is not None:
            use_list = self.neighbours.ensure_fresh(moved)
            if not use_list:
                self.grid.rebuild()  # the fallback scans the grid, which must match the current positions
            if not use_list and not self._warned_overflow:
                self._warned_overflow = True
                warnings.warn(
                    "neighbour list overflow: some particle has more than "
                    f"{self.neighbours.width} neighbours; scanning the cell grid instead (slower)",
                    stacklevel=2,
                )
        elif self.grid is not None:
            self.grid.rebuild()
        ids = self._lists(use_list)
        if then_update is None:
            self._rates(use_list, ids)
        else:
            self._rates_update(use_list, ids, self.integrator, then_update, stage)

    @ti.kernel
    def _prestep(self) -> ti.i32:
        """One launch for the cheap per-step passes (see _prestep_loops); returns 1 when some particle has moved half
        the neighbour skin."""
        self._prestep_loops()
        moved = 0
        if ti.static(self.has_neighbours):
            moved = self.neighbours.stale[None]
        return moved

    @ti.func
    def _prestep_loops(self):
        """Has any particle moved half the neighbour skin (sets neighbours.stale), the springs' thermoelastic update
        and breaking, and the mass inside each power source."""
        if ti.static(self.has_power):
            for k in range(self.heat.n_sources):
                self.heat.src_mass[k] = 0.0
            self.loops.light()
            for i in range(self.particles.n[None]):
                self.heat.add_source_mass(i)
        if ti.static(self.has_neighbours):
            self.neighbours.stale[None] = 0
            self.neighbours.check_count()
            self.loops.light()
            for i in range(self.particles.n[None]):
                self.neighbours.check_one(i)
        if ti.static(self.has_springs):
            # each spring's update reads two phase states: heavier than a light loop, so parallel with the pair loops
            self.loops.pairs()
            for s in range(self.springs.span[None]):
                self.springs.update_one(s)

    @ti.func
    def _pair_terms(self, i, j, d, r2, f_scaled, f_visc, q):
        """Add the pair force (scaled by 1/m_i), the viscous force and the heat flow of neighbour j to i."""
        if ti.static(self.has_pair):
            if r2 < self.pair.cutoff**2:
                f_scaled += self.pair.scaled_force(i, j, d, r2)
                f_visc += self.pair.viscous_force(i, j, d, r2)
        if ti.static(self.has_explicit_heat):
            if r2 < self.heat.support**2:
                q += self.heat.flow(i, j, r2)
        return f_scaled, f_visc, q

    @ti.func
    def half_rows_of_chunk(self, t, n, ids: ti.template()):
        """The half-list rows of chunk t of the n particles (a contiguous block of ids), into buffer row t."""
        for i in range(t * n // self.n_chunks, (t + 1) * n // self.n_chunks):
            self._half_row(t, i, ids)

    @ti.func
    def _half_row(self, t, i, ids: ti.template()):
        """The pairs (i, j) of i's half list: i's share kept, j's (equal and opposite) written to chunk t's buffer
        row. Row t belongs to this chunk alone, so it is updated by a plain load and store: `+=` on a field would be
        an atomic compare-and-swap loop on the CPU (1.4x slower pass). Forces and heat flows are evaluated for every
        listed pair and masked beyond their range rather than branched around: a listed pair lies within reach +
        skin, where both laws are finite, and a branch taken for 80% of pairs mispredicts often."""
        p = self.particles
        xi = p.x[i]
        m_i = p.mass[i]
        fi = ti.Vector.zero(float, self.dim)
        qi = 0.0
        shared = ti.Vector.zero(float, 5)
        if ti.static(self.has_pair):
            shared = self.pair.shared_coefficients()
        t_i, c_i, mat_i = 0.0, 0.0, 0
        if ti.static(self.has_explicit_heat):
            t_i, c_i, mat_i = self.heat.own_terms(i)
        for k in range(self.neighbours.count[i]):
            j = ids[i, k]
            bonded = False  # joined by a live spring: no pair force (heat still flows)
            if ti.static(self.marks_bonds):
                if j < 0:
                    s = -j - 1
                    j = self.springs.other_end(i, s)
                    bonded = self.springs.alive[s] != 0
            d = self.domain.separation(xi, p.x[j])
            r2 = d.dot(d)
            if ti.static(self.has_pair):
                fij = self.pair.force_with(self.pair.pair_coefficients(shared, i, j), m_i, i, j, d, r2)
                fij *= ti.select((r2 < self.pair.cutoff**2) and not bonded, 1.0, 0.0)
                fi += fij
                self.pair_f[t, j] = self.pair_f[t, j] - fij
            if ti.static(self.has_explicit_heat):
                qij = ti.select(r2 < self.heat.support**2, 1.0, 0.0) * self.heat.flow_with(t_i, c_i, mat_i, j, r2)
                qi += qij
                self.pair_q[t, j] = self.pair_q[t, j] - qij
        self.pair_f[t, i] = self.pair_f[t, i] + fi
        if ti.static(self.has_explicit_heat):
            self.pair_q[t, i] = self.pair_q[t, i] + qi

    @ti.kernel
    def _rates(self, use_list: ti.template(), ids: LIST_ARRAY):
        self._rate_loops(use_list, ids, None, 0.0, 0, False)

    @ti.kernel
    def _rates_update(
        self, use_list: ti.template(), ids: LIST_ARRAY, integrator: ti.template(), dt: float, stage: ti.i32
    ):
        merged = ti.static(self._updates_in_gather(use_list))
        self._rate_loops(use_list, ids, integrator, dt, stage, merged)
        if ti.static(not merged):
            self.loops.light()
            for i in range(self.particles.n[None]):
                integrator.update_particle(i, dt, stage)

    def _updates_in_gather(self, use_list: bool) -> bool:
        """Whether the per-particle pass of _rate_loops may update each particle as soon as its force is summed (one
        pass over the particles less): when that pass reads nothing of other particles, i.e. the pair terms come
        from the half-list rows or there are none, and there are no springs (their force reads the other end) and
        no kinematic particles."""
        pairs_precomputed = not self.has_grid or (use_list and self.half_pairs)
        return pairs_precomputed and not self.has_springs and not self.has_kinematic

    @ti.func
    def _rate_loops(
        self,
        use_list: ti.template(),
        ids: ti.template(),
        integrator: ti.template(),
        dt,
        stage,
        update_here: ti.template(),
    ):
        """The loops of a force and heat-rate evaluation (see eval_rates); each runs in parallel unless self.loops
        serializes it. `update_here` (allowed when _updates_in_gather): the per-particle pass also updates each
        particle by `dt` with `integrator`'s `stage` once its rates are in."""
        p = self.particles
        if ti.static(use_list and self.half_pairs):
            n = p.n[None]
            if ti.static(self.loops.serial_pairs):
                ti.loop_config(serialize=True)
                for i in range(n):
                    self._half_row(0, i, ids)
            else:
                for u in range(self.n_chunks * SPREAD_STRIDE):  # a loop over the chunks alone runs on one thread
                    t = spread_item(u)
                    if t >= 0:
                        self.half_rows_of_chunk(t, n, ids)
        if ti.static(self.has_springs):
            self.loops.pairs()  # each particle visits its bonds too: as much work per item as a pair loop
        else:
            self.loops.light()
        for ks in range(p.n[None]):
            i = ks
            if ti.static(self.has_grid):
                i = self.grid.sorted_ids[ks]  # visit particles cell by cell: neighbours stay in cache
            self._gather_particle(i, use_list, ids, integrator, dt, stage, update_here)

    @ti.func
    def _gather_particle(
        self,
        i,
        use_list: ti.template(),
        ids: ti.template(),
        integrator: ti.template(),
        dt,
        stage,
        update_here: ti.template(),
    ):
        """Particle i's force (p.f) and heat rate (p.dhdt): the body forces (gravity, drag, ...), its pair terms
        (summed from the half-list rows, or gathered from its list or the grid), its springs; then, with
        `update_here`, its update by `dt` (the integrator's `stage`)."""
        p = self.particles
        xi = p.x[i]
        f = ti.Vector.zero(float, self.dim)
        for term in ti.static(self.body_forces):  # gravity, drag, ... (physics/body_forces.py)
            f += term.force(i)
        q = 0.0
        if ti.static(self.has_grid):
            f_scaled = ti.Vector.zero(float, self.dim)  # pair-law forces / m_i
            f_visc = ti.Vector.zero(float, self.dim)
            if ti.static(use_list and self.half_pairs):
                for t in range(self.n_pair_rows):  # what the pair pass left for i, read and cleared
                    f_visc += self.pair_f[t, i]
                    self.pair_f[t, i] = ti.Vector.zero(float, self.dim)
                    if ti.static(self.has_explicit_heat):
                        q += self.pair_q[t, i]
                        self.pair_q[t, i] = 0.0
            elif ti.static(use_list):
                for k in range(self.neighbours.count[i]):
                    j = ids[i, k]
                    d = self.domain.separation(xi, p.x[j])
                    f_scaled, f_visc, q = self._pair_terms(i, j, d, d.dot(d), f_scaled, f_visc, q)
            else:
                c = self.grid.cell_of(xi)
                for o in range(self.grid.n_offsets):
                    nc, shift = self.grid.neighbour_cell(c, self.grid.offset(o))
                    if nc >= 0:
                        start = self.grid.cell_start[nc]
                        xs = xi - shift
                        for k in range(start, start + self.grid.cell_count[nc]):
                            j = self.grid.sorted_ids[k]
                            if j != i:
                                d = self.grid.x_sorted[k] - xs
                                f_scaled, f_visc, q = self._pair_terms(i, j, d, d.dot(d), f_scaled, f_visc, q)
            f += p.mass[i] * f_scaled + f_visc
        if ti.static(self.has_springs):
            for k in range(self.springs.max_bonds):
                s = self.springs.bonds[i, k]
                if s < 0:
                    break
                if self.springs.alive[s]:
                    j = self.springs.other_end(i, s)
                    d = self.domain.separation(xi, p.x[j])
                    f += self.springs.force(i, j, s, d)
                    if ti.static(self.has_pair and not (use_list and self.half_pairs and self.marks_bonds)):
                        r2 = d.dot(d)
                        if r2 < self.pair.cutoff**2:  # bonded pairs feel the spring, not the pair force
                            f -= self.pair.force(i, j, d, r2)
        if ti.static(self.has_kinematic):
            if self.g_coupling[p.group[i]] == KINEMATIC:
                f = ti.Vector.zero(float, self.dim)  # moved by the field alone (_advect_kinematic)
        p.f[i] = f
        if ti.static(self.has_explicit_heat):
            q += self.heat.source_flow(i)
            p.dhdt[i] = q / p.mass[i]
        if ti.static(update_here):
            integrator.update_particle(i, dt, stage)

    @ti.func
    def finish_particle(self, i, dt):
        """Walls (or periodic wrap) and the explicit heat update for particle i, at the end of a step."""
        p = self.particles
        p.x[i], p.v[i] = self.domain.enforce(p.x[i], p.v[i], p.radius[i], p.mass[i])
        if ti.static(self.has_kinematic):
            if self.g_coupling[p.group[i]] == KINEMATIC:  # the integrator does not move them: _advect_kinematic does
                p.x[i], p.v[i] = self.x_start[i], self.v_start[i]
        if ti.static(self.has_explicit_heat):
            self.set_enthalpy(i, p.h[i] + dt * p.dhdt[i])

    @ti.func
    def set_enthalpy(self, i, h):
        """Give particle i specific enthalpy h (held by fixed sources), and its temperature and liquid flag."""
        p = self.particles
        if ti.static(self.has_fixed):
            h = self.heat.held(i, h)
        p.h[i] = h
        t, phi = self.phase.state(h, p.material[i])
        p.T[i] = t
        if ti.static(self.can_refreeze):
            if phi >= self.materials.break_fraction[p.material[i]] and p.liquid[i] != NEVER_BONDS:
                p.liquid[i] = LIQUID

    @ti.kernel
    def sync_temperatures(self):
        """Recompute every particle's enthalpy from its temperature (after the temperature was set directly)."""
        for i in range(self.particles.n[None]):
            self.particles.h[i] = self.phase.enthalpy(self.particles.T[i], self.particles.material[i])
            self.set_enthalpy(i, self.particles.h[i])
