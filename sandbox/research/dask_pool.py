"""Where sweeps and studies run their independent jobs: a Dask cluster (local worker processes or an existing
scheduler's address) when the `sweep` extra is installed, else one job after another in this process.

Taichi's CPU threads for each job come from SANDBOX_CPU_THREADS, set around the job (`cpu_threads`), so a worker
process runs each job with the threads its share of the cores allows; each job starts from a fresh Taichi runtime
(runtime.reset), so its results do not depend on which worker ran it or what ran there before.
"""

from __future__ import annotations

import contextlib
import logging
import os
from collections.abc import Callable, Iterator

from ..core.cores import usable_cores
from ..errors import SandboxError

THREADS_VARIABLE = "SANDBOX_CPU_THREADS"


def have_dask() -> bool:
    """Whether dask.distributed can be imported (the `sweep` extra)."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


def choose_scheduler(scheduler: str, jobs: int, log, what: str) -> str:
    """Resolve "auto" to "local" (with dask) or "serial"; say how to get parallelism when it has to be serial."""
    if scheduler != "auto":
        return scheduler
    if have_dask():
        return "local"
    if jobs > 1:
        log(f"running the {what} one job at a time: pip install -e '.[sweep]' (dask) to run it in parallel")
    return "serial"


def local_shape(jobs: int, workers: int | None, threads: int | None) -> tuple[int, int]:
    """Local worker processes and Taichi threads per job: by default one worker per core (no more than the jobs)
    and the cores shared among them, so workers x threads never exceeds the cores this process may use."""
    cores = usable_cores()
    workers = workers or max(1, min(cores, jobs))
    threads = threads or max(1, cores // workers)
    return workers, threads


@contextlib.contextmanager
def cpu_threads(threads: int) -> Iterator[None]:
    """Run the body with SANDBOX_CPU_THREADS = `threads` (read by runtime.init), restoring it afterwards."""
    before = os.environ.get(THREADS_VARIABLE)
    os.environ[THREADS_VARIABLE] = str(threads)
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(THREADS_VARIABLE, None)
        else:
            os.environ[THREADS_VARIABLE] = before


@contextlib.contextmanager
def dask_client(scheduler: str, workers: int, option: str = "--scheduler"):
    """A distributed.Client on a new local cluster of `workers` single-threaded worker processes ("local") or on
    the scheduler at address `scheduler`; both are closed on leaving. `option` names the setting in errors."""
    if not have_dask():
        raise SandboxError(f"{option} {scheduler}: needs dask; pip install -e '.[sweep]'")
    from distributed import Client, LocalCluster

    cluster = None
    if scheduler == "local":
        # the workers log only what is critical: a task's error comes back to the client as its exception, and
        # on Ctrl-C or SIGTERM to the process group a worker losing its scheduler logs a traceback that is noise
        cluster = LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=50
        )
        client = Client(cluster)
    else:
        try:
            client = Client(scheduler, timeout=30)
        except (OSError, TimeoutError, ValueError) as exc:
            raise SandboxError(f"{option} {scheduler}: no Dask scheduler answered ({exc})") from exc
    try:
        yield client
    except BaseException:
        # Stopping on Ctrl-C, a signal or an error: the workers exit with the process group, and closing the cluster
        # then cancels the nannies' own close, which Dask logs as an ERROR with a traceback. That is shutdown noise,
        # not the user's news (the caller says in one line what stopped and what was kept).
        quiet_dask_logs()
        raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def quiet_dask_logs() -> None:
    """Only Dask's critical log lines from now on (every logger under "distributed")."""
    for name in [n for n in logging.root.manager.loggerDict if n.startswith("distributed")] + ["distributed"]:
        logging.getLogger(name).setLevel(logging.CRITICAL)


def run_jobs(
    fn: Callable, jobs: list[tuple], scheduler: str = "auto", workers: int | None = None, threads: int | None = None,
    log=print, what: str = "study",
) -> list:  # fmt: skip
    """fn(*job) for each of `jobs` (independent: a study's temperatures or pressures), each in a fresh Taichi runtime
    with its share of the cores: on a Dask cluster ("local", or a scheduler's address; "auto": local where dask is
    installed), else one after another ("serial"). The results come back in the jobs' order."""
    scheduler = choose_scheduler(scheduler, len(jobs), log, what)
    workers, threads = local_shape(len(jobs), workers if scheduler != "serial" else 1, threads)
    if scheduler == "serial":
        return [fresh_job(fn, threads, job) for job in jobs]
    with dask_client(scheduler, workers) as client:
        futures = [client.submit(fresh_job, fn, threads, job, pure=False) for job in jobs]
        return client.gather(futures)


def fresh_job(fn: Callable, threads: int, job: tuple):
    """fn(*job) with `threads` CPU threads in a fresh Taichi runtime (what a job sees wherever it runs)."""
    from ..core import runtime

    with cpu_threads(threads):
        runtime.reset()
        try:
            return fn(*job)
        finally:
            runtime.reset()
