"""The cores the sandbox sizes Taichi's worker pool to: the process's affinity, capped by its cgroup's CPU quota."""

import os
import subprocess
import sys

import pytest

from sandbox.core.cores import cgroup_cpu_quota, usable_cores


def _cgroups(tmp_path, path: str, limits: dict[str, str]):
    """A fake cgroup v2 tree: /proc/self/cgroup naming `path`, and cpu.max files at the given folders."""
    root = tmp_path / "cgroup"
    (root / path.strip("/")).mkdir(parents=True)
    for folder, text in limits.items():
        (root / folder.strip("/")).mkdir(parents=True, exist_ok=True)
        (root / folder.strip("/") / "cpu.max").write_text(text)
    self_cgroup = tmp_path / "self_cgroup"
    self_cgroup.write_text(f"0::{path}\n")
    return root, self_cgroup


def test_the_least_cgroup_v2_quota_along_the_path_counts(tmp_path):
    """A container started with --cpus=2.5 under a slice that allows 4: 2.5 cores, rounded up to 3 usable."""
    root, me = _cgroups(
        tmp_path,
        "/system.slice/box.scope",
        {"/": "max 100000", "/system.slice": "400000 100000", "/system.slice/box.scope": "250000 100000"},
    )
    assert cgroup_cpu_quota(root, me) == 2.5
    affinity = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    assert usable_cores(root, me) == min(affinity, 3)


def test_no_quota_leaves_the_affinity(tmp_path):
    """Unlimited (max), unreadable or malformed quotas and a missing /proc/self/cgroup mean no cap."""
    root, me = _cgroups(tmp_path, "/user.slice", {"/": "max 100000", "/user.slice": "garbage"})
    assert cgroup_cpu_quota(root, me) is None
    assert cgroup_cpu_quota(root, tmp_path / "absent") is None
    affinity = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    assert usable_cores(root, me) == affinity


def test_a_cgroup_v1_quota_counts(tmp_path):
    cpu = tmp_path / "cgroup" / "cpu"
    cpu.mkdir(parents=True)
    (cpu / "cpu.cfs_quota_us").write_text("50000\n")
    (cpu / "cpu.cfs_period_us").write_text("100000\n")
    assert cgroup_cpu_quota(tmp_path / "cgroup", tmp_path / "absent") == 0.5
    assert usable_cores(tmp_path / "cgroup", tmp_path / "absent") == 1
    (cpu / "cpu.cfs_quota_us").write_text("-1\n")
    assert cgroup_cpu_quota(tmp_path / "cgroup", tmp_path / "absent") is None


@pytest.mark.skipif(
    not hasattr(os, "sched_setaffinity") or len(os.sched_getaffinity(0)) < 2, reason="needs 2 cores to leave one out"
)
def test_taichis_pool_has_a_worker_per_core_the_process_may_use():
    """Pinned to one core (taskset, a container's cpuset), the sandbox starts Taichi with one worker, not one per
    core of the machine: a team of spinning workers several to a core ran at a quarter of its speed."""
    code = (
        "import os; os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})\n"
        "from sandbox.core import runtime, taichi_compat\n"
        "runtime.own_process(); runtime.init('cpu', 'f32')\n"
        "print('threads', taichi_compat.cpu_threads())\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "SANDBOX_CPU_THREADS"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split()[-2:] == ["threads", "1"], out.stdout


def test_a_local_sweep_shares_out_the_cores_the_process_may_use(monkeypatch):
    """`sandbox sweep`'s local pool on a machine of 16 cores of which the process may use 4 (a container's quota):
    workers x threads stays within the 4."""
    from sandbox.research import dask_pool

    monkeypatch.setattr(dask_pool, "usable_cores", lambda: 4)
    monkeypatch.setattr(os, "cpu_count", lambda: 16)
    assert dask_pool.local_shape(jobs=10, workers=None, threads=None) == (4, 1)
    assert dask_pool.local_shape(jobs=2, workers=None, threads=None) == (2, 2)
