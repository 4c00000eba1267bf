"""Batched host <-> field copies (sandbox/transfer.py): exact round trips, leading rows only, clear shape errors."""

import warnings

import numpy as np
import pytest
import taichi as ti

from sandbox.core import runtime, transfer


def test_one_batch_copies_mixed_fields_exactly_and_leaves_the_rows_past_the_values():
    runtime.reset()
    runtime.init("cpu", "f32")
    scalar = ti.field(ti.f32, shape=10)
    wide = ti.field(ti.f64, shape=6)
    ints = ti.field(ti.i32, shape=(5, 3))
    vec = ti.Vector.field(3, ti.f32, shape=8)
    scalar.fill(-1.0)
    vec.fill(-2.0)
    rng = np.random.default_rng(1)
    values = {
        "scalar": rng.normal(size=4).astype(np.float32),  # the first 4 of 10 rows
        "wide": np.array([1 / 3, 1e300, -0.0, 2**-60, 7.0, np.pi]),
        "ints": rng.integers(-(2**31), 2**31 - 1, size=(5, 3)).astype(np.int32),
        "vec": rng.normal(size=(8, 3)).astype(np.float32),
    }
    transfer.upload([(scalar, values["scalar"]), (wide, values["wide"]), (ints, values["ints"]), (vec, values["vec"])])
    got = transfer.download([scalar, wide, ints, vec])
    assert np.array_equal(got[0][:4], values["scalar"]) and np.all(got[0][4:] == -1.0)  # the rest kept
    assert np.array_equal(got[1], values["wide"]) and got[1].dtype == np.float64  # f64 exact
    assert np.array_equal(got[2], values["ints"]) and got[2].dtype == np.int32
    assert np.array_equal(got[3], values["vec"]) and got[3].shape == (8, 3)
    assert np.array_equal(got[3], vec.to_numpy())  # what Taichi's own copy sees
    with pytest.raises(ValueError, match="expecting"):
        transfer.upload([(vec, np.zeros((8, 2)))])


def test_unsigned_32_bit_values_copy_exactly_where_the_float_staging_is_single_precision(monkeypatch):
    """Seeds are u32: they go through the int32 staging as their bits, so a GPU backend, whose float staging is
    float32 (exact only to 2^24), copies them exactly too."""
    runtime.reset()
    runtime.init("cpu", "f32")
    monkeypatch.setattr(transfer, "_float_staging", lambda: np.float32)  # as on Vulkan or Metal
    seeds = ti.field(ti.u32, shape=4)
    one = ti.field(ti.u32, shape=())
    pairs = ti.Vector.field(2, ti.u32, shape=2)
    values = np.array([0, 2**24 + 1, 2**31 + 5, 2**32 - 1], np.uint32)
    transfer.upload([(seeds, values), (one, np.uint32(4_000_000_007)), (pairs, [[1, 2**32 - 2], [2**31, 2**24 + 3]])])
    assert np.array_equal(seeds.to_numpy(), values) and one[None] == 4_000_000_007
    got = transfer.download([seeds, one, pairs])
    assert [g.dtype for g in got] == [np.uint32] * 3
    assert np.array_equal(got[0], values) and got[1] == 4_000_000_007
    assert got[2].tolist() == [[1, 2**32 - 2], [2**31, 2**24 + 3]]


def test_many_fields_of_one_shape_copy_in_one_kernel_without_taichis_unrolling_warning():
    """A scene's build copies dozens of one-row tables together; Taichi warns (SyntaxWarning) about a static loop
    of more than 32 iterations, so the copy loops go in chunks."""
    runtime.reset()
    runtime.init("cpu", "f32")
    fields = [ti.field(ti.f32, shape=()) for _ in range(70)] + [ti.field(ti.i32, shape=3) for _ in range(40)]
    values = [np.float32(k / 7) for k in range(70)] + [np.arange(3, dtype=np.int32) + k for k in range(40)]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        transfer.upload(list(zip(fields, values)))
        got = transfer.download(fields)
    assert all(np.array_equal(g, v) for g, v in zip(got, values))
