"""Which of a step's loops run in parallel on the CPU backend, chosen by the scene's size.

Taichi's CPU backend hands every top-level loop of a kernel to its thread pool, and on the 2-core machines that
round trip costs 20-40 us per loop (`python benchmarks/loop_overhead.py`: three loops of `x[i] += 1` over 1,000
items take 79 us in parallel and 25 us serialized; over 100,000 items 240 vs 237 us; an empty kernel 17 us).
A step has several loops that do a few loads and stores per particle (the integrator's update, the neighbour-list
check, the per-particle gather of the pair pass) and one or two that do real work per particle (the pair pass, the
list build). The first kind runs on the calling thread below LIGHT_PARALLEL_FROM particle slots, the second below
PAIR_PARALLEL_FROM. On a GPU everything stays parallel. The choice is fixed when a Simulation is built (by its
capacity), so kernels compile once.
"""

import taichi as ti

from .oriented import data_oriented

LIGHT_PARALLEL_FROM = 400_000  # slots from which per-particle loops with little work run in parallel, on 2 threads
PAIR_PARALLEL_FROM = 8_000  # particle slots from which the pair pass and the neighbour-list build run in parallel
# ... and when the pair force is the whole step (no springs, no heat): such a step is cheap enough that running it
# serially, many steps to a launch (Simulation._fused_steps), beats two threads woken every step up to here; a step
# with springs and heat does about three times the work per particle and gains from the parallel loops earlier.
PAIR_ONLY_PARALLEL_FROM = 20_000
# ... but from TEAM_FROM to TEAM_UNTIL slots a scene runs many steps to a launch on every thread at once
# (step/team.py): faster than both the serial fused step and the parallel loops from about 2,000 slots (pair-only
# or with springs and heat) to about 150,000, a draw past that. `python benchmarks/team_steps.py [--scene S --side N]`
# compares the three ways in one process; docs/performance.md says how the thresholds were chosen.
TEAM_FROM = 2_000
TEAM_UNTIL = 200_000
# Taichi's CPU range-for hands each thread blocks of consecutive iterations (under 256 of them: 8 heavy items 64
# iterations apart ran on one thread, 256 or more apart on both), so a loop over a few heavy items (the half-list
# pass's chunks, the renderer's screen strips) runs over items * SPREAD_STRIDE iterations instead: see spread_item.
SPREAD_STRIDE = 512


@ti.func
def spread_item(u):
    """The item that iteration u of `for u in range(items * SPREAD_STRIDE)` starts (u // SPREAD_STRIDE), or -1 for
    the empty iterations between items, which only spread the items over the threads."""
    item = -1
    if u % SPREAD_STRIDE == 0:
        item = u // SPREAD_STRIDE
    return item


def light_parallel_from(threads: int) -> int:
    """Particle slots from which the light loops run in parallel with `threads` CPU workers: LIGHT_PARALLEL_FROM on
    two (where it was measured), fewer with more workers, whose pool pays for itself sooner. On a 16-core Xeon a
    3D box of 262,144 atoms stepped at 1.0 M particle-steps/s with its light loops on one thread and 7.5-7.8 M with
    them in parallel (docs/performance.md, "Per CPU")."""
    return LIGHT_PARALLEL_FROM * 2 // max(threads, 2)


@data_oriented
class LoopPolicy:
    """Put `self.loops.light()` before a per-particle loop with little work per item and `self.loops.pairs()`
    before a loop over neighbour pairs: each serializes the loop that follows it when the scene is small."""

    def __init__(self, arch: str, capacity: int, pair_only: bool = False, threads: int = 1, team_ok: bool = False):
        """`capacity`: particle slots; `pair_only`: no springs, no heat in the step (see PAIR_ONLY_PARALLEL_FROM);
        `threads`: the CPU backend's worker threads; `team_ok`: the scene's steps can run as a team (see
        step.plan.can_step_as_a_team). `team`: they will, at this size (the pair loops then keep their parallel layout,
        which the team shares, for the steps that do not run as a team)."""
        cpu = arch == "cpu"
        # on a GPU the grid's sort sums the cells' counts in blocks (CellGrid.prefix_sum) and a list build stores
        # only the neighbours it keeps (NeighbourList._scan): loops shaped for many threads and their memory
        self.gpu = not cpu
        self.serial_light = cpu and capacity < light_parallel_from(threads)
        self.serial_pairs = cpu and capacity < (PAIR_ONLY_PARALLEL_FROM if pair_only else PAIR_PARALLEL_FROM)
        self.team = cpu and team_ok and threads >= 2 and TEAM_FROM <= capacity < TEAM_UNTIL
        if self.team:
            self.serial_pairs = False

    @ti.func
    def light(self):
        """Serialize the next loop when per-particle loops with little work are not worth the thread pool."""
        if ti.static(self.serial_light):
            ti.loop_config(serialize=True)

    @ti.func
    def pairs(self):
        """Serialize the next loop when pair loops are not worth the thread pool."""
        if ti.static(self.serial_pairs):
            ti.loop_config(serialize=True)

    def describe(self) -> str:
        kinds = [name for name, serial in (("light", self.serial_light), ("pair", self.serial_pairs)) if serial]
        text = f"serial loops: {', '.join(kinds)}" if kinds else "all loops parallel"
        return text + (" (steps as a team of threads where the scene allows)" if self.team else "")
