"""`sandbox bench --cache N`: how fast each particle cache streams N particles a frame to disk, against the disk.

Each format writes the same frames (N particles of a 3D liquid's point data: positions, velocities, temperature, melt
fraction, phase, material, body, id) through the cache writer a run uses (files/cache_sequence.py) into a folder
beside the output; the raw disk rate is the same number of bytes written in 1 MiB blocks to one file (no fsync in
either, so both measure what the page cache and the disk take together). The resident memory's growth over the run
shows whether frames are held: a cache that streams grows by about one frame, not by all of them. Each format runs in
a process of its own, so one format's memory and imports (usd-core's) never count against another's.
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ..files.cache_formats import CacheFrame
from ..files.cache_sequence import CacheSequence
from ..files.claim import Claim


def synthetic_frame(n: int, index: int, rng: np.random.Generator) -> CacheFrame:
    """A frame of `n` particles with every attribute a real cache carries (values random, sizes exact)."""
    data = {
        "velocity": rng.standard_normal((n, 3)).astype(np.float32),
        "temperature": rng.uniform(20, 200, n).astype(np.float32),
        "melt_fraction": rng.uniform(0, 1, n).astype(np.float32),
        "phase": rng.integers(0, 3, n).astype(np.int32),
        "material": rng.integers(0, 4, n).astype(np.int32),
        "body": rng.integers(0, 4, n).astype(np.int32),
        "id": np.arange(n, dtype=np.int64),
    }
    points = rng.uniform(0, 100, (n, 3)).astype(np.float32)
    return CacheFrame(index, index * 0.02, points, data, np.ones(n, np.float32))


def _rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def bench_format(kind: str, n: int, frames: int, folder: Path) -> dict:
    """Write `frames` frames of `n` particles as a `kind` cache (ply, vtp, usd) under `folder`: seconds, bytes a
    frame, MB/s, frames/s and the peak resident memory's growth (MB) while writing, in this process."""
    if kind == "usd":
        try:
            import pxr  # noqa: F401
        except ImportError:
            return {"skipped": "usd-core is not installed"}
    rng = np.random.default_rng(1)
    frame_list = [synthetic_frame(n, k, rng) for k in range(2)]  # two frames, alternated: no allocation in the loop
    target = folder / kind
    target.mkdir(parents=True, exist_ok=True)
    claim = Claim("--cache", target / f"bench.{'pvd' if kind == 'vtp' else kind}")
    claim.acquire()
    sequence = CacheSequence(claim, target / f"bench.{kind}")
    sequence.start()
    before = _rss_mb()
    start = time.perf_counter()
    for k in range(frames):
        frame = frame_list[k % 2]
        frame.frame = k
        sequence.write(frame)
    sequence.publish()
    seconds = time.perf_counter() - start
    claim.release()
    size = sum(p.stat().st_size for p in target.iterdir())
    shutil.rmtree(target)
    return {
        "seconds": seconds,
        "bytes_per_frame": size / frames,
        "mb_per_second": size / seconds / 1e6,
        "frames_per_second": frames / seconds,
        "memory_growth_mb": _rss_mb() - before,
        "process": os.getpid(),
    }


def bench_caches(n: int, frames: int, folder: Path, formats=("ply", "vtp", "usd")) -> dict:
    """Each format's bench_format in a process of its own (so no format's memory or imports count against
    another's), then the raw disk rate for as many bytes as the largest wrote."""
    results: dict = {"particles": n, "frames": frames, "formats": {}}
    for kind in formats:
        command = [sys.executable, "-m", __name__, kind, str(n), str(frames), str(folder)]
        done = subprocess.run(command, capture_output=True, text=True)
        if done.returncode != 0:
            lines = done.stderr.strip().splitlines() or ["it exited with no message"]
            raise OSError(f"the {kind} cache bench failed: {lines[-1]}")
        results["formats"][kind] = json.loads(done.stdout)
    largest = max(r.get("bytes_per_frame", 0) for r in results["formats"].values())
    results["raw_mb_per_second"] = _raw_rate(folder, int(largest * frames))
    return results


def _raw_rate(folder: Path, total: int) -> float:
    """MB/s writing `total` bytes in 1 MiB blocks to one file in `folder`."""
    block = np.random.default_rng(2).bytes(1 << 20)
    path = folder / "raw.bin"
    start = time.perf_counter()
    with open(path, "wb") as out:
        for _ in range(max(1, total >> 20)):
            out.write(block)
    seconds = time.perf_counter() - start
    written = path.stat().st_size
    path.unlink()
    return written / seconds / 1e6


def report(results: dict) -> str:
    lines = [
        f"particle caches, {results['particles']:,} particles x {results['frames']} frames "
        f"(the disk takes {results['raw_mb_per_second']:.0f} MB/s in 1 MiB blocks):"
    ]
    for kind, r in results["formats"].items():
        if "skipped" in r:
            lines.append(f"  {kind:4s} skipped: {r['skipped']}")
            continue
        lines.append(
            f"  {kind:4s} {r['frames_per_second']:6.2f} frames/s, {r['mb_per_second']:6.0f} MB/s "
            f"({r['mb_per_second'] / results['raw_mb_per_second']:.0%} of the disk's rate), "
            f"{r['bytes_per_frame'] / 1e6:.1f} MB a frame, memory grew {r['memory_growth_mb']:.0f} MB"
        )
    return "\n".join(lines)


def run(n: int, frames: int, out: str | None) -> dict:
    folder = Path(tempfile.mkdtemp(prefix="sandbox-cache-bench-", dir=out or None))
    try:
        return bench_caches(n, frames, folder)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


# one format's bench, for bench_caches: python -m sandbox.research.cache_bench KIND N FRAMES DIR
if __name__ == "__main__":
    print(json.dumps(bench_format(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), Path(sys.argv[4]))))
