"""State files are checked before use: crafted or damaged files end in one clear line (a SandboxError; exit 2 from the
command line), never a crash, a traceback or a run on garbage. The fuzz mutates a saved state (values, dtypes,
shapes, missing entries, the meta table, the host values, truncation); SANDBOX_FUZZ=campaign runs thousands."""

from __future__ import annotations

import io
import json
import math
import os
import re
import zipfile

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import sandbox
from sandbox.app.cli import EXIT_BAD_INPUT, main
from sandbox.core import runtime
from sandbox.errors import SandboxError, SimulationError
from sandbox.files.persist import load_into

CAMPAIGN = os.environ.get("SANDBOX_FUZZ") == "campaign"
SMALL = {"bodies.0.hi": [70.0, 8.0]}  # candle: springs, heat, refreezing, emitters, lifetimes, kinematic flame


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    """A candle state after a few frames: (the file's arrays by key, its meta, its host values, the path)."""
    sim = sandbox.load("candle", set=SMALL, arch="cpu")
    sim.run(3)
    path = sim.save(tmp_path_factory.mktemp("state") / "candle")
    with np.load(path, allow_pickle=False) as data:
        arrays = {key: data[key] for key in data.files}
    meta, host = json.loads(str(arrays.pop("meta"))), json.loads(str(arrays.pop("host")))
    return arrays, meta, host, path


def write(path, arrays: dict, meta: dict, host: dict) -> None:
    np.savez(path, meta=np.array(json.dumps(meta)), host=np.array(json.dumps(host)), **arrays)


def edited(saved, tmp_path, arrays=None, meta=None, host=None):
    """A copy of the saved state with some arrays, meta keys or host values replaced (None values: removed)."""
    base_arrays, base_meta, base_host, _ = saved
    out = []
    for base, change in ((base_arrays, arrays), (base_meta, meta), (base_host, host)):
        copy = dict(base)
        for key, value in (change or {}).items():
            if value is None:
                copy.pop(key, None)
            else:
                copy[key] = value
        out.append(copy)
    path = tmp_path / "crafted.npz"
    write(path, *out)
    return path


@pytest.mark.parametrize(
    "change, says",
    [
        (lambda a, m, h: {"arrays": {"field:particles.n": np.array(10_000_000, np.int32)}}, "particles.n"),
        (lambda a, m, h: {"arrays": {"field:particles.n": np.array(-3, np.int32)}}, "particles.n"),
        (lambda a, m, h: {"arrays": {"field:springs.i": _set(a["field:springs.i"], 0, 10**6)}}, "springs.i"),
        (lambda a, m, h: {"arrays": {"field:springs.j": _set(a["field:springs.j"], 1, 3000)}}, "spring"),
        (
            lambda a, m, h: {"arrays": {"field:particles.material": _set(a["field:particles.material"], 2, 7)}},
            "material",
        ),
        (lambda a, m, h: {"arrays": {"field:particles.x": _set(a["field:particles.x"], 5, np.nan)}}, "particles.x"),
        (lambda a, m, h: {"arrays": {"field:particles.mass": _set(a["field:particles.mass"], 0, 0.0)}}, "mass"),
        (lambda a, m, h: {"arrays": {"field:particles.v": a["field:particles.v"][:10]}}, "particles.v"),
        (lambda a, m, h: {"arrays": {"field:particles.h": a["field:particles.h"].astype(np.float64)}}, "particles.h"),
        (lambda a, m, h: {"arrays": {"field:springs.bonds": None}}, "springs.bonds"),
        (
            lambda a, m, h: {"arrays": {"ndarray:neighbours.ids": _set(a["ndarray:neighbours.ids"], 3, 10**7)}},
            "neighbour",
        ),
        (lambda a, m, h: {"meta": {"frame": -4}}, "frame"),
        (lambda a, m, h: {"meta": {"step": "ten"}}, "step"),
        (lambda a, m, h: {"meta": {"integrator": None}}, "integrator"),
        (lambda a, m, h: {"meta": {"controls": {}}}, "controls"),  # found by the campaign: a KeyError
        (lambda a, m, h: {"meta": {"controls": {**m["controls"], "world.gravity": 1.0}}}, "control world.gravity"),
        (lambda a, m, h: {"meta": {"scene": {"world": {"dim": 7}}}}, "dim"),
        (lambda a, m, h: {"host": {"clock.frames": -1}}, "clock.frames"),
        (lambda a, m, h: {"host": {"clock.dt": 0.0}}, "clock.dt"),
        (lambda a, m, h: {"host": {"emitters.serial": [1, 2, 3, 4, 5]}}, "emitters.serial"),
        (lambda a, m, h: {"host": {"clock.time": None}}, "clock.time"),
        # issue 72: values the scene file could not hold (an OverflowError in the emitters; accepted controls)
        (lambda a, m, h: {"host": {"clock.dt": 1e308}}, "clock.dt"),
        (lambda a, m, h: {"meta": {"controls": {**m["controls"], "heat.ambient": -300.0}}}, "control heat.ambient"),
        (lambda a, m, h: {"meta": {"controls": {**m["controls"], "heat.ambient": 1e30}}}, "control heat.ambient"),
        (lambda a, m, h: {"meta": {"controls": {**m["controls"], "world.drag": -1.0}}}, "control world.drag"),
        (lambda a, m, h: {"meta": {"controls": {**m["controls"], "world.gravity": [0.0, 1e-300]}}}, "world.gravity"),
        (lambda a, m, h: {"meta": {"controls": {**m["controls"], "pair.scale": [-1.0, 1.0]}}}, "control pair.scale"),
    ],
    ids=lambda v: v if isinstance(v, str) else "",
)
def test_a_crafted_state_file_is_refused_in_one_line(saved, tmp_path, capsys, change, says):
    """The holes of issue 42: a huge or negative count, a spring or material index out of range, NaN, a zero mass,
    a wrong shape or dtype, a missing entry or meta key, a negative frame: `sandbox run --resume` says so in one line
    and exits 2, before anything is built from it."""
    arrays, meta, host, _ = saved
    path = edited(saved, tmp_path, **change(arrays, meta, host))
    code = main(
        [
            "run",
            "candle",
            "--resume",
            str(path),
            "--frames",
            "6",
            "--headless",
            "--quiet",
            "--out",
            str(tmp_path / "x.png"),
        ]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code == EXIT_BAD_INPUT, err
    assert len(err) == 1 and err[0].startswith("error: ") and str(path) in err[0], err
    assert says in err[0], err
    assert not (tmp_path / "x.png").exists()


def _set(array: np.ndarray, index: int, value) -> np.ndarray:
    out = array.copy()
    out.reshape(-1)[index] = value
    return out


def test_a_truncated_or_foreign_file_is_refused(saved, tmp_path):
    _, _, _, path = saved
    data = path.read_bytes()
    for k, blob in enumerate([data[: len(data) // 2], data[:100], b"not a zip at all", b""]):
        broken = tmp_path / f"broken{k}.npz"
        broken.write_bytes(blob)
        with pytest.raises(SandboxError, match=str(broken)):
            sandbox.resume(broken)
    with zipfile.ZipFile(tmp_path / "other.npz", "w") as z:
        z.writestr("meta.npy", b"nonsense")
    with pytest.raises(SandboxError, match="other.npz"):
        sandbox.resume(tmp_path / "other.npz")


MUTATIONS = st.sampled_from(["value", "dtype", "shape", "drop", "meta", "host", "truncate"])
HOSTILE = [0, -1, -(2**31), 2**31 - 1, 10**9, math.nan, math.inf, -math.inf, 1e30, -1e30, 0.5, 255]
HOSTILE_JSON = [None, -1, 0, 10**12, -1.5, "x", [], {}, [1e30], True, 3.0]


@pytest.mark.long  # a fuzz campaign's worth of state files: `python3 -m pytest -m long`
@settings(
    max_examples=3000 if CAMPAIGN else 20,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(data=st.data(), how=MUTATIONS)
def test_fuzzed_state_files_are_refused_or_run_sanely(saved, tmp_path_factory, data, how):
    """A mutated state file is refused with a SandboxError or, where the mutation is harmless, runs: its frames are
    finite, or the blow-up guard stops it by name. Never a crash, never another exception."""
    arrays, meta, host, path = saved
    arrays, meta, host = dict(arrays), dict(meta), dict(host)
    keys = sorted(arrays)
    if how in ("value", "dtype", "shape", "drop"):
        key = data.draw(st.sampled_from(keys))
        a = arrays[key]
        if how == "value" and a.size:
            a = a.copy()
            flat = a.reshape(-1)
            value = data.draw(st.sampled_from(HOSTILE))
            with np.errstate(invalid="ignore", over="ignore"):
                flat[data.draw(st.integers(0, flat.size - 1))] = (
                    np.asarray(value).astype(a.dtype) if np.isfinite(value) or a.dtype.kind == "f" else 0
                )
            arrays[key] = a
        elif how == "dtype":
            arrays[key] = a.astype(data.draw(st.sampled_from([np.float64, np.float32, np.int64, np.int8, np.uint32])))
        elif how == "shape":
            arrays[key] = a.reshape(-1)[: data.draw(st.integers(0, max(a.size - 1, 0)))]
        else:
            arrays.pop(key)
    elif how == "meta":
        meta[data.draw(st.sampled_from(sorted(meta)))] = data.draw(st.sampled_from(HOSTILE_JSON))
    elif how == "host":
        host[data.draw(st.sampled_from(sorted(host)))] = data.draw(st.sampled_from(HOSTILE_JSON))
    target = tmp_path_factory.mktemp("fuzz") / "state.npz"
    write(target, arrays, meta, host)
    if how == "truncate":
        blob = target.read_bytes()
        target.write_bytes(blob[: data.draw(st.integers(0, len(blob) - 1))])
    runtime.reset()  # a fresh runtime per example: Taichi holds about 512 field trees in one
    try:
        sim = sandbox.resume(target)
    except SandboxError as exc:
        assert str(target) in str(exc) or "state" in str(exc)
        return
    try:
        sim.run(2)
    except SimulationError:
        return
    assert np.isfinite(sim.particles()["position"]).all()


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_a_checked_state_still_resumes_bit_for_bit(saved):
    """The checks read the file; they change nothing of what is put back."""
    _, _, _, path = saved
    sim = sandbox.resume(path)
    again = sandbox.resume(path)
    a, b = sim.run(2), again.run(2)
    assert np.array_equal(a["total_energy"], b["total_energy"])


def _npy(shape: tuple, dtype: str, payload: bytes = b"") -> bytes:
    """A .npy member whose header declares `shape` of `dtype`, followed by `payload` (whatever its size)."""
    buffer = io.BytesIO()
    header = {"descr": dtype, "fortran_order": False, "shape": shape}
    np.lib.format.write_array_header_1_0(buffer, header)
    return buffer.getvalue() + payload


def _rezip(path, out, replace: dict | None = None, method: int | None = None, flags: int = 0) -> None:
    """Copy the archive at `path` to `out` with members replaced (name: bytes), and, where asked, every member's
    compression method (`method`) and general-purpose flags (`flags` or-ed in) patched in the written headers."""
    with zipfile.ZipFile(path) as src, zipfile.ZipFile(out, "w") as dst:
        for info in src.infolist():
            name = info.filename[:-4]
            dst.writestr(info.filename, (replace or {}).get(name, src.read(info)))
    if method is None and not flags:
        return
    blob = bytearray(out.read_bytes())
    for signature, method_at, flags_at in ((b"PK\x03\x04", 8, 6), (b"PK\x01\x02", 10, 8)):
        at = blob.find(signature)
        while at >= 0:
            if method is not None:
                blob[at + method_at : at + method_at + 2] = method.to_bytes(2, "little")
            old = int.from_bytes(blob[at + flags_at : at + flags_at + 2], "little")
            blob[at + flags_at : at + flags_at + 2] = (old | flags).to_bytes(2, "little")
            at = blob.find(signature, at + 4)
    out.write_bytes(bytes(blob))


@pytest.mark.parametrize(
    "member, content, says",
    [
        ("field:particles.x", _npy((2**40,), "<f4"), "declares shape (1099511627776,)"),
        ("meta", _npy((10**12,), "<U10"), "declares shape (1000000000000,)"),
        ("host", _npy((4,), "|O", b"\x00" * 32), "Python objects"),
        ("field:particles.v", b"\x93NUMPY garbage", "no valid array header"),
    ],
    ids=["2**40 floats", "10**12 strings", "objects", "garbage header"],
)
def test_a_member_declaring_more_than_it_holds_is_refused_before_any_allocation(saved, tmp_path, member, content, says):
    """A 64-byte member declaring 2**40 floats asked np.load for 4 TiB (a traceback; in the classroom, a dead
    session): its header is now checked against the member's size before anything is allocated."""
    _, _, _, path = saved
    crafted = tmp_path / "crafted.npz"
    _rezip(path, crafted, replace={member: content})
    with pytest.raises(SandboxError, match=re.escape(says)) as caught:
        sandbox.resume(crafted)
    assert str(crafted) in str(caught.value) and "\n" not in str(caught.value)


@pytest.mark.parametrize(
    "method, flags, says",
    [
        (12, 0, "compression method 12"),
        (14, 0, "compression method 14"),
        (99, 0, "compression method 99"),
        (None, 1, "is encrypted"),
    ],
)
def test_members_of_other_compression_methods_or_encrypted_are_refused(saved, tmp_path, method, flags, says):
    _, _, _, path = saved
    crafted = tmp_path / "crafted.npz"
    _rezip(path, crafted, method=method, flags=flags)
    with pytest.raises(SandboxError, match=says):
        sandbox.resume(crafted)


MEMBER_SHAPES = st.sampled_from([(), (0,), (1,), (3, 2), (2**31,), (2**40,), (10**12, 3), (2**62, 2**62)])
MEMBER_DTYPES = st.sampled_from(["<f4", "<f8", "<i4", "|u1", "<U8", "<U100000000", "|O", "|V16", ">f8"])


@settings(
    max_examples=2000 if CAMPAIGN else 25,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(data=st.data())
def test_fuzzed_archive_members_are_refused_in_one_line_never_allocated(saved, tmp_path_factory, data):
    """Any member replaced by a header of any shape and dtype with any payload, under any compression method or
    flags: a SandboxError naming the file, or (where it happens to be valid) a state that is then checked; never a
    MemoryError, a traceback of another kind, or a hang."""
    arrays, _, _, path = saved
    member = data.draw(st.sampled_from(["meta", "host", *sorted(arrays)]))
    payload = data.draw(st.binary(max_size=64))
    content = _npy(data.draw(MEMBER_SHAPES), data.draw(MEMBER_DTYPES), payload)
    crafted = tmp_path_factory.mktemp("members") / "state.npz"
    method = data.draw(st.sampled_from([None, None, 0, 8, 12, 14, 95, 98]))
    _rezip(path, crafted, replace={member: content}, method=method, flags=data.draw(st.sampled_from([0, 0, 1, 8])))
    runtime.reset()
    try:
        sandbox.resume(crafted)
    except SandboxError as exc:
        assert str(crafted) in str(exc) and "\n" not in str(exc)


@pytest.mark.parametrize(
    "scene, control, value",
    [
        ("condensation", "thermal_walls.floor", -1.0),
        ("pressure_cooker", "lid.pressure", -1.0),
        ("pressure_cooker", "lid.pressure", 1e308),
    ],
)
def test_a_molecular_state_files_controls_keep_the_scenes_ranges(tmp_path, scene, control, value):
    """A wall's temperature or the lid's pressure out of the scene's range was a ValueError traceback (issue 72):
    now one SandboxError naming the control, through the API, and the simulation is left as it was."""
    sim = sandbox.load(scene, arch="cpu")
    path = sim.save(tmp_path / "cooker")
    with np.load(path, allow_pickle=False) as data:
        arrays = {key: data[key] for key in data.files}
    meta = json.loads(str(arrays.pop("meta")))
    meta["controls"][control] = value
    write(path, arrays, meta, json.loads(str(arrays.pop("host"))))
    with pytest.raises(SandboxError, match=rf"control {re.escape(control)} = "):
        sandbox.resume(path)
    before = sim.controls.values()
    with pytest.raises(SandboxError, match=rf"control {re.escape(control)} = "):
        load_into(sim, path)
    assert sim.controls.values() == before
    with pytest.raises(SandboxError, match=rf"control {re.escape(control)} = "):
        sim.controls.set({control: value})
