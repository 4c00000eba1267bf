"""`sandbox study`: error against run time, convergence orders and stability limits of the integrators.

`sandbox study --out DIR [--quick] [--scheduler auto|serial|local|ADDRESS]` writes runs.csv (every run),
stability.csv, stiff.csv, report.md and, with matplotlib, PNG plots. The problems are in study_problems.py; here
they are cut into tasks (a problem for some integrators, plus each problem's shared reference) that run one after
another in this process or spread over Dask workers (dask_pool.py). Every task starts from a fresh Taichi runtime
and builds its own simulations, so its results do not depend on where it ran: with the same Taichi threads per task,
the CSVs from a cluster equal the serial run's apart from the wall-time columns.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from ..config.scene_tables import INTEGRATORS as ALL_INTEGRATORS
from ..errors import SandboxError
from . import study_problems as problems
from . import study_stability
from .dask_pool import choose_scheduler, dask_client, fresh_job, local_shape
from .heat_study import heat_runs
from .study_report import write_outputs
from .study_runs import StudyResult

# the study's reading order (by order of accuracy); an integrator added later is studied after these
_READING_ORDER = ("forward_euler", "symplectic_euler", "midpoint", "verlet", "velocity_verlet", "rk4", "implicit_euler")
INTEGRATORS = tuple(n for n in _READING_ORDER if n in ALL_INTEGRATORS) + tuple(
    n for n in ALL_INTEGRATORS if n not in _READING_ORDER
)
PROBLEMS = ("oscillator", "lattice", "lj_cluster", "melting", "heat_pulse", "stability", "stiff")
QUICK_SKIPS = ("melting",)  # --quick leaves these out
WALL_TIME_COLUMNS = ("wall_seconds", "particle_steps_per_second")  # the only columns that differ between machines


@dataclass(frozen=True)
class StudyTask:
    """One job of the study: `problem` for some integrators (sharing its simulations), or with no integrators the
    problem's shared reference (lattice, melting) or the whole problem (heat_pulse, which compares heat steppers)."""

    problem: str
    integrators: tuple[str, ...]
    quick: bool

    @property
    def key(self) -> str:
        return f"study-{self.problem}-{'-'.join(self.integrators) or 'reference'}"

    @property
    def name(self) -> str:
        if self.integrators:
            return f"{self.problem} {', '.join(self.integrators)}"
        return f"{self.problem} reference" if self.problem in REFERENCED else self.problem


def ladders(quick: bool) -> dict:
    """The steps (or h*w, stiffnesses, substeps) each problem runs at."""
    return {
        "oscillator_h_omegas": [0.08, 0.04, 0.02, 0.01] if quick else [0.16, 0.08, 0.04, 0.02, 0.01, 0.005],
        "lattice_dts": [0.008, 0.004, 0.002] if quick else [0.008, 0.004, 0.002, 0.001, 0.0005],
        "lattice_end": 0.256 if quick else 1.024,
        "lj_dts": [0.005] if quick else [0.005, 0.0025],
        "lj_end": 5.0 if quick else 50.0,
        "melting_dts": [0.0025, 0.00125],
        "melting_end": 1.0,
        "stiffnesses": [1e2, 1e4, 1e6, 1e8] if quick else [1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8],
        "substeps": [1, 4, 16, 64, 256] if quick else [1, 2, 4, 8, 16, 32, 64, 128, 256, 512, 1024, 2048],
        "stiff_frames": 5 if quick else 20,
    }


REFERENCED = ("lattice", "melting")  # problems whose integrator tasks need their reference task's result


def plan_tasks(quick: bool, integrators=INTEGRATORS, problems_to_run=PROBLEMS, split: int = 1) -> list[StudyTask]:
    """The study's tasks in report order: each problem's reference first, then its integrators cut into `split`
    tasks (one task per problem when 1: the integrators share the problem's simulations and compiled kernels)."""
    unknown = [p for p in problems_to_run if p not in PROBLEMS]
    if unknown:
        raise SandboxError(f"study: unknown problem {unknown[0]!r}; expected one of {', '.join(PROBLEMS)}")
    bad = [name for name in integrators if name not in INTEGRATORS]
    if bad:
        raise SandboxError(f"study: unknown integrator {bad[0]!r}; expected one of {', '.join(INTEGRATORS)}")
    split = max(1, min(split, len(integrators)))
    cuts = [round(k * len(integrators) / split) for k in range(split + 1)]  # contiguous: the report's order
    groups = [tuple(integrators[a:b]) for a, b in zip(cuts, cuts[1:])]
    tasks = []
    for problem in PROBLEMS:
        if problem not in problems_to_run or (quick and problem in QUICK_SKIPS):
            continue
        if problem in REFERENCED or problem == "heat_pulse":
            tasks.append(StudyTask(problem, (), quick))
        if problem != "heat_pulse":
            tasks += [StudyTask(problem, group, quick) for group in groups]
    return tasks


def run_task(task: StudyTask, threads: int, reference=None) -> dict:
    """Run one task in a fresh Taichi runtime with `threads` CPU threads; `reference`: the result of the problem's
    reference task (for lattice and melting). Returns {"runs": [...], "stability": [...], "stiff": [...],
    "notes": {...}, "reference": ...}, each part present where the task makes it."""
    return fresh_job(_run_task, threads, (task, reference))  # shared kernels come back from the offline cache


def _run_task(task: StudyTask, reference) -> dict:
    lad = ladders(task.quick)
    names = list(task.integrators)
    if task.problem == "oscillator":
        return {"runs": problems.oscillator_runs(names, lad["oscillator_h_omegas"])}
    if task.problem in REFERENCED:  # lattice, melting: (reference, runs against it) over the same ladder
        make_reference, runs_against = {
            "lattice": (problems.lattice_reference, problems.lattice_runs),
            "melting": (problems.melting_reference, problems.melting_runs),
        }[task.problem]
        dts, end = lad[f"{task.problem}_dts"], lad[f"{task.problem}_end"]
        if not task.integrators:
            ref, notes = make_reference(dts, end)
            return {"reference": ref, "notes": notes}
        return {"runs": runs_against(names, dts, end, reference)}
    if task.problem == "lj_cluster":
        return {"runs": problems.lj_cluster_runs(names, lad["lj_dts"], lad["lj_end"])}
    if task.problem == "heat_pulse":
        runs, notes = heat_runs(task.quick)
        return {"runs": runs, "notes": notes}
    if task.problem == "stability":
        return {"stability": study_stability.stability_rows(names, task.quick)}
    rows = problems.stiff_sweep(names, lad["stiffnesses"], lad["substeps"], frames=lad["stiff_frames"])
    return {"stiff": rows}


def run_study(
    out: Path,
    quick: bool = False,
    integrators=INTEGRATORS,
    problems_to_run=PROBLEMS,
    scheduler: str = "serial",
    workers: int | None = None,
    threads: int | None = None,
    log=print,
) -> StudyResult:
    """Run the study's tasks and write runs.csv, stability.csv, stiff.csv, report.md (and plots with matplotlib).

    `scheduler`: "serial" (one task per problem, one after another here), "local" (a local Dask cluster of `workers`
    processes), "auto" (local where the sweep extra is installed) or a Dask scheduler's address; on Dask each
    problem's integrators are cut into as many tasks as the cluster has worker threads. `threads`: Taichi CPU
    threads per task (default: the cores, shared among the local workers)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    integrators = tuple(integrators)
    scheduler = choose_scheduler(scheduler, len(PROBLEMS), log, "study")
    workers, threads = local_shape(len(integrators), workers if scheduler != "serial" else 1, threads)
    start = time.perf_counter()

    def done(task: StudyTask) -> None:
        log(f"study: {task.name} done at {time.perf_counter() - start:.1f} s")

    if scheduler == "serial":
        tasks = plan_tasks(quick, integrators, problems_to_run)
        results = _run_serial(tasks, threads, done)
        where = "this process"
    else:
        plan_tasks(quick, integrators, problems_to_run)  # its errors before a cluster starts
        with dask_client(scheduler, workers) as client:
            slots = sum(client.nthreads().values()) or 1
            tasks = plan_tasks(quick, integrators, problems_to_run, split=slots)
            results = _run_on_dask(client, threads, tasks, done)
        where = f"Dask ({scheduler}, {slots} worker slots)"
    res = StudyResult()
    for task in tasks:
        part = results[task]
        res.runs += part.get("runs", [])
        res.stability += part.get("stability", [])
        res.stiff += part.get("stiff", [])
        res.notes.update(part.get("notes", {}))
    res.notes["tasks ran on"] = f"{where}, {threads} Taichi threads per task"
    write_outputs(out, res)
    return res


def _reference_task(task: StudyTask) -> StudyTask | None:
    """The task whose result `task` needs: its problem's reference, if it has one and `task` is not it."""
    return StudyTask(task.problem, (), task.quick) if task.problem in REFERENCED and task.integrators else None


def _run_serial(tasks: list[StudyTask], threads: int, done) -> dict:
    results = {}
    for task in tasks:
        ref = _reference_task(task)
        results[task] = run_task(task, threads, results[ref]["reference"] if ref else None)
        done(task)
    return results


def _run_on_dask(client, threads: int, tasks: list[StudyTask], done) -> dict:
    from distributed import as_completed

    futures, references = {}, {}
    for task in tasks:  # a reference comes before its problem's integrator tasks in the plan
        ref = _reference_task(task)
        reference = references[ref] if ref else None
        futures[task] = client.submit(run_task, task, threads, reference, key=task.key, pure=False, retries=3)
        if task.problem in REFERENCED and not task.integrators:  # the reference alone travels to the tasks
            references[task] = client.submit(_reference_of, futures[task], pure=False)
    by_future = {future: task for task, future in futures.items()}
    results = {}
    for future in as_completed(list(futures.values())):
        task = by_future[future]
        results[task] = future.result()
        done(task)
    return results


def _reference_of(part: dict):
    return part["reference"]
