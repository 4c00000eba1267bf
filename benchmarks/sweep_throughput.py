"""Sweep throughput: the same sweep one run at a time in one process (all cores to each run), on a local Dask
cluster (one worker process per core, one Taichi thread each) and as worlds (the runs of each material as the worlds
of one simulation, sandbox/app/sweep_batch.py); runs per hour and memory per worker.

    python benchmarks/sweep_throughput.py [--frames 60] [--plates 4] [--out /tmp/sweep-bench]

The sweep: the melting block at `--plates` plate temperatures x 2 materials (runs of `--frames` frames). Every way
starts with the kernel cache as the first run left it, so the later ways' first runs compile as the first's do.
"""

import argparse
import os
import shutil
import tempfile
import time
from pathlib import Path

import this_tree  # noqa: F401  (this checkout's sandbox, not the installed one)

from sandbox.app.sweep import parse_vary, plan_runs, run_sweep
from sandbox.config.resources import shipped_scene


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--plates", type=int, default=4)
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    out = Path(args.out or tempfile.mkdtemp(prefix="sweep-bench-"))
    runs = plan_runs(
        [
            parse_vary(f"heat.sources.0.temperature=120:240:{args.plates}"),
            parse_vary("bodies.0.material=wax,chocolate"),
        ]
    )
    scene = shipped_scene("melting_block")
    cores = os.cpu_count() or 1
    results = {}
    for name, kwargs in (
        ("one by one", dict(scheduler="serial", threads=cores, batch=False)),
        ("local cluster", dict(scheduler="local", workers=cores, threads=1, batch=False)),
        ("as worlds", dict(scheduler="serial", threads=1)),
    ):
        folder = out / name.replace(" ", "-")
        shutil.rmtree(folder, ignore_errors=True)
        start = time.perf_counter()
        records = run_sweep(scene, runs, folder, frames=args.frames, log=lambda s: None, **kwargs)
        wall = time.perf_counter() - start
        assert all(r["outcome"] == "done" for r in records), records
        results[name] = wall
        print(
            f"{name:14s}: {len(runs)} runs of {args.frames} frames in {wall:6.1f} s = {3600 * len(runs) / wall:6.0f} "
            "runs/hour"
        )
    print(f"speed-up of the local cluster ({cores} workers): {results['one by one'] / results['local cluster']:.2f}")
    print(f"speed-up as worlds: {results['one by one'] / results['as worlds']:.2f}")
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=cores, threads_per_worker=1, dashboard_address=None, silence_logs=40) as cluster:
        with Client(cluster) as client:
            from sandbox.app.sweep_run import execute_run

            futures = [
                client.submit(
                    execute_run, str(scene), o, str(out / f"mem{k}"), args.frames, False, None, None, 1, pure=False
                )
                for k, o in enumerate(runs[:cores])
            ]
            client.gather(futures)
            rss = client.run(lambda: __import__("psutil").Process().memory_info().rss)
    print("memory per worker after a run (RSS):", ", ".join(f"{v / 2**20:.0f} MiB" for v in rss.values()))


if __name__ == "__main__":
    main()
