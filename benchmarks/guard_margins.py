"""How close each shipped scene comes to the blow-up guard's limits over its whole run (no drawing).

    python benchmarks/guard_margins.py [SCENE ...]

For every frame it reads the measurement the guard checks and prints, per scene, the largest fraction of each limit
used: kinetic energy over RUNAWAY_FACTOR x the energy scale, one step's travel over half the domain, and the
temperature range seen against the range allowed. A healthy scene stays far below 1 on each.
"""

import sys
import time

import this_tree  # noqa: F401  (this checkout's sandbox, not the installed one)

from sandbox.config.resources import shipped_scenes
from sandbox.config.scene import load_scene
from sandbox.measure.guard import RUNAWAY_FACTOR
from sandbox.simulation import Simulation


def margins(path) -> str:
    scene = load_scene(path)
    sim = Simulation(scene, arch="cpu")
    limits = sim.guard.limits
    energy = travel = 0.0
    coldest, hottest = float("inf"), float("-inf")
    start = time.perf_counter()
    heated = sim.terms.heat is not None
    for _ in range(scene.render.frames):
        sim.advance_frame()
        acc = sim.diagnostics.measure(pairs=False)  # the sums the guard reads (Simulation.stats checks them)
        sim.stats(pair_energy=False)
        scale = RUNAWAY_FACTOR * limits.energy_scale(acc["mass"])
        energy = max(energy, acc["ke"] / scale if scale > 0 else 0.0)
        travel = max(travel, acc["vmax"] * sim.dt / limits.step_travel)
        if heated:
            coldest, hottest = min(coldest, -acc["tcold"]), max(hottest, acc["thot"])
    if not heated:
        heat = "no heat"
    elif coldest > hottest:  # the sums' sentinels: no particle was measured (an empty box)
        heat = "no particles"
    else:
        heat = f"T {coldest:.1f}..{hottest:.1f} C of {limits.temperature_lo:.0f}..{limits.temperature_hi:.0f}"
    wall = time.perf_counter() - start
    return (
        f"{path.stem:18s} {scene.render.frames:4d} frames  energy {energy:.1e}  travel {travel:.1e}  {heat}"
        f"  ({wall:.0f} s)"
    )


def main() -> None:
    names = set(sys.argv[1:])
    for path in shipped_scenes():
        if not names or path.stem in names:
            print(margins(path), flush=True)


if __name__ == "__main__":
    main()
