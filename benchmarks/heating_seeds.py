"""The boiling plateau's shift with the lid's pressure over several seeds: how far the heating study's single
trajectories can be trusted.

    python benchmarks/heating_seeds.py [SEEDS]      (default 4; two runs a seed, about 100 s each on 2 cores)

Each seed heats the study's 365-atom crystal (research/heating_curve.py, the same power and lids) from its own
starting velocities, and prints the boiling liquid's kT under each lid, the shift between the lids, and their means
with standard errors beside the measured coexistence curve's boiling points and shift.
"""

import math
import sys

import numpy as np
import this_tree  # noqa: F401  (this checkout's sandbox, not the installed one)

from sandbox.measure.coexistence_curve import shipped_curve
from sandbox.research.heating_curve import run_heating

PRESSURES = (0.015, 0.03)
POWER = 2.0


def main(seeds: int) -> None:
    curve = shipped_curve(3)
    expected = [curve.boiling_temperature(p) for p in PRESSURES]
    rows = []
    for seed in range(1, seeds + 1):
        plateaus = [run_heating(p, POWER, seed=seed).plateau() for p in PRESSURES]
        rows.append(plateaus)
        print(f"seed {seed}: " + ", ".join(f"lid {p:g}: kT {t:.3f}" for p, t in zip(PRESSURES, plateaus))
              + f", shift {plateaus[1] - plateaus[0]:+.3f}", flush=True)  # fmt: skip
    data = np.array(rows)
    shift = data[:, 1] - data[:, 0]
    err = lambda v: v.std(ddof=1) / math.sqrt(len(v)) if len(v) > 1 else math.nan  # noqa: E731
    for k, p in enumerate(PRESSURES):
        print(f"lid {p:g}: boiling liquid's kT {data[:, k].mean():.3f} +- {err(data[:, k]):.3f} "
              f"(the curve's boiling point {expected[k]:.3f})")  # fmt: skip
    print(f"shift {shift.mean():+.3f} +- {err(shift):.3f} (the curve's {expected[1] - expected[0]:+.3f})")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 4)
