"""Pin Taichi's CPU worker threads to distinct cores.

Taichi's CPU backend runs each parallel loop on a pool of worker threads that sleep between loops, and Linux may
wake two of them on one core, so a parallel loop runs at a serial loop's speed (OpenMP runtimes offer the same choice
as OMP_PROC_BIND). After Taichi starts on the CPU, `pin_workers` finds the pool's threads (those that run a small
parallel kernel: the calling thread only waits) and gives each a core of its own, round robin over the cores this
process may use. Linux only; SANDBOX_PIN_THREADS=0 leaves the threads alone.

While other programs share the cores (step/plan.py's crowded stepping, one worker at a time), `free_workers(True)`
lets the pinned workers run on any usable core, so the scheduler can move the one that works to the core less
crowded now; `free_workers(False)` pins them again for the team. Pinning changes where threads run, never what they
compute. What each choice was measured to gain (`python benchmarks/thread_pinning.py`) is in docs/performance.md.
"""

import os
import time

import taichi as ti

from .cores import pinnable_cores, usable_cores

_probe_field = None
PROBE_ATTEMPTS = 10  # rounds of probe launches to find the pool's threads (see pin_workers)
PROBE_ROUNDS = 300  # steps of the probe's busy chain per item: a launch keeps each worker busy ~0.1 ms
IDLE_SECONDS = 0.003  # the pause in which threads other than the pool show themselves
pinned: list[tuple[int, int]] = []  # (thread id, core) of the workers pinned by the last pin_workers()
_freed = False  # whether free_workers(True) has let the pinned workers run on every usable core


@ti.kernel
def _probe(x: ti.template(), rounds: ti.i32):
    for i in range(x.shape[0]):  # every worker of the pool runs its share of each parallel loop
        v = x[i]
        for _ in range(rounds):  # a dependent chain the compiler cannot drop: keeps each worker busy a while
            v = (v * 1103515245 + 12345) & 0x7FFFFFFF
        x[i] = v


def _cpu_ns_by_thread() -> dict[int, int]:
    """Nanoseconds of CPU time each thread of this process has run (/proc/self/task/*/schedstat)."""
    out = {}
    for tid in os.listdir("/proc/self/task"):
        try:
            with open(f"/proc/self/task/{tid}/schedstat") as f:
                out[int(tid)] = int(f.read().split()[0])
        except (OSError, ValueError, IndexError):
            continue
    return out


def _ran_between(earlier: dict[int, int], later: dict[int, int]) -> set[int]:
    """The threads whose CPU time grew from `earlier` to `later` (two _cpu_ns_by_thread() readings)."""
    return {tid for tid, ns in later.items() if ns > earlier.get(tid, ns)}


def pin_workers(threads: int) -> list[tuple[int, int]]:
    """Give each of Taichi's `threads` CPU worker threads a core of its own; returns (thread id, core) pairs, empty
    when nothing was pinned (not Linux, one core, one thread, fewer threads than the cores this process may run on,
    disabled by SANDBOX_PIN_THREADS=0, or the workers not found)."""
    global _probe_field, _freed
    pinned.clear()
    _freed = False
    cores = pinnable_cores()
    if threads < 2 or not os.path.isdir("/proc/self/task"):
        return []
    if not cores or threads < len(cores):
        # With cores to spare the scheduler places the workers where the machine is idle; pinned, every such process
        # (sweeps' workers, renders started side by side with SANDBOX_CPU_THREADS) would crowd the first cores.
        return []
    _probe_field = ti.field(ti.i32, shape=threads * 1024)  # enough items that the pool shares them out evenly
    _probe(_probe_field, 1)  # compiles
    main = os.getpid()
    # Another of Taichi's threads can stay busy for a while after a compile (on the 2-core machine, in some runs, for
    # a tenth of a second, writing more CPU time than the workers): it runs while the pool sleeps, so the threads
    # that ran during a short pause are left out. Look again if that does not leave the pool alone; never guess.
    for _attempt in range(PROBE_ATTEMPTS):
        start = _cpu_ns_by_thread()
        time.sleep(IDLE_SECONDS)
        before = _cpu_ns_by_thread()
        for _ in range(4):
            _probe(_probe_field, PROBE_ROUNDS)
        after = _cpu_ns_by_thread()
        ran = _ran_between(before, after) - _ran_between(start, before) - {main}
        if len(ran) == threads:
            break
    else:
        return []
    for k, tid in enumerate(sorted(ran)):
        core = cores[k % len(cores)]
        try:
            os.sched_setaffinity(tid, {core})
        except OSError:
            break
        pinned.append((tid, core))
    return list(pinned)


def free_workers(free: bool) -> None:
    """Let the workers pin_workers() pinned run on every core this process may use (`free`), or pin each to its own
    core again; does nothing when it is already so or nothing is pinned."""
    global _freed
    if free == _freed or not pinned:
        return
    _freed = free
    everywhere = os.sched_getaffinity(0)
    for tid, core in pinned:
        try:
            os.sched_setaffinity(tid, everywhere if free else {core})
        except OSError:  # the thread is gone (Taichi restarted): the next start pins its own
            continue


class LoadWatch:
    """Whether other runnable work shares this process's cores now. A team of spinning workers (step/team.py) needs
    every one of its threads on a core of its own: when another task wants one of those cores, a worker is
    descheduled while the rest spin at a barrier, and the team runs at a fraction of one thread's speed (W1 beside one
    other CPU-bound program on 2 cores: 10 M particle-steps/s against 25 on one thread). Reads the machine's runnable
    count (/proc/loadavg) at most every PERIOD seconds, less this process's own running threads, smoothed over a few
    reads; `busy()` is True once the others would leave fewer free cores than the team has threads. Where the process
    may use only some of the machine's cores (an affinity, a container's quota), others are taken to fill the cores
    it may not use first, as Linux's load balancing places them."""

    PERIOD = 0.05  # seconds between reads of /proc/loadavg
    SMOOTHING = 0.3  # each read's share of the running estimate: a lasting other task shows after 2-3 reads

    def __init__(
        self, threads: int, path: str = "/proc/loadavg", cores: int | None = None, own=None, machine: int | None = None
    ) -> None:
        """`threads`: the team's; `path`: the load file; `cores`: those this process may use (default:
        cores.usable_cores()); `own`: counts this process's running threads (default: /proc/self/task); `machine`:
        the machine's cores (default: os.cpu_count())."""
        self.threads, self.path = threads, path
        self.own_running = own or _own_running
        self.cores = cores if cores is not None else usable_cores()
        self.elsewhere = max((machine or os.cpu_count() or 1) - self.cores, 0)  # cores others may use, not this
        self.others = 0.0  # runnable tasks of other processes, smoothed
        self.last = -1.0
        self.readable = True  # until a read fails (no /proc: never crowded)

    def busy(self, now: float | None = None) -> bool:
        """True while other runnable tasks would leave fewer free cores than the team has threads."""
        if not self.readable or self.threads < 2:
            return False
        now = time.monotonic() if now is None else now
        if now - self.last >= self.PERIOD:
            self.last = now
            mine = max(self.runnable_others() - self.elsewhere, 0)  # the others that land on this process's cores
            self.others += self.SMOOTHING * (mine - self.others)
        return self.cores - self.others < self.threads - 0.5

    def runnable_others(self) -> int:
        """Runnable tasks on the machine now, less this process's threads that are running (the reader, and pool
        workers that have not yet gone back to sleep)."""
        try:
            with open(self.path, encoding="ascii") as load:
                running = int(load.read().split()[3].split("/")[0])
        except (OSError, ValueError, IndexError):
            self.readable = False
            return 0
        return max(running - max(self.own_running(), 1), 0)


def _own_running() -> int:
    """This process's threads in the running state now (/proc/self/task/*/stat; 0 where unreadable)."""
    count = 0
    try:
        tasks = os.listdir("/proc/self/task")
    except OSError:
        return 0
    for tid in tasks:
        try:
            with open(f"/proc/self/task/{tid}/stat", encoding="ascii", errors="replace") as stat:
                count += stat.read().rsplit(")", 1)[1].split()[0] == "R"
        except (OSError, IndexError):
            continue
    return count
