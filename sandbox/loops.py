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

LIGHT_PARALLEL_FROM = 400_000  # particle slots from which per-particle loops with little work run in parallel
PAIR_PARALLEL_FROM = 8_000  # particle slots from which the pair pass and the neighbour-list build run in parallel
# ... and when the pair force is the whole step (no springs, no heat): such a step is cheap enough that running it
# serially, many steps to a launch (Simulation._fused_steps), beats two threads woken every step up to here. W1 at
# 10,000 particles (15,000 slots), three alternating runs of `sandbox.bench.measure`: 10.2, 11.9, 8.3 M particle-steps/s
# serial and fused, 8.0, 9.2, 8.3 parallel; the 10,000-particle melting block's frame (springs and heat, three times
# the work per particle) 29.6-30.7 ms serial against 21.4-25.2 ms parallel.
PAIR_ONLY_PARALLEL_FROM = 20_000
# ... but from TEAM_FROM to TEAM_UNTIL slots a scene runs many steps to a launch on every thread at once
# (sandbox/team.py): W1 at 10,000 particles, `python benchmarks/team_steps.py` (medians of alternating batches of
# 100 steps in one process): 437-691 us a step as a team of two, 745-1102 serial and fused, 619-938 parallel. Above,
# a scratch script (`sandbox.bench.measure` on W1, three rounds alternating team and parallel loops, thresholds
# overridden): 32k particles 22.2, 20.6, 16.2 M particle-steps/s as a team against 17.6, 16.2, 13.4; 100k 19.1, 13.0,
# 13.3 against 12.4, 12.3, 11.0; 316k 13.4, 12.3, 16.6 against 13.7, 12.8, 12.5; 1M 20.6, 20.0, 18.1 against 22.2,
# 21.7, 13.6: a gain to 100k (150k slots), a draw past it. Scenes with springs and heat (the melting block at a
# size, `/tmp` scratch script, medians of 12 alternating batches of 40 steps): 3,600 particles 0.84 ms a step as a
# team against 0.97 serial and fused; 6,400: 1.15 against 1.40 parallel; 10,000: 2.46 against 2.82; 40,000: 7.95
# against 8.96.
# Smaller scenes pay too (scratch scripts against the serial fused step, alternating batches, medians): the
# melting block at 400 particles 92 us a step against 110, 900 178 against 226, 1,200 (shipped, 2,224 slots) 223
# against 303, 2,025 477 against 649; W1 at 1,024 particles (2,048 slots) 45.9 against 70.1 us, 2,500 101.5 against
# 173.5 (15 batches of 500 steps). Test-sized scenes (under about 1,000 particles) keep the serial fused step.
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


@data_oriented
class LoopPolicy:
    """Put `self.loops.light()` before a per-particle loop with little work per item and `self.loops.pairs()`
    before a loop over neighbour pairs: each serializes the loop that follows it when the scene is small."""

    def __init__(self, arch: str, capacity: int, pair_only: bool = False, threads: int = 1, team_ok: bool = False):
        """`capacity`: particle slots; `pair_only`: no springs, no heat in the step (see PAIR_ONLY_PARALLEL_FROM);
        `threads`: the CPU backend's worker threads; `team_ok`: the scene's steps can run as a team (see
        simulation.can_step_as_a_team). `team`: they will, at this size (the pair loops then keep their parallel layout,
        which the team shares, for the steps that do not run as a team)."""
        cpu = arch == "cpu"
        self.serial_light = cpu and capacity < LIGHT_PARALLEL_FROM
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
