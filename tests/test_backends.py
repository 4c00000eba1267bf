"""The GPU code path on Taichi's Vulkan backend, and counting kernel launches on any backend.

On a GPU backend a scene steps the long way with the GPU layout: full neighbour lists gathered without write
conflicts, every loop parallel, each pass launched from the host. Mesa's software Vulkan (lavapipe, which .ci/run
installs) runs that path on the CPU; no CUDA machine is needed to check that it computes what the CPU path does.
"""

import json
import subprocess
import sys

import numpy as np
import pytest
import taichi as ti

from sandbox.config.scene import load_scene
from sandbox.core import runtime
from sandbox.render.raster import Renderer
from sandbox.research import bench
from sandbox.research.launch_count import count_launches
from sandbox.simulation import Simulation

from .conftest import ROOT

pytestmark = pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)

LJ_STEPS = 400
FRAMES = 20


def run_both_workloads(arch: str) -> dict:
    """A 256-particle W1 box for LJ_STEPS steps and a 144-particle melting block drawn for FRAMES frames on `arch`:
    energies, positions, the block's readouts, the last picture and the box's launches per step."""
    sim = bench.lj_box_sim(16, arch)
    out = {"arch": runtime.running_arch()}
    e0 = sim.stats().total_energy
    sim.step(LJ_STEPS)
    out["drift"] = (sim.stats().total_energy - e0) / abs(e0)
    out["x"] = sim.positions().tolist()
    with count_launches() as launches:
        sim.step(100)
        ti.sync()
    out["launches_per_step"] = launches.total / 100
    sim = Simulation(load_scene(bench.SCENES / "melting_block.toml", bench.melting_block_of(12)), arch=arch)
    renderer = Renderer(sim.model, sim.state, 320, 180, sim.scene.render)
    for _ in range(FRAMES):
        renderer.begin_frame()
        sim.advance_frame()
    s = sim.stats()
    out["block"] = {
        "mean_temperature": s.mean_temperature,
        "heat_content": s.heat_content,
        "kinetic_energy": s.kinetic_energy,
        "molten_fraction": s.molten_fraction,
        "broken_springs": s.broken_springs,
    }
    out["frame"] = renderer.frame().tolist()
    return out


@pytest.mark.slow  # the Vulkan backend compiles every kernel again
def test_the_gpu_path_on_vulkan_computes_what_the_cpu_computes(tmp_path):
    """Vulkan in a fresh process (a runtime holds one backend) against the CPU here: the box's energy drift and
    positions, the melting block's heat, melt and broken bonds, and the picture. Skips where Vulkan is missing."""
    out = tmp_path / "vulkan.json"
    code = (
        "import json; from tests.test_backends import run_both_workloads as run; "
        f"json.dump(run('vulkan'), open({str(out)!r}, 'w'))"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    gpu = json.loads(out.read_text())
    if gpu["arch"] != "vulkan":
        pytest.skip("no Vulkan driver (Taichi fell back to the CPU): apt-get install mesa-vulkan-drivers libvulkan1")
    cpu = run_both_workloads("cpu")

    assert abs(gpu["drift"]) < 3e-3 and abs(gpu["drift"] - cpu["drift"]) < 2e-4
    assert np.abs(np.array(gpu["x"]) - np.array(cpu["x"])).max() < 1e-2  # f32, 400 steps of a chaotic liquid
    g, c = gpu["block"], cpu["block"]
    assert g["mean_temperature"] == pytest.approx(c["mean_temperature"], rel=1e-5)
    assert g["heat_content"] == pytest.approx(c["heat_content"], rel=1e-5)
    assert g["kinetic_energy"] == pytest.approx(c["kinetic_energy"], rel=1e-3)
    assert g["molten_fraction"] == pytest.approx(c["molten_fraction"], abs=1e-3)
    assert c["molten_fraction"] > 0.1 and c["broken_springs"] > 50  # the block is melting by then
    assert abs(g["broken_springs"] - c["broken_springs"]) <= 2
    diff = np.abs(np.array(gpu["frame"], dtype=int) - np.array(cpu["frame"], dtype=int)).sum(axis=2)
    assert (diff > 40).mean() < 0.002
    # the GPU step: a launch for the step's start (list check, springs), one for rates and update, and a read of
    # the list's staleness when due; the small CPU scene runs whole batches of steps to a launch
    assert 2.0 <= gpu["launches_per_step"] <= 3.0
    assert cpu["launches_per_step"] < 0.1


def test_the_launch_counter_counts_each_kernel_call_and_field_access_once():
    runtime.init("cpu", "f32")
    xs = ti.field(ti.f32, shape=4)
    vs = ti.Vector.field(2, ti.f32, shape=3)

    @ti.kernel
    def fill():
        for i in xs:
            xs[i] = i

    fill()
    with count_launches() as launches:
        fill()
        fill()
        xs[1] = 2.0
        assert xs[1] == 2.0
        vs[0] = [1.0, 2.0]  # a write per component
        assert vs[0][1] == 2.0  # one component read
    fill()  # outside the block: not counted
    assert launches.by_name == {fill.__qualname__: 2, "field write": 3, "field read": 2}
    assert launches.total == 7
