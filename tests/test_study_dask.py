"""`sandbox study` on Dask: the same tables as the serial study, the integrators cut into tasks per worker and the
references computed once; bad study arguments end in one line."""

import csv

import numpy as np
import pytest

from sandbox.errors import SandboxError
from sandbox.research.study import StudyTask, plan_tasks, run_study

pytestmark = [
    pytest.mark.xdist_group("dask"),
    pytest.mark.long,
]  # the two cluster tests do not start their clusters side by side

PAIR = ("symplectic_euler", "velocity_verlet")


def _table(path):
    """A study CSV without the columns that time the runs."""
    with open(path, newline="") as f:
        return [
            {k: v for k, v in row.items() if k not in ("wall_seconds", "particle_steps_per_second")}
            for row in csv.DictReader(f)
        ]


def test_the_plan_cuts_integrators_into_contiguous_tasks_after_each_reference():
    tasks = plan_tasks(True, PAIR + ("rk4",), ("lattice", "oscillator"), split=2)
    assert tasks == [
        StudyTask("oscillator", PAIR, True),
        StudyTask("oscillator", ("rk4",), True),
        StudyTask("lattice", (), True),
        StudyTask("lattice", PAIR, True),
        StudyTask("lattice", ("rk4",), True),
    ]
    assert [t.problem for t in plan_tasks(True)].count("melting") == 0  # --quick leaves the melting block out
    assert [t.integrators for t in plan_tasks(False, PAIR, ("melting",))] == [(), PAIR]
    with pytest.raises(SandboxError, match="unknown problem 'latice'"):
        plan_tasks(True, PAIR, ("latice",))
    with pytest.raises(SandboxError, match="unknown integrator 'leapfrog'"):
        plan_tasks(True, ("leapfrog",))


@pytest.mark.slow  # a 2-worker Dask cluster and the serial study beside it
def test_the_study_on_a_local_cluster_equals_the_serial_study(tmp_path):
    pytest.importorskip("distributed")
    problems = ("oscillator", "lattice")
    said = []
    serial = run_study(tmp_path / "serial", True, PAIR, problems, scheduler="serial", threads=1, log=said.append)
    assert [line.split(" done")[0] for line in said] == [
        "study: oscillator symplectic_euler, velocity_verlet",
        "study: lattice reference",
        "study: lattice symplectic_euler, velocity_verlet",
    ]
    said.clear()
    spread = run_study(
        tmp_path / "dask", True, PAIR, problems, scheduler="local", workers=2, threads=1, log=said.append
    )
    assert len(said) == 5  # each problem's two integrators as two tasks, and the lattice's reference once
    for name in ("runs", "stability", "stiff"):
        assert _table(tmp_path / "serial" / f"{name}.csv") == _table(tmp_path / "dask" / f"{name}.csv")
    assert len(_table(tmp_path / "dask" / "runs.csv")) == 2 * 4 + 2 * 3  # oscillator: 4 h*w; lattice: 3 steps
    assert serial.notes["lattice_reference (rk4) dt"] == spread.notes["lattice_reference (rk4) dt"]
    assert spread.notes["tasks ran on"] == "Dask (local, 2 worker slots), 1 Taichi threads per task"
    lattice = [r for r in spread.runs if r.problem == "lattice"]
    assert [r.integrator for r in lattice] == ["symplectic_euler"] * 3 + ["velocity_verlet"] * 3
    assert all(0 < r.error < 0.02 for r in lattice)  # measured against the reference the workers were given


def test_bad_study_arguments_end_in_one_line(tmp_path, capsys):
    from sandbox.app.cli import main

    out = str(tmp_path / "s")
    assert main(["study", "--out", out, "--problems", "oscillator,latice"]) == 2
    assert main(["study", "--out", out, "--integrators", "leapfrog"]) == 2
    assert main(["study", "--out", out, "--scheduler", "remote"]) == 2
    assert main(["study", "--out", out, "--workers", "0"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err == [
        "error: --problems oscillator,latice: expected a comma-separated list of oscillator, lattice, lj_cluster, "
        "melting, heat_pulse, stability, stiff",
        "error: --integrators leapfrog: expected a comma-separated list of forward_euler, symplectic_euler, midpoint, "
        "verlet, velocity_verlet, rk4, implicit_euler",
        "error: --scheduler remote: expected auto, local, serial or an address tcp://HOST:PORT",
        "error: --workers 0: expected an integer from 1 to 1,024",
    ]
    assert not (tmp_path / "s").exists()  # nothing written


def test_a_studys_jobs_on_a_local_cluster_equal_them_one_after_another_in_order():
    """run_jobs (the coexistence and heating studies' temperatures and pressures): on two local Dask workers each job
    runs in a fresh runtime with its share of the cores and returns what it returns one after another, in order."""
    from sandbox.research.dask_pool import run_jobs

    jobs = [(0.015, 8.0, 3), (0.03, -8.0, 3)]  # a small crystal under two lids, briefly heated or cooled
    serial = run_jobs(_heated_positions, jobs, "serial")
    parallel = run_jobs(_heated_positions, jobs, "local", workers=2)
    assert len(parallel) == 2 and all(np.array_equal(a, b) for a, b in zip(serial, parallel))
    assert not np.array_equal(serial[0], serial[1])  # each job its own


def _heated_positions(pressure: float, power: float, cells: int):
    from sandbox.config.scene import scene_from_dict
    from sandbox.research.heating_curve import heating_scene
    from sandbox.research.study_runs import STUDY_PATH
    from sandbox.simulation import Simulation

    sim = Simulation(scene_from_dict(heating_scene(pressure, power, cells, height=20.0), STUDY_PATH))
    sim.step(300)
    return sim.positions()
