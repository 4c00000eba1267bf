"""Shared helpers: scenes from Python dicts, and Taichi on the CPU backend."""

import copy
import json
import os
import signal
from pathlib import Path

import pytest

from sandbox.config.scene import Scene, scene_from_dict
from sandbox.core import runtime

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "scenes"

# Compiled kernels are cached in the checkout (.cache/taichi, ignored by git): a second run of the suite compiles
# little, and the suite's kernels (over 100 MB) neither crowd the user's own Taichi cache out of its 100 MB nor are
# evicted from their own halfway through a run.
os.environ.setdefault("TI_OFFLINE_CACHE_FILE_PATH", str(ROOT / ".cache" / "taichi"))
os.environ.setdefault("TI_OFFLINE_CACHE_MAX_SIZE_OF_FILES", str(1 << 30))
# The suite crowds the machine on purpose (a worker per core): tests that check which way a step ran keep the team
# of threads whatever the load; tests/test_fast_paths.py checks the crowded plan's way with a LoadWatch of its own.
os.environ.setdefault("SANDBOX_TEAM", "always")


def scene_dict(dim: int = 2, **sections) -> dict:
    """A minimal valid scene table: a 20^dim box domain with one small jelly body; sections replace tables."""
    base = {
        "world": {"dim": dim, "lo": [0.0] * dim, "hi": [20.0] * dim, "dt": 0.001, "substeps": 1},
        "bodies": [{"material": "jelly", "shape": "box", "lo": [5.0] * dim, "hi": [8.0] * dim}],
    }
    base.update(copy.deepcopy(sections))
    return base


def _ignored_here_only(_signum, _frame) -> None:
    """A handler that does nothing: this process still ignores the signal, and the processes it starts do not."""


# The tests stop the processes they start with SIGINT, SIGTERM and SIGHUP, as a person would. A signal ignored at a
# process's start stays ignored in the programs it runs (and the sandbox leaves it so, as nohup asks: app/signals.py),
# so a suite started in the background (SIGINT ignored) or under nohup (SIGHUP) failed those tests. A handler of the
# suite's own keeps the signal away from the suite and lets its children start with the default.
for _signum in (signal.SIGINT, signal.SIGHUP):
    if signal.getsignal(_signum) is signal.SIG_IGN:
        signal.signal(_signum, _ignored_here_only)

runtime.own_process()  # the tests are the sandbox's own: pinned CPU workers, light compile-error excerpts (as the CLI)


@pytest.fixture(autouse=True)
def fresh_taichi():
    """A fresh Taichi runtime per test. A runtime holds at most ~512 field trees (runtime.reset), and a kernel's
    offline-cache key names the field ids it reads, which restart at each start: a scene built first in a test has the
    ids, and so the cached kernels, of the same scene built first in any earlier test."""
    runtime.reset()
    yield


def make_scene(data: dict, name: str = "test.toml") -> Scene:
    return scene_from_dict(data, ROOT / "tests" / name)


@pytest.fixture
def scene_file(tmp_path):
    """Write TOML text to a scene file in a temporary folder; returns its path."""

    def write(text: str, name: str = "scene.toml") -> Path:
        path = tmp_path / name
        path.write_text(text)
        return path

    return write


def pytest_addoption(parser):
    parser.addoption("--regen-golden", action="store_true", help="rewrite the stored golden images in tests/golden")
    parser.addoption("--record-durations", action="store_true", help="rewrite tests/durations.json from this run")


@pytest.fixture
def compiled_kernels(monkeypatch) -> list[str]:
    """The names of the kernels compiled (or loaded from the offline cache) from now on in this test, in order."""
    from taichi.lang import kernel_impl

    compiled: list[str] = []
    materialize = kernel_impl.Kernel.materialize

    def materialize_and_note(self, key=None, args=None, arg_features=None):
        if key not in self.compiled_kernels:
            compiled.append(self.func.__qualname__)
        return materialize(self, key, args, arg_features)

    monkeypatch.setattr(kernel_impl.Kernel, "materialize", materialize_and_note)
    return compiled


# Each module's recorded worker-seconds (setup, call and teardown of its tests with an empty kernel cache, 2 workers):
# the modules start longest first, so that the last to start are short and both workers finish together. A module not
# recorded starts last. `python3 -m pytest --record-durations` (and `-m long --record-durations`) rewrites the file
# from the run it finishes.
DURATIONS_FILE = ROOT / "tests" / "durations.json"
DURATIONS: dict[str, float] = json.loads(DURATIONS_FILE.read_text()) if DURATIONS_FILE.exists() else {}


def _module(item) -> str:
    return item.module.__name__.rpartition(".")[2]


@pytest.hookimpl(tryfirst=True)  # before xdist's own, which reads the groups
def pytest_collection_modifyitems(config, items):
    """Each module's tests run one after another on one worker (an xdist group per module, unless a test names its
    own): tests of one module mostly build the same scenes, and a kernel compiled by one test is loaded from the
    offline cache by the next, where two workers running neighbouring tests side by side would both compile it."""
    for item in items:
        if item.get_closest_marker("xdist_group") is None:
            item.add_marker(pytest.mark.xdist_group(_module(item)))
    items.sort(key=lambda item: -DURATIONS.get(_module(item), -1.0))


_recorded: dict[str, float] = {}


def pytest_runtest_logreport(report):
    """Each test's setup, call and teardown, summed by module (on the controller too: xdist sends it the reports)."""
    module = report.nodeid.split("::")[0].rpartition("/")[2].removesuffix(".py")
    _recorded[module] = _recorded.get(module, 0.0) + report.duration


def pytest_sessionfinish(session):
    """--record-durations: the modules run now get their recorded seconds (the others keep theirs)."""
    if session.config.getoption("--record-durations") and not hasattr(session.config, "workerinput"):
        merged = {**DURATIONS, **{k: round(v, 1) for k, v in _recorded.items()}}
        ordered = dict(sorted(merged.items(), key=lambda kv: -kv[1]))
        DURATIONS_FILE.write_text(json.dumps(ordered, indent=1) + "\n")
