"""The rates of a step, built from the term list: each particle's force (`force`) and heat rate (`heat_rate`), and
its end-of-step work (`finish_particle`).

Per evaluation: one launch for the terms' per-stage passes (`prestep_loops`: spring updates, power-source masses)
and the neighbour lists' staleness check; the lists rebuilt when stale; then one launch for the rates: the half-list
pair pass (each pair once, every pair term's contribution applied to both particles through per-chunk buffer rows)
and the per-particle gather (body forces, the pair rows, the bonds, heat sources, then any force adjustment),
optionally with the integrator's update of each particle in the same loop. The fused step and the team
(step/fused.py, step/team.py) run these same funcs inside their own launches, so all three ways of stepping sum
the same terms in the same order.
"""

import taichi as ti

from ..core import runtime
from ..core.loops import SPREAD_STRIDE, spread_item
from ..core.oriented import data_oriented
from ..core.particles import fold_bonds
from ..physics.neighbours import LIST_ARRAY, no_lists
from ..physics.term import hook_order

PAIR_BLOCK = 16  # half-list entries computed in one vectorized loop before they are applied (see _blocked_force_pairs)
CHUNKS_PER_THREAD = 2  # half-list pass on the thread pool: blocks of particles per thread, each with its own row


def _having(terms: list, flag: str, hook: str | None = None) -> list:
    """The terms with `flag` set, in the order of their `hook` (default: the flag's name)."""
    return sorted((t for t in terms if getattr(t, flag)), key=lambda t: hook_order(t, hook or flag))


@data_oriented
class Rates:
    """Forces and heat rates of `terms` over the particles of `state` and the neighbourhood `hood` (None: no pair
    terms). Integrators call `evaluate()` and, inside their update kernels, `finish_particle()`; they read `force`
    (and the heat term reads `heat_rate`)."""

    def __init__(self, model, state, terms: list, hood):
        self.model, self.state, self.hood = model, state, hood
        self.dim = model.dim
        self.loops = model.loops
        self.domain = model.domain
        self.springs = state.springs
        capacity = model.capacity
        self.pair_terms = _having(terms, "pair_channel", "pair")
        self.force_pair_terms = [t for t in self.pair_terms if t.pair_channel == "force"]
        self.heat_pair_terms = [t for t in self.pair_terms if t.pair_channel == "heat"]
        self.bond_terms = _having(terms, "bonded", "bond")
        self.force_terms = _having(terms, "particle_force")
        self.heat_terms = _having(terms, "particle_heat")
        self.adjust_terms = _having(terms, "adjusts_force")
        self.prestep_terms = _having(terms, "prestep")
        self.finish_terms = _having(terms, "finishes", "finish")
        self.excluded = [t for t in self.force_pair_terms if t.excludes_bonded]  # not between bonded particles
        if any(t.excludes_bonded for t in self.heat_pair_terms):
            raise ValueError("a heat pair term cannot exclude bonded pairs")
        self.has_heat_rate = bool(self.heat_pair_terms or self.heat_terms)
        self.force = ti.Vector.field(self.dim, float, shape=capacity)  # force of the last evaluation, (C, D)
        if self.has_heat_rate:
            self.heat_rate = ti.field(float, shape=capacity)  # enthalpy rate of the last evaluation, (C,)
        self.has_grid = hood is not None
        self.has_lists = hood is not None and hood.lists is not None
        self.half = self.has_lists and hood.half
        self.marks_bonds = self.has_lists and hood.marks_bonds
        self.no_lists = hood.no_lists if hood is not None else no_lists()
        # 3D rows of pair forces alone (no heat flows, no bonded pairs marked) are computed in vectorized blocks
        # where the CPU's gathers pay (runtime.vector_gathers_pay); W1's rows in 2D (10 pairs a row, against 38) ran
        # slower in blocks even there, so 2D keeps the plain loop
        self.blocked_rows = (
            self.dim == 3 and not self.heat_pair_terms and not self.marks_bonds and runtime.vector_gathers_pay()
        )
        self.worlds = model.worlds  # worlds held, each a contiguous block of ids (world_chunk_rows)
        self.world_size = state.particles.world_size  # ... of this many (the first n / world_size are live)
        lone = model.lone_loops  # how one world alone loops
        self.serial_rows = self.loops.serial_pairs if self.worlds == 1 else lone.serial_pairs
        self.world_chunks = self.worlds > 1 and not lone.serial_pairs
        if self.has_lists:
            # a listed pair is at most reach + skin apart at the build and each has moved under half the skin since
            self.seam_margin = hood.lists.reach + 2.0 * hood.lists.skin
        if self.half:
            # Each worker thread takes a contiguous block of particles and writes what its pairs give to the other
            # particle into its own buffer row (no atomics, no write conflicts); the per-particle pass sums the rows.
            # A team hands each worker its chunks in order, so one each (fewer rows to sum); the thread pool
            # balances two a thread.
            self.n_chunks = (1 if self.loops.team else CHUNKS_PER_THREAD) * max(1, model.threads)
            self.n_pair_rows = 1 if self.loops.serial_pairs else self.n_chunks  # rows the pair pass writes
            # With many worlds, each world's rows are summed as its lone run sums them: where that run's pair pass is
            # serial, by the same serial pass over every world's rows in turn (the same compiled loop: another shape
            # of loop was compiled to sums an ulp away, on ice_cube); else in the lone run's chunks of each world
            # (world_chunk_rows)
            if self.worlds > 1:
                self.n_chunks = (1 if lone.team else CHUNKS_PER_THREAD) * max(1, model.lone_threads)
                self.n_pair_rows = 1 if lone.serial_pairs else self.n_chunks
            self.pair_f = ti.Vector.field(self.dim, float, shape=(self.n_pair_rows, capacity))
            if self.heat_pair_terms:
                self.pair_q = ti.field(float, shape=(self.n_pair_rows, capacity))

    def ids(self, use_lists: bool):
        """The neighbour lists to hand a kernel: the lists when used, else the 1 x 1 stand-in."""
        return self.hood.ids(use_lists) if self.hood is not None else self.no_lists

    def evaluate(self, dt: float | None = None, stage: int = 0, integrator=None) -> None:
        """Forces and heat rates at the current state. With `integrator`: its update_particle(i, dt, stage) on every
        particle in the same launch (one launch less per step: a launch costs about 30 us on the CPU backend)."""
        moved = bool(self._prestep()) if (self.has_lists or self.prestep_terms) else False
        use_list = self.hood.refresh(moved) if self.hood is not None else False
        ids = self.ids(use_list)
        if integrator is None:
            self._rates(use_list, ids)
        else:
            self._rates_update(use_list, ids, integrator, dt, stage)

    @ti.kernel
    def _prestep(self) -> ti.i32:
        """One launch for the per-stage passes (see prestep_loops); returns 1 when some particle has moved half the
        neighbour skin."""
        self.prestep_loops()
        moved = 0
        if ti.static(self.has_lists):
            moved = self.hood.lists.stale[None]
        return moved

    @ti.func
    def prestep_loops(self):
        """The terms' per-stage device work, and whether some particle has moved half the skin (lists.stale)."""
        for term in ti.static(self.prestep_terms):
            term.prestep_loops()
        if ti.static(self.has_lists):
            lists = self.hood.lists
            lists.stale[None] = 0
            lists.check_count()
            self.loops.light()
            for i in range(self.state.particles.n[None]):
                if self.state.particles.idle(i):
                    continue
                lists.check_one(i)

    # ------------------------------------------------------------------ the pair pass over half lists
    @ti.func
    def half_rows_of_chunk(self, t, n, ids: ti.template()):
        """The half-list rows of chunk t of the n particles (a contiguous block of ids), into buffer row t."""
        width = self.hood.lists.width_of(ids)  # once: after a store the compiler reloads the shape and divides again
        for i in range(t * n // self.n_chunks, (t + 1) * n // self.n_chunks):
            self._half_row(t, i, ids, i * width)

    @ti.func
    def world_chunk_rows(self, item, n, ids: ti.template()):
        """With many worlds, item k n_chunks + t: the rows of chunk t of world k (each world a contiguous block of n /
        worlds ids, chunked as its lone run chunks its particles), into buffer row t. No two worlds share a particle,
        so their chunks t share buffer row t without a conflict, and each world's forces are summed in the order of
        its lone run."""
        width = self.hood.lists.width_of(ids)
        size = self.world_size
        k, t = item // self.n_chunks, item % self.n_chunks
        if k < n // size:  # a live world (those past the live count wait to be added: Simulation.add_world)
            first, end = self.state.particles.world_slots(k)  # its live particles
            each = end - first
            for i in range(first + t * each // self.n_chunks, first + (t + 1) * each // self.n_chunks):
                self._half_row(t, i, ids, i * width)

    @ti.func
    def _half_row(self, t, i, ids: ti.template(), row):
        """The pairs (i, j) of i's half list (its row of `ids` starts at `row`): i's share kept, j's (equal and
        opposite) written to chunk t's buffer row. Row t belongs to this chunk alone, so it is updated by a plain load
        and store: `+=` on a field would be an atomic compare-and-swap loop on the CPU (1.4x slower pass). In a
        periodic box a particle away from the seams (all but a few percent) takes a copy of the loop without the
        minimum-image test: it would never shift."""
        p = self.state.particles
        xi = p.x[i]
        rows = [term.row(i) for term in ti.static(self.pair_terms)]
        fi = ti.Vector.zero(float, self.dim)
        qi = 0.0
        if ti.static(self.domain.periodic):
            if self.domain.inside_by(xi, self.seam_margin):
                fi, qi = self._half_pairs(t, i, xi, rows, row, ids, False)
            else:
                fi, qi = self._half_pairs(t, i, xi, rows, row, ids, True)
        else:
            fi, qi = self._half_pairs(t, i, xi, rows, row, ids, False)
        self.pair_f[t, i] = self.pair_f[t, i] + fi
        if ti.static(self.heat_pair_terms):
            self.pair_q[t, i] = self.pair_q[t, i] + qi

    @ti.func
    def _half_pairs(self, t, i, xi, rows: ti.template(), row, ids: ti.template(), wrap: ti.template()):
        """The pairs of i's half-list row starting at `row` in `ids`: each j's share written to buffer row t;
        returns i's (force, heat flow). `wrap`: take the minimum image (else x_j - x_i as it is)."""
        p = self.state.particles
        fi = ti.Vector.zero(float, self.dim)
        qi = 0.0
        if ti.static(self.blocked_rows):
            fi = self._blocked_force_pairs(t, i, xi, rows, row, ids, wrap)
        else:
            for k in range(self.hood.lists.count[i]):
                j = ids[row + k]
                bonded = False  # joined by a live spring: no pair force (heat still flows)
                if ti.static(self.marks_bonds):
                    if j < 0:
                        s = -j - 1
                        j = self.springs.other_end(i, s)
                        bonded = self.springs.alive[s] != 0
                d = p.x[j] - xi
                if ti.static(wrap):
                    d = self.domain.separation(xi, p.x[j])
                r2 = d.dot(d)
                if ti.static(self.force_pair_terms):
                    fij = self._pair_sum("force", rows, i, j, d, r2, bonded)
                    fi += fij
                    self.pair_f[t, j] = self.pair_f[t, j] - fij
                if ti.static(self.heat_pair_terms):
                    qij = self._pair_sum("heat", rows, i, j, d, r2, bonded)
                    qi += qij
                    self.pair_q[t, j] = self.pair_q[t, j] - qij
        return fi, qi

    @ti.func
    def _blocked_force_pairs(self, t, i, xi, rows: ti.template(), row, ids: ti.template(), wrap: ti.template()):
        """_half_pairs for rows of pair forces alone (see blocked_rows), PAIR_BLOCK entries at a time: one loop
        computes each pair's force into a local block and sums i's with no store to a field, so the compiler runs it
        on the vector units (gathering the neighbours' positions); a scalar loop then applies the block to the other
        particles. Returns the force on i."""
        p = self.state.particles
        fi = ti.Vector.zero(float, self.dim)
        count = self.hood.lists.count[i]
        for block in range((count + PAIR_BLOCK - 1) // PAIR_BLOCK):
            first = row + block * PAIR_BLOCK
            size = ti.min(PAIR_BLOCK, count - block * PAIR_BLOCK)
            js = ti.Vector.zero(ti.i32, PAIR_BLOCK)
            fs = ti.Matrix.zero(float, PAIR_BLOCK, self.dim)
            for k in range(size):
                j = ids[first + k]
                d = p.x[j] - xi
                if ti.static(wrap):
                    d = self.domain.separation(xi, p.x[j])
                fij = self._pair_sum("force", rows, i, j, d, d.dot(d), False)
                fi += fij
                js[k] = j
                for a in ti.static(range(self.dim)):
                    fs[k, a] = fij[a]
            for k in range(size):
                j = js[k]
                self.pair_f[t, j] = self.pair_f[t, j] - ti.Vector([fs[k, a] for a in ti.static(range(self.dim))])
        return fi

    @ti.func
    def _pair_sum(self, channel: ti.template(), rows: ti.template(), i, j, d, r2, bonded):
        """The `channel` pair terms' contributions on i from j, summed (rows: each pair term's row(i)). The sum starts
        at the first term's, not at zero: 0 + x is not folded (it is not x for x = -0), an add per pair and axis."""
        which = ti.static([n for n, term in enumerate(self.pair_terms) if term.pair_channel == channel])
        total = self.pair_terms[which[0]].pair(rows[which[0]], i, j, d, r2, bonded)
        for n in ti.static(which[1:]):
            total += self.pair_terms[n].pair(rows[n], i, j, d, r2, bonded)
        return total

    # ------------------------------------------------------------------ the rates launch
    @ti.kernel
    def _rates(self, use_list: ti.template(), ids: LIST_ARRAY):
        self.rate_loops(use_list, ids, None, 0.0, 0, False)

    @ti.kernel
    def _rates_update(
        self, use_list: ti.template(), ids: LIST_ARRAY, integrator: ti.template(), dt: float, stage: ti.i32
    ):
        merged = ti.static(self.updates_in_gather(use_list))
        self.rate_loops(use_list, ids, integrator, dt, stage, merged)
        if ti.static(not merged):
            self.loops.light()
            for i in range(self.state.particles.n[None]):
                if self.state.particles.idle(i):
                    continue
                integrator.update_particle(i, dt, stage)

    def updates_in_gather(self, use_list: bool) -> bool:
        """Whether the per-particle pass may update each particle as soon as its force is summed (one pass over the
        particles less): when that pass reads nothing of other particles, i.e. the pair terms come from the
        half-list rows or there are none, and there are no bonds (their force reads the other end) and no force
        adjustments (kinematic particles)."""
        pairs_precomputed = not self.has_grid or (use_list and self.half)
        return pairs_precomputed and not self.bond_terms and not self.adjust_terms

    @ti.func
    def rate_loops(
        self,
        use_list: ti.template(),
        ids: ti.template(),
        integrator: ti.template(),
        dt,
        stage,
        update_here: ti.template(),
    ):
        """The loops of an evaluation (see evaluate); each runs in parallel unless self.loops serializes it.
        `update_here` (allowed when updates_in_gather): the per-particle pass also updates each particle by `dt` with
        `integrator`'s `stage` once its rates are in."""
        p = self.state.particles
        if ti.static(use_list and self.half and self.world_chunks):
            # each world's chunks on the thread pool, serial or not: a serialized loop of items compiled to sums in
            # another order than the lone run's (measured: an ulp on a few particles a step)
            n = p.n[None]
            for u in range(self.worlds * self.n_chunks * SPREAD_STRIDE):
                item = spread_item(u)
                if item >= 0:
                    self.world_chunk_rows(item, n, ids)
        elif ti.static(use_list and self.half):
            n = p.n[None]
            if ti.static(self.serial_rows):  # the lone run's serial pass: every world's rows, a world after another
                width = self.hood.lists.width_of(ids)
                ti.loop_config(serialize=True)
                for i in range(n):
                    self._half_row(0, i, ids, i * width)
            else:
                for u in range(self.n_chunks * SPREAD_STRIDE):  # a loop over the chunks alone runs on one thread
                    t = spread_item(u)
                    if t >= 0:
                        self.half_rows_of_chunk(t, n, ids)
        if ti.static(self.bond_terms):
            self.loops.pairs()  # each particle visits its bonds too: as much work per item as a pair loop
        else:
            self.loops.light()
        for ks in range(p.n[None]):
            i = ks
            if ti.static(self.has_grid):
                i = self.hood.grid.sorted_ids[ks]  # visit particles cell by cell: neighbours stay in cache
            if p.idle(i):
                continue
            self.gather_particle(i, use_list, ids, integrator, dt, stage, update_here)

    @ti.func
    def gather_particle(
        self,
        i,
        use_list: ti.template(),
        ids: ti.template(),
        integrator: ti.template(),
        dt,
        stage,
        update_here: ti.template(),
    ):
        """Particle i's force and heat rate: the body forces, its pair terms (summed from the half-list rows, or
        gathered from its list or the grid), its bonds, its heat sources, any adjustment; then, with `update_here`,
        its update by `dt` (the integrator's `stage`)."""
        p = self.state.particles
        xi = p.x[i]
        f = ti.Vector.zero(float, self.dim)
        for term in ti.static(self.force_terms):  # gravity, drag, ...
            f += term.force(i)
        q = 0.0
        gathers = ti.static(self.has_grid and not (use_list and self.half))  # pairs visited from i's side here
        rows = [term.row(i) for term in ti.static(self.pair_terms if gathers else [])]
        if ti.static(self.has_grid):
            pairs = ti.Vector.zero(float, self.dim + 1)  # the pair terms' force on i, then their heat flow into it
            if ti.static(use_list and self.half):
                for t in range(self.n_pair_rows):  # what the pair pass left for i, read and cleared
                    for a in ti.static(range(self.dim)):
                        pairs[a] += self.pair_f[t, i][a]
                    self.pair_f[t, i] = ti.Vector.zero(float, self.dim)
                    if ti.static(self.heat_pair_terms):
                        pairs[self.dim] += self.pair_q[t, i]
                        self.pair_q[t, i] = 0.0
            elif ti.static(use_list):
                row = self.hood.lists.row(i, ids)
                for k in range(self.hood.lists.count[i]):
                    j = ids[row + k]
                    pairs = self._add_pair(pairs, j, self.domain.separation(xi, p.x[j]), k, (i, rows))
            else:
                pairs = self.hood.grid.fold(i, xi, pairs, self._add_pair, (i, rows))
            for a in ti.static(range(self.dim)):
                f[a] += pairs[a]
            q += pairs[self.dim]
        if ti.static(self.bond_terms):
            excluding = ti.static(gathers and len(self.excluded) > 0)  # half rows skip bonded pairs themselves
            f = fold_bonds(self.springs, i, f, self._add_bond, (xi, rows, excluding))
        for term in ti.static(self.adjust_terms):  # kinematic particles: no force
            f = term.adjust_force(i, f)
        self.force[i] = f
        if ti.static(self.has_heat_rate):
            for term in ti.static(self.heat_terms):
                q += term.heat(i)
            self.heat_rate[i] = q / p.mass[i]
        if ti.static(update_here):
            integrator.update_particle(i, dt, stage)

    @ti.func
    def _add_pair(self, acc, j, d, k, extra: ti.template()):
        """acc (force on i = extra[0], then heat flow into it) plus neighbour j's pair terms (extra[1]: their rows)."""
        i = extra[0]
        rows = ti.static(extra[1])
        if j != i:
            r2 = d.dot(d)
            if ti.static(self.force_pair_terms):
                fij = self._pair_sum("force", rows, i, j, d, r2, False)
                for a in ti.static(range(self.dim)):
                    acc[a] += fij[a]
            if ti.static(self.heat_pair_terms):
                acc[self.dim] += self._pair_sum("heat", rows, i, j, d, r2, False)
        return acc

    @ti.func
    def _add_bond(self, f, i, j, s, extra: ti.template()):
        """f plus the bond terms' force on i from live spring s to j; where the pairs were gathered from i's side,
        less the pair terms that exclude bonded pairs (extra: x_i, the pair rows of i, whether to exclude)."""
        xi = extra[0]
        rows = ti.static(extra[1])
        d = self.domain.separation(xi, self.state.particles.x[j])
        for term in ti.static(self.bond_terms):
            f += term.bond(i, j, s, d)
        if ti.static(extra[2]):
            r2 = d.dot(d)
            for n in ti.static(range(len(self.pair_terms))):
                if ti.static(self.pair_terms[n].excludes_bonded):
                    f -= self.pair_terms[n].pair(rows[n], i, j, d, r2, False)
        return f

    @ti.func
    def finish_particle(self, i, dt):
        """Particle i's end-of-step work: each finishing term in order (walls or the periodic wrap, kinematic
        particles put back, the explicit heat update)."""
        for term in ti.static(self.finish_terms):
            term.finish(i, dt, self)

    def describe(self) -> str:
        """The rates launch and the terms it sums, in words: the pair terms, the bonds, then the particle terms."""
        words, seen = [], []
        for term in self.pair_terms + self.bond_terms + self.force_terms + self.heat_terms:
            if term not in seen:
                seen.append(term)
                words += term.words("rates")
        pairs = " (each neighbour pair once, applied to both)" if self.half else ""
        return f"fused rates kernel{pairs}: " + ", ".join(words)
