"""`sandbox bench --serve N`: N simulated browser tabs on one classroom server over loopback.

Each client does what the page does: draws nothing, but answers every picture with "ready" at once, and twice a
second moves the air-temperature slider with a sequence number. It reports each session's delivered frame rate, the
input-to-picture latency (from sending a slider move to receiving the first picture drawn after the session applied
it: a particle frame, or the readouts that come with a JPEG picture, echo the last number applied), the slow-motion
factor (simulated seconds per wall second against the scene's own pace), and the server's CPU and memory per
session (psutil); with `--contended K`, the same class measured again beside K CPU-bound processes.
"""

from __future__ import annotations

import asyncio
import json
import os
import secrets
import socket
import statistics
import subprocess
import sys
import time
import urllib.request

from ..errors import SandboxError
from ..render.particle_frame import HEADER, PAGE_FRAMES

WARMUP = 8.0  # seconds after every session has drawn its first picture
MEASURE = 15.0  # seconds measured


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


async def _client(url: str, stop: float, out: dict) -> None:
    """One simulated tab until `stop` (monotonic seconds): answers every picture with "ready" at once, moves a slider
    twice a second; records in `out` when each picture came, each input's latency and the simulated clock."""
    import websockets

    pictures, latencies, clock, seq, sent, acked = [], [], [], 0, {}, 0
    async with websockets.connect(url, max_size=None) as ws:
        next_input = 0.0
        while True:
            now = time.monotonic()
            if now > stop:
                break
            try:
                message = await asyncio.wait_for(ws.recv(), timeout=max(stop - now, 0.01))
            except asyncio.TimeoutError:
                break
            now = time.monotonic()
            if isinstance(message, bytes) and message[:1] in PAGE_FRAMES:  # a frame the page draws carries its clock
                _, _, acked, sim_time, _ = HEADER.unpack_from(message)
                clock.append((now, sim_time))
            if isinstance(message, bytes) and message[:1] in (b"F", *PAGE_FRAMES):  # a picture (not a backdrop or band)
                pictures.append(now)
                if acked in sent:  # the first picture after the session applied input `acked`
                    latencies.append((now, now - sent.pop(acked)))
                if now >= next_input:
                    seq += 1
                    sent[seq] = now
                    next_input = now + 0.5
                    await ws.send(json.dumps({"t": "set", "key": "air", "value": 20.0 + seq % 5, "seq": seq}))
                await ws.send('{"t": "ready"}')
            elif not isinstance(message, bytes):
                info = json.loads(message)
                if info.get("t") == "info":
                    acked = info.get("seq", 0)
                    clock.append((now, info["time"]))
    out.update(pictures=pictures, latencies=latencies, clock=clock)


def bench_serve(
    clients: int, scene: str = "melting_block", draw: str = "page", hogs: int = 0, worlds: bool = True
) -> dict:
    """Run the server with `clients` tabs of `scene` (`draw`: who draws the particles, serve_session.DRAWS; `worlds`
    False: `--no-worlds`, every tab a session of its own) for WARMUP + MEASURE seconds quiet, then (with `hogs`)
    MEASURE more beside that many CPU-bound processes; the figures described in the module docstring, per
    condition."""
    import psutil

    from ..config.resources import shipped_scene
    from ..config.scene import load_scene
    from .peer_bench import CpuHog

    port, teacher = _free_port(), secrets.token_urlsafe(12)
    launched = time.monotonic()
    server = subprocess.Popen(
        [sys.executable, "-m", "sandbox", "serve", scene, "--port", str(port), "--max-sessions", str(clients)]
        + [f"--teacher-token={teacher}", "--draw", draw, "--per-client", "0"]  # "=": a token may begin with "-"
        + ([] if worlds else ["--no-worlds"]),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    windows = []
    try:
        _wait_until_warm(server, port, teacher, clients)  # the class arrives when its sessions are ready
        ready_seconds = time.monotonic() - launched
        url = f"ws://127.0.0.1:{port}/ws?scene={scene}"
        t0 = time.monotonic()
        windows.append(("quiet", t0 + WARMUP, t0 + WARMUP + MEASURE))
        if hogs:
            start = windows[-1][2] + 2.0  # the hogs start between the windows, and settle
            windows.append((f"{hogs} hog{'s' if hogs > 1 else ''}", start, start + MEASURE))
        stop = windows[-1][2]
        results = [{} for _ in range(clients)]

        async def everyone():
            tabs = asyncio.gather(*(_client(url, stop, r) for r in results))
            if not hogs:
                await tabs
                return
            await asyncio.sleep(max(windows[-1][1] - 2.0 - time.monotonic(), 0.0))  # the quiet window is over
            with CpuHog(hogs):
                await tabs

        process = psutil.Process(server.pid)
        samplers = [_Sampler(process, w_start, w_stop) for _, w_start, w_stop in windows]
        for sampler in samplers:
            sampler.start()
        before = os.times()
        asyncio.run(everyone())
        after = os.times()
        for sampler in samplers:
            sampler.join()
    finally:
        server.terminate()
        server.wait(10)
    silent = sum(1 for r in results if not r.get("pictures"))
    if silent:
        raise SandboxError(
            f"serve bench: {silent} of {clients} tabs received no picture; expected every tab to be served (the "
            "machine is too busy, or the server failed)"
        )
    scene_cfg = load_scene(shipped_scene(scene))
    world = scene_cfg.world
    pace = (world.dt * world.substeps if world.substeps != "auto" else world.frame_time) * scene_cfg.render.fps
    conditions = [
        _condition(name, w_start, w_stop, results, sampler, clients, pace)
        for (name, w_start, w_stop), sampler in zip(windows, samplers)
    ]
    return {
        "clients": clients,
        "scene": scene,
        "picture": "frames drawn by the page (where it can)" if draw == "page" else "960 x 540 JPEG",
        "draw": draw,
        "tabs_as": "worlds" if worlds else "sessions",
        "conditions": conditions,
        "ready_seconds": ready_seconds,  # from the server's launch until every tab's session had drawn a picture
        **conditions[0],  # the quiet figures, under their names of old
        # the simulated tabs share the machine with the server: their CPU (over the whole run) is not the server's
        "clients_cpu_percent": 100 * (after.user + after.system - before.user - before.system) / (stop - t0),
    }


def _condition(name, start, stop, results, sampler, clients, pace) -> dict:
    """One measured window's figures over every tab."""
    span = stop - start
    fps = [sum(1 for t in r["pictures"] if start <= t < stop) / span for r in results]
    latencies = [x for r in results for t, x in r["latencies"] if start <= t < stop]
    slow = []
    for r in results:
        clock = [c for t, c in r["clock"] if start <= t < stop]
        slow.append((clock[-1] - clock[0]) / span / pace if len(clock) > 1 else 0.0)
    return {
        "condition": name,
        "fps_per_session": fps,
        "fps_median": statistics.median(fps),
        "latency_median_ms": 1000 * statistics.median(latencies) if latencies else float("nan"),
        "slow_motion": slow,
        "cpu_percent_per_session": sampler.cpu / max(clients, 1),
        "memory_mb_per_session": sampler.memory / max(clients, 1) / 2**20,
        "memory_mb": sampler.memory / 2**20,  # the server's whole: its process and every session's
    }


def _wait_until_warm(server, port: int, teacher: str, clients: int, limit: float = 300.0) -> None:
    """Wait until the server listens and has `clients` sessions started ahead of the tabs (its warm pool); a
    SandboxError when it exits or does not get there within `limit` seconds."""
    url = f"http://127.0.0.1:{port}/api/sessions?teacher={teacher}"
    end = time.monotonic() + limit
    while time.monotonic() < end:
        if server.poll() is not None:
            raise SandboxError(f"serve bench: the server stopped ({_last_line(server.stderr.read())})")
        try:
            if json.loads(urllib.request.urlopen(url, timeout=2).read())["warm"] >= clients:
                return
        except (OSError, ValueError, KeyError):
            pass  # not listening yet
        time.sleep(0.5)
    raise SandboxError(f"serve bench: the server did not start {clients} sessions within {limit:.0f} s")


def _last_line(text: str) -> str:
    lines = [line for line in (text or "").splitlines() if line.strip()]
    return lines[-1] if lines else "no output"


class _Sampler:
    """The server's sessions' CPU (percent of one core) and resident memory, averaged over the measurement."""

    def __init__(self, process, start: float, stop: float):
        import threading

        self.process, self.start_at, self.stop_at = process, start, stop
        self.cpu = self.memory = 0.0
        self.thread = threading.Thread(target=self.run, daemon=True)

    def start(self) -> None:
        self.thread.start()

    def join(self) -> None:
        self.thread.join()

    def run(self) -> None:
        import psutil

        time.sleep(max(self.start_at - time.monotonic(), 0))
        children = self.process.children(recursive=True)
        for child in children:
            child.cpu_percent(None)
        self.process.cpu_percent(None)
        time.sleep(max(self.stop_at - time.monotonic(), 0))
        cpu = memory = 0.0
        for proc in [self.process, *children]:
            try:
                cpu += proc.cpu_percent(None)
                memory += proc.memory_info().rss
            except psutil.Error:
                pass
        self.cpu, self.memory = cpu, memory


def report(result: dict) -> str:
    """The benchmark's lines for the terminal."""
    lines = [
        f"serve: {result['clients']} tabs of {result['scene']} over loopback, {result['picture']}, the tabs as "
        f"{result.get('tabs_as', 'worlds')}",
        f"  ready: every session drew its first picture {result['ready_seconds']:.1f} s after the server started",
    ]
    quiet = result["conditions"][0]
    for condition in result["conditions"]:
        fps = ", ".join(f"{f:.1f}" for f in condition["fps_per_session"])
        slow = statistics.median(condition["slow_motion"])
        lines += [
            f"  {condition['condition']}: pictures per second per session: median {condition['fps_median']:.1f} "
            f"(each: {fps})",
            f"    input-to-picture latency: median {condition['latency_median_ms']:.0f} ms; simulated time at "
            f"{slow:.2f} of the scene's own pace (1: real time as in its video)",
            f"    pace of each tab's scene: {', '.join(f'{x:.2f}' for x in condition['slow_motion'])}",
            f"    server per session: {condition['cpu_percent_per_session']:.0f}% of a core, "
            f"{condition['memory_mb_per_session']:.0f} MB resident; the whole server {condition['memory_mb']:.0f} MB",
        ]
        if condition is not quiet and quiet["fps_median"] > 0:
            lines.append(f"    kept {100 * condition['fps_median'] / quiet['fps_median']:.0f}% of the quiet rate")
    lines.append(f"  the simulated tabs took {result['clients_cpu_percent']:.0f}% of a core")
    return "\n".join(lines)
