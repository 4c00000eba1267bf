"""Cold compile of the first whole-step launch (the team's or the fused steps' kernel) with Taichi's CFG pass on and
off, in fresh processes with fresh offline caches, alternating; then the step rate of each (what
runtime.without_cfg_pass trades).

    python benchmarks/cfg_pass_compile.py [--scene scenes/lj_box.toml] [--rounds 3]

Prints, per setting, the CPU seconds of the first step (almost all of it the compile) and the microseconds per step of
the next 1,000 steps, each a median over the rounds.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

import this_tree

CHILD = """
import json, sys, time
import taichi as ti
from sandbox.core import runtime
from sandbox.config.scene import load_scene
from sandbox.simulation import Simulation
sim = Simulation(load_scene(sys.argv[1]), arch="cpu")
off = sys.argv[2] == "off"
if not off:  # keep the pass on for the whole-step launch too
    import contextlib
    runtime.without_cfg_pass = contextlib.nullcontext
c0 = time.process_time()
sim.step(1)
ti.sync()
compile_cpu = time.process_time() - c0
sim.step(100)
ti.sync()
t0 = time.perf_counter()
sim.step(1000)
ti.sync()
print(json.dumps({"compile_cpu_s": compile_cpu, "us_per_step": (time.perf_counter() - t0) * 1e3}))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="scenes/lj_box.toml")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    results: dict[str, list[dict]] = {"on": [], "off": []}
    for _ in range(args.rounds):
        for setting in results:
            with tempfile.TemporaryDirectory() as cache:
                # the child imports this checkout's sandbox, as this script does (see this_tree.py)
                env = dict(os.environ, TI_OFFLINE_CACHE_FILE_PATH=cache, PYTHONPATH=str(this_tree.ROOT))
                command = [sys.executable, "-c", CHILD, args.scene, setting]
                out = subprocess.run(command, env=env, capture_output=True, text=True, check=True)
                results[setting].append(json.loads(out.stdout.strip().splitlines()[-1]))
    for setting, runs in results.items():
        compile_cpu = statistics.median(r["compile_cpu_s"] for r in runs)
        step = statistics.median(r["us_per_step"] for r in runs)
        print(f"CFG pass {setting:>3}: first step {compile_cpu:.2f} s of CPU, then {step:.0f} us a step")


if __name__ == "__main__":
    main()
