"""Taichi's internals are touched in one module: each fast path is active on the pinned Taichi, each falls back to
the plain path on a Taichi it does not know, and nothing changes Taichi for the whole process unless asked."""

import gc
import inspect
import json
import os
import subprocess
import sys

import pytest
import taichi as ti
from taichi.lang import kernel_impl

from sandbox.core import runtime, taichi_compat
from sandbox.core.oriented import data_oriented
from sandbox.errors import SandboxError
from sandbox.step.rates import Rates
from tests.conftest import ROOT


def _counter_class():
    runtime.init("cpu", "f32")

    @data_oriented
    class Counter:
        def __init__(self):
            self.total = ti.field(ti.i32, shape=())
            self.step = 3

        @ti.kernel
        def add(self, k: ti.i32):
            self.total[None] += k * self.step

    return Counter


def test_every_fast_path_is_active_on_the_pinned_taichi():
    assert taichi_compat.SUPPORTED and tuple(ti.__version__[:2]) == (1, 7)
    # data-oriented classes read plain attributes the ordinary way, only kernels through Taichi's lookup
    assert Rates.__getattribute__.__module__ == "sandbox.core.oriented"
    counter = _counter_class()()
    counter.add(2)
    assert counter.total[None] == 6
    # the whole-step kernels compile without the CFG pass, which comes back afterwards
    assert ti.cfg.cfg_optimization
    with taichi_compat.without_cfg_pass():
        assert not ti.cfg.cfg_optimization
    assert ti.cfg.cfg_optimization
    # the launch paths launch_count wraps exist
    paths = taichi_compat.launch_paths()
    assert len(paths) == 5 and all(callable(getattr(owner, name)) for owner, name, _ in paths)
    # the tests own their process (conftest): compile-error excerpts are the light ones, and each function's source
    # is read once: the same lines inspect reads, in a list of the caller's own
    assert taichi_compat.kernel_debug_info_lightened() and taichi_compat.kernel_sources_cached()
    lines, first = kernel_impl.getsourcelines(_counter_class)
    assert (lines, first) == inspect.getsourcelines(_counter_class)
    lines.append("# changed by a caller")
    assert kernel_impl.getsourcelines(_counter_class) == inspect.getsourcelines(_counter_class)


class _Holder:
    """Two ndarrays in a reference cycle: Python frees them only when its cycle collector next runs."""

    def __init__(self):
        self.me = self
        self.small = runtime.ndarray(ti.i32, (1, 1))
        self.lists = runtime.ndarray(ti.i32, (1000, 16))


def test_ndarrays_collected_after_a_reset_leave_the_new_runtimes_arrays_whole():
    """Taichi 1.7 frees an ndarray by address when Python collects it, in whatever runtime then runs; one collected
    after a reset could free the array of the next runtime that took its address (a test's neighbour lists then read
    as garbage). reset() detaches the sandbox's ndarrays first: a later collection frees nothing, and using one fails
    plainly instead of reading freed memory."""
    gc.disable()  # cycles are collected when the test says so
    try:
        for _ in range(6):
            runtime.init("cpu", "f32")
            left = [_Holder() for _ in range(3)]
            survivor = left[0].small
            del left
            runtime.reset()
            runtime.init("cpu", "f32")
            arrays = [runtime.ndarray(ti.i32, shape) for shape in [(1, 1)] * 3 + [(1000, 16)] * 3]
            for k, array in enumerate(arrays):
                array.fill(k)
            gc.collect()
            assert [int(array.to_numpy().sum()) for array in arrays] == [0, 1, 2, 3 * 16000, 4 * 16000, 5 * 16000]
            with pytest.raises(AttributeError):
                survivor.to_numpy()
            runtime.reset()
    finally:
        gc.enable()


def test_an_unknown_taichi_gets_the_plain_path_with_one_warning(monkeypatch):
    monkeypatch.setattr(taichi_compat, "SUPPORTED", False)
    monkeypatch.setattr(taichi_compat, "_warned", set())
    with pytest.warns(RuntimeWarning, match="not a version the sandbox knows") as said:
        plain = _counter_class()
        _counter_class()  # said once only
    messages = [str(w.message) for w in said]
    assert any("attribute lookup" in m for m in messages)
    assert any("kernel sources are read again" in m for m in messages)
    assert len(messages) == len(set(messages)), messages  # (a Taichi start here also says how it formats errors)
    assert plain.__getattribute__.__module__.startswith("taichi.")  # Taichi's own lookup
    counter = plain()
    counter.add(5)
    assert counter.total[None] == 15  # kernels work the same
    with pytest.warns(RuntimeWarning, match="CFG pass"), taichi_compat.without_cfg_pass():
        assert ti.cfg.cfg_optimization  # left as Taichi has it
    with pytest.raises(SandboxError, match="counting kernel launches needs Taichi 1.7"):
        taichi_compat.launch_paths()


PROBE = """
import json, sys
import sandbox
from sandbox.core import taichi_compat, threads
from sandbox.config.scene import load_scene
from sandbox.simulation import Simulation
from sandbox.step.rates import Rates
if sys.argv[1] == "own":
    sandbox.own_process()  # the public spelling, straight after the import
Simulation(load_scene("scenes/spring_lattice.toml"))
light, sources = taichi_compat.kernel_debug_info_lightened(), taichi_compat.kernel_sources_cached()
print(json.dumps({"pinned": len(threads.pinned), "light": light, "sources": sources}))
"""


@pytest.mark.parametrize("mode", ["embedded", "own"])
def test_nothing_changes_taichi_for_the_whole_process_unless_asked(mode):
    """Embedded in another program, the sandbox neither pins Taichi's CPU workers, reformats its compile errors nor
    remembers kernel sources;
    the CLI, these tests and the classroom notebook opt in with sandbox.own_process()."""
    done = subprocess.run(
        [sys.executable, "-c", PROBE, mode], cwd=ROOT, capture_output=True, text=True, timeout=300, check=True
    )
    seen = json.loads(done.stdout.strip().splitlines()[-1])
    assert seen["light"] == seen["sources"] == (mode == "own")
    if mode == "embedded":
        assert seen["pinned"] == 0
    elif taichi_compat.cpu_threads() >= 2 and hasattr(__import__("os"), "sched_getaffinity"):
        assert seen["pinned"] == taichi_compat.cpu_threads()


ONE_THREAD_PROBE = """
import os, sys
import taichi as ti
from sandbox.core import runtime
if sys.argv[1] == "own":
    runtime.own_process()
for threads in ("1", "2"):
    os.environ["SANDBOX_CPU_THREADS"] = threads
    runtime.reset()
    runtime.init("cpu")

    @ti.kernel
    def first_over(limit: ti.i32) -> ti.i32:
        found = -1
        for i in range(100):  # a break in a top-level loop compiles only where the loop runs in place
            if i * i > limit:
                found = i
                break
        return found

    try:
        print(threads, first_over(50))
    except Exception as error:
        print(threads, type(error).__name__)
"""


@pytest.mark.parametrize("mode", ["embedded", "own"])
def test_on_one_cpu_thread_the_sandboxs_own_process_runs_every_loop_in_place(mode, tmp_path):
    """Taichi's pool hands even a one-thread loop to its worker (about 70 us a loop on the 2-core Xeon): where the
    sandbox owns the process and Taichi runs one CPU thread (a classroom host), each loop is compiled serialized,
    which Taichi shows by allowing what only a serial top-level loop may do, a `break`; on two threads, or embedded
    in another program, loops stay Taichi's."""
    probe = tmp_path / "probe.py"  # Taichi reads a kernel's source from its file
    probe.write_text(ONE_THREAD_PROBE)
    done = subprocess.run(
        [sys.executable, str(probe), mode],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    said = dict(line.split() for line in done.stdout.strip().splitlines()[-2:])
    assert said["1"] == ("8" if mode == "own" else "TaichiSyntaxError"), done.stdout + done.stderr
    assert said["2"] == "TaichiSyntaxError", done.stdout + done.stderr
