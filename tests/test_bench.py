"""The benchmark's workloads measure what they say: W2 is a steady spring lattice, W3 the same run every repeat."""

import numpy as np
import pytest

from sandbox.research import bench

pytestmark = pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)


def test_the_w2_lattice_holds_its_shape_under_its_own_weight():
    """A 100-layer gel block on a plate: it sags and rebounds, but stays a block (a jelly one collapsed into a pile
    while it was timed, its neighbour lists widening tenfold), so W2's cost does not drift with the time it runs."""
    sim = bench.spring_heat_lattice_sim("cpu")
    y0 = sim.positions()[:, 1]
    sim.step(1500)  # 3 time units: several sag-and-rebound periods
    y = sim.positions()[:, 1]
    assert abs(y.mean() - y0.mean()) < 0.05 * y0.mean()
    assert y.max() > 0.95 * y0.max()
    assert sim.hood.lists.grown == 0  # no particle has gained neighbours beyond the lattice's
    stats = sim.stats()
    assert stats.broken_springs == 0 and stats.mean_temperature > 20.0  # heat flows in from the plate


def test_w3_is_timed_over_the_same_run_from_the_start_every_repeat():
    """measure_from_start resets the scene before each timed run: every run ends in the same state."""
    sim = bench.melting_block_sim("cpu")
    ends = []
    original = sim.reset

    def reset_then_remember_the_last_end():
        if sim.step_count:
            ends.append((sim.step_count, sim.positions().copy()))
        original()

    sim.reset = reset_then_remember_the_last_end
    res = bench.measure_from_start(sim, repeats=2)
    ends.append((sim.step_count, sim.positions()))
    assert res["steps_per_batch"] == 300 * 8  # the demo's frames x substeps
    assert [count for count, _ in ends] == [2400, 2400, 2400]  # the compiling run, then each timed one
    assert np.array_equal(ends[0][1], ends[1][1]) and np.array_equal(ends[1][1], ends[2][1])  # the same each time
    assert sim.stats().molten_fraction > 0.8  # the run spans the melt, solid to puddle


def test_the_pair_rate_counts_each_pair_within_the_cutoff_once_and_the_ideal_loop_computes_lj_forces():
    """bench's pair interactions: pair_count agrees with a brute-force count over the periodic box; the ideal
    in-cache loop's forces are the Lennard-Jones forces of NumPy's brute-force sum."""
    import numpy as np

    from sandbox.research.bench import lj_box_sim
    from sandbox.research.peer_bench import _IdealLoop, pair_count

    sim = lj_box_sim(20, "cpu")  # 400 particles
    sim.step(20)
    x = sim.positions()
    box = np.asarray(sim.scene.world.hi, float) - np.asarray(sim.scene.world.lo, float)
    d = x[:, None, :] - x[None, :, :]
    d -= box * np.round(d / box)
    r2 = (d**2).sum(-1)
    brute = int((np.triu(r2 < sim.scene.pair.cutoff**2, k=1)).sum())
    assert pair_count(sim) == brute

    loop = _IdealLoop(2, 256, 0.8, 2.5)
    force = loop.force()
    x = loop.x.to_numpy().astype(np.float64)
    d = x[:, None, :] - x[None, :, :]  # an open box: no periodic images
    r2 = (d**2).sum(-1)
    np.fill_diagonal(r2, np.inf)
    inv6 = np.where(r2 < 6.25, r2**-3, 0.0)
    expected = (24.0 * inv6 * (2.0 * inv6 - 1.0) / r2)[:, :, None] * d
    assert np.allclose(force, expected.sum(1), rtol=1e-3, atol=1e-3)
    assert loop.pairs == int(np.triu(r2 < 6.25, k=1).sum())  # each pair once, in a half list


def test_lammps_is_tried_on_the_cores_the_sandbox_uses():
    """LAMMPS gets the cores the sandbox's threads get: pinned to one core (taskset) it ran 2 processes there against
    the sandbox's one thread; on 16 a process per core or 16 threads."""
    from sandbox.research.peer_bench import lammps_configs

    assert lammps_configs(1) == (("plain", 1, 1), ("opt", 1, 1), ("omp", 1, 1))
    assert lammps_configs(2) == (("plain", 2, 1), ("opt", 2, 1), ("omp", 1, 2), ("omp", 2, 1))
    assert lammps_configs(16) == (("plain", 16, 1), ("opt", 16, 1), ("omp", 1, 16), ("omp", 16, 1))


def test_lammps_is_tried_in_every_configuration_and_the_fastest_is_kept(monkeypatch):
    """The peer is LAMMPS at its best on these cores: each configuration (plain, -sf opt, -sf omp as 1 x 2 and 2 x 1)
    is run with the suffix, package and thread count it names, the fastest is kept, and in.lj's own list policy
    (every 20 steps, unchecked) is passed as variables. LAMMPS itself is stood in for by its output's last line."""
    import types

    seconds = {"plain": 1.0, "opt": 0.8, "omp": 0.9}
    calls = []

    def fake_run(cmd, capture_output, text, cwd, env):
        calls.append((cmd, env["OMP_NUM_THREADS"]))
        accel = cmd[cmd.index("-sf") + 1] if "-sf" in cmd else "plain"
        loop = f"Loop time of {seconds[accel]} on 2 procs for 500 steps with 10082 atoms"
        return types.SimpleNamespace(stdout=f"...\n{loop}\n")

    monkeypatch.setattr(bench.shutil, "which", lambda name: f"/usr/bin/{name}")
    monkeypatch.setattr(bench.subprocess, "run", fake_run)
    run, found = bench.lammps_at_its_best(100, 2, 500, cores=2)
    assert found["config"] == "opt 2x1"
    assert list(found["rates"]) == ["plain 2x1", "opt 2x1", "omp 1x2", "omp 2x1"]
    omp_one = calls[2][0]
    assert omp_one[:3] != ["/usr/bin/mpirun", "-np", "2"] and calls[2][1] == "2"  # one process, two threads
    assert omp_one[omp_one.index("-pk") : omp_one.index("-pk") + 3] == ["-pk", "omp", "2"]
    own = run("in.lj")
    cmd = calls[-1][0]
    assert own["policy"] == "in.lj" and own["particle_steps_per_second"] == 10082 * 500 / 0.8
    assert cmd[cmd.index("every") + 1] == "20" and cmd[cmd.index("check") + 1] == "no"


def test_the_machine_line_says_whether_sessions_share_the_cores_first(tmp_path):
    """Under load what each side gets depends on Linux's autogroup (mpirun gives LAMMPS a session of its own): the
    bench records and prints it, and leaves it out where it is not known."""
    from sandbox.app.cli_bench import _autogroup, machine_line

    flag = tmp_path / "autogroup"
    flag.write_text("1\n")
    assert _autogroup(str(flag)) is True
    flag.write_text("0\n")
    assert _autogroup(str(flag)) is False
    assert _autogroup(str(tmp_path / "none")) is None
    base = {"cpu": "X", "cpus": 2, "vectors": ["avx2"], "caches": {"L1d": "48K"}}
    assert machine_line({**base, "autogroup": True}).endswith("(cores shared between sessions first) on")
    assert machine_line({**base, "autogroup": False}).endswith("(cores shared between sessions first) off")
    assert machine_line({**base, "autogroup": None}) == "on X, 2 cores; vector extensions avx2; data caches L1d 48K"
    pinned = machine_line({**base, "cpus": 16, "usable_cpus": 2})  # taskset -c 0,1 on a 16-core machine
    assert pinned.startswith("on X, 2 of its 16 cores;")
    fewer = machine_line({**base, "cpus": 16, "usable_cpus": 16, "threads": 4})  # SANDBOX_CPU_THREADS=4
    assert fewer.startswith("on X, 16 cores, 4 threads (SANDBOX_CPU_THREADS);")
    assert machine_line({**base, "threads": 2}).startswith("on X, 2 cores;")


def _small_peer_comparison(monkeypatch, tmp_path, **options) -> int:
    """`sandbox bench --3d --side 8 --quick` with `options` (lammps, contended, rounds), the ideal loop not run."""
    import argparse

    from sandbox.app import cli_bench

    monkeypatch.setattr(cli_bench, "ideal_pair_rate", lambda dim: 1e9)
    args = argparse.Namespace(three_d=True, side=8, quick=True, out=str(tmp_path), arch="cpu", json=None, **options)
    return cli_bench.peer_comparison(args, repeats=1)


def test_under_load_the_sandbox_is_timed_in_batches_of_as_many_steps_as_quiet(monkeypatch, tmp_path):
    """measure() sizes its batches to about 0.4 s, so beside hogs a batch held a quarter of the quiet batch's steps,
    and a call's fixed cost (velocity Verlet's synchronising force evaluation) weighed four times as much, a cost
    LAMMPS's runs of 500 steps do not pay. The loaded condition is timed in batches of the quiet condition's steps."""
    import contextlib

    from sandbox.research import bench, peer_bench

    loaded = [False]
    batches: dict[bool, list[int]] = {False: [], True: []}
    real = bench.timed_steps

    def timed(sim, steps):  # under "load" every step reads four times as slow
        batches[loaded[0]].append(steps)
        return real(sim, steps) * (4 if loaded[0] else 1)

    @contextlib.contextmanager
    def hog(count):
        loaded[0] = True
        yield
        loaded[0] = False

    monkeypatch.setattr(bench, "timed_steps", timed)
    monkeypatch.setattr(peer_bench, "CpuHog", hog)
    assert _small_peer_comparison(monkeypatch, tmp_path, lammps=False, contended=1, rounds=None) == 0
    quiet_batch = batches[False][-1]  # after the 20-step probe that sizes it
    assert batches[False] == [20, quiet_batch] and quiet_batch > 100
    assert batches[True] == [quiet_batch]  # no probe: the quiet batch's steps


def test_the_rounds_against_lammps_are_as_many_as_asked(monkeypatch, tmp_path, capsys):
    """`--rounds N` alternates N rounds of each side (3 by default) on a machine too noisy for three; the medians of
    those rounds are compared. LAMMPS runs both ways each round (issue 77): with the strict list check and with
    in.lj's own list policy, and the sandbox's ratio to each is printed side by side, with each side's spread."""
    from sandbox.app import cli_bench

    runs = []

    def fake_lammps(policy=None):
        runs.append(policy)
        return {"particle_steps_per_second": 1e6 * len(runs)}

    found = {"config": "plain 1x1", "rates": {"plain 1x1": 1e6}}
    monkeypatch.setattr(cli_bench, "lammps_at_its_best", lambda n_side, dim, steps: (fake_lammps, found))
    assert _small_peer_comparison(monkeypatch, tmp_path, lammps=True, contended=None, rounds=4) == 0
    assert runs == ["strict", "in.lj"] * 4  # four rounds, each policy in each
    out = capsys.readouterr().out
    assert "LAMMPS (list checked every step)   5.00 M" in out  # of 1, 3, 5, 7: the upper middle
    assert "LAMMPS (in.lj's own list policy)   6.00 M" in out  # of 2, 4, 6, 8
    assert "LAMMPS strict 7.00, LAMMPS in.lj 4.00" in out  # each side's rounds, max over min


def test_the_report_says_which_rounds_stepped_crowded(monkeypatch, tmp_path, capsys):
    """Issue 77: a round that other work crowded off its cores reads at a fraction of the others (the team steps
    the crowded way: step/crowd.py), and the spread alone did not say why. Each round's share of crowded steps is
    measured and the report counts the rounds that stepped crowded; here the second and fourth of four."""
    from sandbox.app import cli_bench
    from sandbox.research import bench

    runs = []
    real = bench.timed_steps

    def timed(sim, steps):
        took = real(sim, steps)
        if (len(runs) // 2) % 2 == 1:  # the sandbox's rounds 2 and 4 (LAMMPS runs twice a round)
            sim.plan.crowded_steps += steps
        return took

    def fake_lammps(policy=None):
        runs.append(policy)
        return {"particle_steps_per_second": 1e6}

    found = {"config": "plain 1x1", "rates": {"plain 1x1": 1e6}}
    monkeypatch.setattr(bench, "timed_steps", timed)
    monkeypatch.setattr(cli_bench, "lammps_at_its_best", lambda n_side, dim, steps: (fake_lammps, found))
    assert _small_peer_comparison(monkeypatch, tmp_path, lammps=True, contended=None, rounds=4) == 0
    assert "; 2 of the sandbox's 4 rounds stepped crowded (other work)" in capsys.readouterr().out


def test_under_load_lammps_is_compared_at_its_best_under_that_load(monkeypatch, tmp_path, capsys):
    """LAMMPS's OpenMP threads spin at barriers as a team of threads does: beside 3 hogs on 2 cores `omp 1x2`, the
    fastest configuration quiet in one run, kept under a tenth of its quiet rate while `opt 2x1` kept 30%, so the
    sandbox's ratio under load read 270% of its quiet one. Every configuration is tried again under the load and the
    fastest there is the peer."""
    import contextlib

    from sandbox.app import cli_bench
    from sandbox.research import peer_bench

    loaded = [False]

    @contextlib.contextmanager
    def hog(count):
        loaded[0] = True
        yield
        loaded[0] = False

    def at_its_best(n_side, dim, steps):
        if loaded[0]:  # under load opt 2x1 leads: 1 M particle-steps/s against omp 1x2's 0.1 M
            found = {"config": "opt 2x1", "rates": {"opt 2x1": 1e6, "omp 1x2": 1e5}}
            return (lambda policy=None: {"particle_steps_per_second": 1e6}), found
        found = {"config": "omp 1x2", "rates": {"opt 2x1": 3e6, "omp 1x2": 4e6}}
        return (lambda policy=None: {"particle_steps_per_second": 4e6}), found

    monkeypatch.setattr(peer_bench, "CpuHog", hog)
    monkeypatch.setattr(cli_bench, "lammps_at_its_best", at_its_best)
    assert _small_peer_comparison(monkeypatch, tmp_path, lammps=True, contended=3, rounds=1) == 0
    out = capsys.readouterr().out
    assert "LAMMPS at its best here: omp 1x2" in out and "LAMMPS at its best beside 3 hogs: opt 2x1" in out
    assert "LAMMPS (list checked every step)   4.00 M" in out and "LAMMPS (list checked every step)   1.00 M" in out
