"""The CPU cores this process may use: its affinity, capped by its cgroup's CPU quota.

Taichi sizes its CPU worker pool from the machine's core count (C++'s hardware_concurrency), not from the cores the
process may run on. Under `taskset`, a container's `--cpuset-cpus` or `--cpus`, or a batch job's allocation, that
gives the pool more workers than cores, and a team of spinning workers (step/team.py) several to a core: W1 2D
(100,489) pinned to 2 of a 16-core Xeon's cores ran at 11.3 M particle-steps/s with 16 workers and 27.6 M with 2.
`runtime.init` sizes the pool with `usable_cores()`.
"""

import math
import os
from pathlib import Path


def pinnable_cores() -> list[int]:
    """The cores this process may pin its busy threads to, sorted: its CPU affinity where it has two or more cores
    and pinning is allowed (Linux; not with SANDBOX_PIN_THREADS=0); else none. Taichi's workers (threads.pin_workers)
    and the classroom's hosts (app/serve_slots.py) are pinned to these."""
    if os.environ.get("SANDBOX_PIN_THREADS", "1") == "0" or not hasattr(os, "sched_setaffinity"):
        return []
    cores = sorted(os.sched_getaffinity(0))
    return cores if len(cores) >= 2 else []


def usable_cores(cgroup_root: str | Path = "/sys/fs/cgroup", self_cgroup: str | Path = "/proc/self/cgroup") -> int:
    """Cores this process may run on at once: its CPU affinity, capped by its cgroup's CPU quota rounded up (at
    least 1). The paths are parameters for tests."""
    if hasattr(os, "sched_getaffinity"):
        cores = len(os.sched_getaffinity(0))
    else:
        cores = os.cpu_count() or 1
    quota = cgroup_cpu_quota(cgroup_root, self_cgroup)
    if quota is not None:
        cores = min(cores, math.ceil(quota - 1e-9))
    return max(cores, 1)


def cgroup_cpu_quota(
    cgroup_root: str | Path = "/sys/fs/cgroup", self_cgroup: str | Path = "/proc/self/cgroup"
) -> float | None:
    """The CPU time this process's cgroups allow, in cores (quota / period; the least along its cgroup's path, as
    the kernel enforces every level), or None when unlimited or unreadable. cgroup v2 (`cpu.max`) and v1
    (`cpu.cfs_quota_us` / `cpu.cfs_period_us` of the cpu controller's root)."""
    root = Path(cgroup_root)
    limits = [_v2_limit(folder / "cpu.max") for folder in _v2_folders(root, Path(self_cgroup))]
    limits.append(_v1_limit(root / "cpu"))
    known = [limit for limit in limits if limit is not None]
    return min(known) if known else None


def _v2_folders(root: Path, self_cgroup: Path) -> list[Path]:
    """This process's cgroup v2 folder and each above it, up to the root."""
    try:
        lines = self_cgroup.read_text(encoding="utf-8").splitlines()
    except OSError:
        return []
    paths = [line[3:] for line in lines if line.startswith("0::")]
    if not paths:
        return []
    parts = [part for part in paths[0].strip().split("/") if part and part not in (".", "..")]
    return [root.joinpath(*parts[:depth]) for depth in range(len(parts), -1, -1)]


def _v2_limit(cpu_max: Path) -> float | None:
    """cgroup v2's `cpu.max` ("QUOTA PERIOD" in microseconds, or "max PERIOD") in cores; None when unlimited."""
    try:
        quota, period = cpu_max.read_text(encoding="ascii").split()[:2]
        return None if quota == "max" else _cores(int(quota), int(period))
    except (OSError, ValueError):
        return None


def _v1_limit(folder: Path) -> float | None:
    """cgroup v1's CFS quota in cores; None when unlimited (-1) or absent."""
    try:
        quota = int((folder / "cpu.cfs_quota_us").read_text(encoding="ascii"))
        period = int((folder / "cpu.cfs_period_us").read_text(encoding="ascii"))
    except (OSError, ValueError):
        return None
    return _cores(quota, period)


def _cores(quota: int, period: int) -> float | None:
    return quota / period if quota > 0 and period > 0 else None
