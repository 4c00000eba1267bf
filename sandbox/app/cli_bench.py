"""`sandbox bench`: runs the research benchmarks (research/bench.py) and the window's (bench_window.py), prints them
as a table and writes them as JSON."""

from __future__ import annotations

import json
import os
import platform
import tempfile
from pathlib import Path

from ..config.arguments import check_count, check_file_output, check_folder_output
from ..config.resources import shipped_scenes
from ..core import runtime
from ..core.cores import usable_cores
from ..errors import SandboxError
from ..research.bench import (
    LIKE_LAMMPS,
    PEER_ROUNDS,
    against_lammps,
    integrator_rates,
    lammps_at_its_best,
    launches_per_step,
    lj_box_3d_sim,
    lj_box_sim,
    measure,
    measure_from_start,
    melting_block_sim,
    no_lammps,
    render_cost,
    scaling,
    spring_heat_lattice_sim,
    startup_seconds,
)
from ..research.peer_bench import LAMMPS_POLICIES, ideal_pair_rate, pair_rate
from .bench_window import interactive_frame, print_window_rates, window_rates


def cmd_bench(args) -> int:
    """`sandbox bench`: its arguments checked (one line for a bad one), then run_bench."""
    check_count("--repeats", args.repeats, 1, 1000)
    if args.rounds is not None:
        if not args.lammps:
            raise SandboxError("--rounds: only with --lammps (rounds alternate the sandbox and LAMMPS)")
        check_count("--rounds", args.rounds, 1, 50)
    if args.contended is not None:
        check_count("--contended", args.contended, 1, 16)
    if args.side is not None:
        if not (args.three_d or args.contended):
            raise SandboxError("--side: only with --3d or --contended (the comparison against LAMMPS)")
        check_count("--side", args.side, 8, 100 if args.three_d else 1000)
    if args.json is not None:
        check_file_output("--json", args.json, (".json",))
    if args.scaling:
        check_folder_output("--out", args.out)
    if args.cache is not None:
        check_count("--cache", args.cache, 1, 100_000_000)
        check_count("--cache-frames", args.cache_frames, 1, 100_000)
    runtime.require(args.arch, "f32")

    return run_bench(args)


def run_bench(args) -> int:
    """`sandbox bench`: one of the single benchmarks its options name, else the whole set, printed (and written as
    JSON with --json)."""
    repeats = 3 if args.quick else args.repeats
    if args.scaling:
        print("W1 throughput against N:")
        scaling(args.arch, repeats, Path(args.out))
        return 0
    if args.worlds is not None:
        return worlds_bench(args, repeats)
    if args.serve is not None:
        from ..research.serve_bench import bench_serve, report

        if args.serve < 1:
            raise SandboxError(f"--serve: expected a number of sessions of at least 1, got {args.serve}")
        names = [path.stem for path in shipped_scenes()]
        if args.serve_scene not in names:
            raise SandboxError(
                f"--serve-scene: no shipped scene {args.serve_scene!r}; expected one of {', '.join(names)}"
            )
        worlds = not args.serve_sessions
        result = bench_serve(args.serve, args.serve_scene, draw=args.draw, hogs=args.contended or 0, worlds=worlds)
        print(report(result))
        write_json(args.json, result)
        return 0
    if args.three_d or args.contended:
        return peer_comparison(args, repeats)
    if args.cache is not None:
        from ..research import cache_bench

        result = cache_bench.run(args.cache, args.cache_frames, None)
        print(cache_bench.report(result))
        write_json(args.json, result)
        return 0
    if args.window:
        rates = window_rates(args.arch, frames=40 if args.quick else 120)
        print_window_rates(rates)
        write_json(args.json, rates)
        return 0
    results, rows = whole_set(args, repeats)
    print_whole_set(results, rows)
    if args.lammps and not any("lammps" in res for _, res in rows):
        print("LAMMPS not found: pip install 'lammps[mpi]' (or set LAMMPS_BIN) to compare")
    write_json(args.json, results)
    return 0


def worlds_bench(args, repeats: int) -> int:
    """`sandbox bench --worlds K SCENE` (research/worlds_bench.py), its arguments checked first."""
    from ..core.worlds import MAX_WORLDS
    from ..research.worlds_bench import bench_worlds, report

    count, scene = args.worlds
    if not count.isdigit() or not 1 <= int(count) <= MAX_WORLDS:
        raise SandboxError(f"--worlds: expected a number of worlds from 1 to {MAX_WORLDS}, got {count!r}")
    names = [path.stem for path in shipped_scenes()]
    if scene not in names:
        raise SandboxError(f"--worlds: no shipped scene {scene!r}; expected one of {', '.join(names)}")
    result = bench_worlds(int(count), scene, frames=10 if args.quick else 30, repeats=repeats)
    print(report(result))
    write_json(args.json, result)
    return 0


def write_json(path: str | None, result: dict) -> None:
    """With --json: the benchmark's result as JSON at `path`."""
    if path:
        Path(path).write_text(json.dumps(result, indent=2))
        print(f"wrote {path}")


def peer_rounds(args) -> int:
    """Alternating rounds against LAMMPS: --rounds where given, else 1 with --quick and PEER_ROUNDS otherwise."""
    if args.rounds is not None:
        return args.rounds
    return 1 if args.quick else PEER_ROUNDS


def whole_set(args, repeats: int) -> tuple[dict, list]:
    """Every workload (W1 2D and 3D against LAMMPS with --lammps, W2, W3), the ideal pair loop, integrators, kernel
    launches, memory, drawing, the window's frame and start-up: (results, the workloads' (name, result) rows)."""
    results: dict = {
        "machine": machine(),
        "workloads": {},
    }
    sizes = [100] if args.quick else [100, 317]
    rounds = peer_rounds(args)
    rows = []
    peers = [("W1 lj_box", lambda n=n_side: lj_box_sim(n, args.arch), n_side, 2) for n_side in sizes]
    if not args.quick:
        peers.append(("W1-3D LJ liquid", lambda: lj_box_3d_sim(32, args.arch), 32, 3))
    for label, factory, n_side, dim in peers:
        run_lammps, found = lammps_at_its_best(n_side, dim, 500) if args.lammps else (no_lammps, {})
        runtime.reset()  # independent workloads: a runtime holds at most ~512 field trees
        sim = factory()
        # fix nve is velocity Verlet: the same integrator on both sides; the scenes' default beside it
        both = against_lammps(sim, run_lammps, repeats, rounds if args.lammps else 0, (LIKE_LAMMPS, "symplectic_euler"))
        for integrator, res in both.items():
            res["arch"] = runtime.running_arch()
            res["pairs_per_second"] = pair_rate(sim, res["particle_steps_per_second"])
            res["dim"] = sim.model.dim
            if "lammps" in res:
                res["lammps"]["configs"] = found
            name = f"{label} N={res['particles']} {integrator}"
            results["workloads"][name] = res
            rows.append((name, res))
    runtime.reset()
    runtime.require(args.arch, "f32")
    results["ideal_pairs_per_second"] = {dim: ideal_pair_rate(dim) for dim in sorted({r["dim"] for _, r in rows})}
    runtime.reset()
    results["integrators_w1"] = integrator_rates(lj_box_sim(100, args.arch), repeats)
    for name, factory, timing in (
        ("W2 spring lattice + heat", spring_heat_lattice_sim, measure),
        ("W3 melting_block", melting_block_sim, measure_from_start),
    ):
        runtime.reset()
        res = timing(factory(args.arch), repeats)
        results["workloads"][name] = res
        rows.append((name, res))
    results["launches"] = {
        "W1 lj_box N=10000": launches_per_step(lambda arch: lj_box_sim(100, arch), args.arch),
        "W3 melting_block": launches_per_step(melting_block_sim, args.arch),
    }
    runtime.reset()
    sim = melting_block_sim(args.arch)
    memory = sim.memory_bytes()
    results["memory_melting_block"] = dict(memory, spring_slots=sim.state.springs.count, capacity=sim.capacity)
    results["render"] = render_cost(args.arch, repeats)
    runtime.reset()
    results["interactive"] = interactive_frame(args.arch, repeats)
    with tempfile.TemporaryDirectory() as cache:
        results["startup"] = {"cold_seconds": startup_seconds(cache), "warm_seconds": startup_seconds(cache)}
    return results, rows


def print_whole_set(results: dict, rows: list) -> None:
    """The whole set's table and lines, as `sandbox bench` prints them."""
    print(machine_line(results["machine"]))
    print(
        f"{'workload':42s} {'N':>8s} {'M particle-steps/s':>19s} {'ms/step':>8s} {'LAMMPS':>8s} {'ratio':>6s} "
        f"{'M pairs/s (of ideal)':>21s}"
    )
    ideal = results["ideal_pairs_per_second"]
    for name, res in rows:
        lmp = res.get("lammps", {})
        lrate = f"{lmp['particle_steps_per_second'] / 1e6:8.2f}" if "particle_steps_per_second" in lmp else "       -"
        ratio = f"{res['ratio_to_lammps']:6.2f}" if "ratio_to_lammps" in res else "     -"
        pairs = ""
        if "pairs_per_second" in res:
            share = res["pairs_per_second"] / ideal[res["dim"]]
            pairs = f"{res['pairs_per_second'] / 1e6:13.1f} ({100 * share:3.0f}%)"
        print(
            f"{name:42s} {res['particles']:8d} {res['particle_steps_per_second'] / 1e6:19.2f} "
            f"{res['seconds_per_step'] * 1e3:8.3f} {lrate} {ratio} {pairs}"
        )
    print(
        "ideal pair loop (pairs within the cutoff, each once, in cache; see docs/performance.md): "
        + ", ".join(f"{dim}D {rate / 1e6:.0f} M pairs/s" for dim, rate in ideal.items())
    )
    print(
        "W1 N=10000 by integrator (M particle-steps/s): "
        + ", ".join(f"{k} {v['particle_steps_per_second'] / 1e6:.2f}" for k, v in results["integrators_w1"].items())
    )
    for name, launch in results["launches"].items():
        print(
            f"kernel launches per step, {name}: {launch['launches_per_step']:.2f} "
            f"(the neighbour list rebuilt on {100 * launch['rebuild_fraction']:.0f}% of steps)"
        )
    memory = {k: v for k, v in results["memory_melting_block"].items() if k not in ("spring_slots", "capacity")}
    per_particle = {k: v for k, v in memory.items() if k != "springs"}
    cap = results["memory_melting_block"]["capacity"]
    print(
        f"memory, melting_block: {sum(per_particle.values()) / cap:.0f} B per particle slot ({cap} slots: "
        f"{', '.join(f'{k} {v / 1e3:.0f} kB' for k, v in per_particle.items())}); "
        f"{memory['springs'] / results['memory_melting_block']['spring_slots']:.0f} B per spring slot "
        f"(bond tables included)"
    )
    r = results["render"]
    print(
        f"render 1280x720 melting_block frame: {r['render_seconds'] * 1e3:.2f} ms; one simulation frame "
        f"({r['substeps']} steps): {r['sim_frame_seconds'] * 1e3:.2f} ms"
    )
    f = results["interactive"]
    print(
        f"window frame, melting_block at {f['particles']} particles, {f['substeps']} steps: "
        + ", ".join(f"{k} {v:.1f} ms" for k, v in f["ms"].items())
        + f" = {f['frame_ms']:.1f} ms ({f['fps']:.0f} fps; all but the simulation {100 * f['window_overhead']:.0f}%; "
        f"slowest frame {f['slowest_frame_ms']:.0f} ms; {f['window']})"
    )
    s = results["startup"]
    print(
        f"start-up to first step (lj_box): cold cache {s['cold_seconds']:.2f} s, warm cache {s['warm_seconds']:.2f} s"
    )


def machine() -> dict:
    """What the figures were measured on: platform, Python, CPU model, the machine's cores and those the bench may
    use (its affinity and cgroup quota: `taskset -c 0,1 sandbox bench ...` measures 2 cores of a larger machine),
    and the threads the sandbox and LAMMPS run (SANDBOX_CPU_THREADS, else the usable cores)."""
    return {
        "platform": platform.platform(),
        "python": platform.python_version(),
        "cpu": runtime.cpu_model(),
        "cpus": os.cpu_count(),
        "usable_cpus": usable_cores(),
        "threads": runtime.cpu_threads_wanted(),
        "autogroup": _autogroup(),
        **runtime.cpu_features(),
    }


def _autogroup(path: str = "/proc/sys/kernel/sched_autogroup_enabled") -> bool | None:
    """Whether Linux shares the cores between sessions before the tasks of each (None: not known here). Under load
    it decides what each side gets: mpirun starts LAMMPS in a session of its own, and the bench's hogs start theirs."""
    try:
        with open(path, encoding="ascii") as flag:
            return flag.read().strip() == "1"
    except OSError:
        return None


def machine_line(machine_: dict) -> str:
    """The machine a figure was measured on, in one line: CPU, cores (and the threads both sides ran, where
    SANDBOX_CPU_THREADS set another count), vector extensions, data caches."""
    vectors = ", ".join(machine_.get("vectors", [])) or "none known"
    caches = ", ".join(f"{k} {v}" for k, v in machine_.get("caches", {}).items()) or "unknown"
    usable = machine_.get("usable_cpus", machine_["cpus"])
    cores = f"{machine_['cpus']} cores" if usable == machine_["cpus"] else f"{usable} of its {machine_['cpus']} cores"
    threads = machine_.get("threads", usable)
    if threads != usable:  # SANDBOX_CPU_THREADS: the sandbox and LAMMPS both use this many
        cores += f", {threads} thread{'s' if threads > 1 else ''} (SANDBOX_CPU_THREADS)"
    line = f"on {machine_['cpu']}, {cores}; vector extensions {vectors}; data caches {caches}"
    autogroup = {True: "on", False: "off"}.get(machine_.get("autogroup"))
    if autogroup:
        line += f"; the scheduler's autogroup (cores shared between sessions first) {autogroup}"
    return line


def peer_comparison(args, repeats: int) -> int:
    """`sandbox bench --lammps --3d` / `--contended [N]`: W1 (2D, 100k) or W1-3D (32,768) against LAMMPS at its best
    on these cores (each of its configurations tried first under each condition's load, the fastest kept) in
    alternating rounds, quiet and (with --contended) beside N CPU hogs, the sandbox under load in batches of as many
    steps as quiet; each side's pair interactions per second as a fraction of the ideal in-cache pair loop on the
    same cores."""
    import contextlib

    from ..research.peer_bench import CpuHog, write_lammps_input

    dim = 3 if args.three_d else 2
    n_side = args.side or (32 if dim == 3 else (100 if args.quick else 317))
    lammps_steps = max(20, min(500, int(6e7 / n_side**dim)))  # 500 at the default sizes, 60 at a million
    folder = Path(args.out)
    script = write_lammps_input(dim, folder)
    rounds = peer_rounds(args)
    results: dict = {"dim": dim, "lammps_input": str(script), "machine": machine()}
    hogs = args.contended or 0
    conditions = [("quiet", contextlib.nullcontext)]
    if hogs:
        conditions.append((f"{hogs} hog{'s' if hogs > 1 else ''}", lambda: CpuHog(hogs)))
    batch = None  # steps a timed call: under load as many as quiet, so a call's fixed costs weigh the same
    for name, context in conditions:
        runtime.reset()
        sim = lj_box_3d_sim(n_side, args.arch) if dim == 3 else lj_box_sim(n_side, args.arch)
        with context():
            # LAMMPS's best under this condition's load: its OpenMP threads spin at barriers as a team does (beside
            # 3 hogs on 2 cores `omp 1x2`, fastest quiet in one run, kept under a tenth of its quiet rate, opt 2x1 30%)
            run_lammps, found = lammps_at_its_best(n_side, dim, lammps_steps) if args.lammps else (no_lammps, {})
            # LAMMPS both ways: with the strict list check (every step), and with in.lj's own policy (rebuilt every
            # 20 steps, unchecked), which is how its users run this benchmark
            res = against_lammps(
                sim, run_lammps, repeats, rounds if args.lammps else 0, steps=batch, policies=tuple(LAMMPS_POLICIES)
            )
            ideal = ideal_pair_rate(dim)  # under the same load
        res = res[LIKE_LAMMPS]
        batch = batch or res["steps_per_batch"]
        res["pairs_per_second"] = pair_rate(sim, res["particle_steps_per_second"])
        res["ideal_pairs_per_second"] = ideal
        res["lammps_configs"] = found
        results[name] = res
    print_peer_comparison(results, conditions, dim, script)
    if args.lammps and "ratio_to_lammps" not in results["quiet"]:
        print("LAMMPS not found: pip install 'lammps[mpi]' (or set LAMMPS_BIN) to compare")
    write_json(args.json, results)
    return 0


POLICY_WORDS = {"strict": "list checked every step", "in.lj": "in.lj's own list policy"}


def print_peer_comparison(results: dict, conditions: list, dim: int, script: Path) -> None:
    """The comparison's lines: the settings, the machine, LAMMPS's configurations, each condition's rates."""
    from ..research.peer_bench import describe

    quiet = results["quiet"]
    print(describe(dim, quiet["particles"], quiet["lammps_configs"].get("config")))
    print(machine_line(results["machine"]))
    print(f"LAMMPS input written to {script}")
    for name, _ in conditions:
        found = results[name]["lammps_configs"]  # {} without LAMMPS
        if found:
            tried = "; ".join(f"{config} {rate / 1e6:.2f}" for config, rate in found["rates"].items())
            print(
                f"LAMMPS at its best {'here' if name == 'quiet' else 'beside ' + name}: {found['config']} (suffix, "
                f"processes x threads; tried, M particle-steps/s: {tried})"
            )
    for name, _ in conditions:
        res = results[name]
        ideal = res["ideal_pairs_per_second"]
        line = (
            f"{name:9s} sandbox {res['particle_steps_per_second'] / 1e6:6.2f} M particle-steps/s, "
            f"{res['pairs_per_second'] / 1e6:7.1f} M pairs/s ({100 * res['pairs_per_second'] / ideal:.0f}% of the "
            f"ideal loop's {ideal / 1e6:.0f} M)"
        )
        for policy, peer in res.get("by_policy", {}).items():
            lmp = peer["lammps"]["particle_steps_per_second"]
            line += f"; LAMMPS ({POLICY_WORDS[policy]}) {lmp / 1e6:6.2f} M, ratio {peer['ratio']:.2f}"
        print(line)
        spread = {"sandbox": res["rounds"]}
        spread.update({f"LAMMPS {p}": peer["lammps"]["rounds"] for p, peer in res.get("by_policy", {}).items()})
        crowded = res.get("crowded_rounds", 0)
        said = f"; {crowded} of the sandbox's {len(res['rounds'])} rounds stepped crowded (other work)"
        print(
            "          rounds, max/min: "
            + ", ".join(f"{who} {max(r) / min(r):.2f}" for who, r in spread.items() if r and min(r) > 0)
            + (said if crowded else "")
        )
    loaded = [name for name, _ in conditions[1:]]
    for name in loaded:
        if "ratio_to_lammps" in results["quiet"] and "ratio_to_lammps" in results[name]:
            kept = results[name]["ratio_to_lammps"] / results["quiet"]["ratio_to_lammps"]
            results[f"ratio_kept_{name.replace(' ', '_')}"] = kept
            print(f"beside {name} the sandbox keeps {100 * kept:.0f}% of its quiet ratio to LAMMPS")
