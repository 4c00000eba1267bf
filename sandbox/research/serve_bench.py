"""`sandbox bench --serve N`: N simulated browser tabs on one classroom server over loopback.

Each client does what the page does: draws nothing, but answers every picture with "ready" at once, and twice a
second moves the air-temperature slider with a sequence number. It reports each session's delivered frame rate, the
input-to-picture latency (from sending a slider move to receiving the first picture drawn after the session applied
it: the readouts that come with each picture echo the last number applied), the slow-motion factor (simulated
seconds per wall second against the scene's own pace), and the server's CPU and memory per session (psutil).
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

WARMUP = 8.0  # seconds after every session has drawn its first picture
MEASURE = 15.0  # seconds measured


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


async def _client(url: str, start: float, stop: float, out: dict) -> None:
    import websockets

    frames, latencies, seq, sent, acked = 0, [], 0, {}, 0
    times: list[float] = []
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
            if isinstance(message, bytes):
                if start <= now:
                    frames += 1
                    if acked in sent:  # the first picture after the session applied input `acked`
                        latencies.append(now - sent.pop(acked))
                    if now >= next_input:
                        seq += 1
                        sent[seq] = now
                        next_input = now + 0.5
                        await ws.send(json.dumps({"t": "set", "key": "air", "value": 20.0 + seq % 5, "seq": seq}))
                await ws.send('{"t": "ready"}')
            else:
                info = json.loads(message)
                if info.get("t") == "info":
                    acked = info.get("seq", 0)
                    if start <= now:
                        times.append(info["time"])
    out.update(frames=frames, latencies=latencies, sim_seconds=(times[-1] - times[0]) if len(times) > 1 else 0.0)


def bench_serve(clients: int, scene: str = "melting_block") -> dict:
    """Run the server with `clients` tabs of `scene` for WARMUP + MEASURE seconds; the figures described above."""
    import psutil

    from ..config.resources import shipped_scene
    from ..config.scene import load_scene

    port, teacher = _free_port(), secrets.token_urlsafe(12)
    server = subprocess.Popen(
        [sys.executable, "-m", "sandbox", "serve", scene, "--port", str(port), "--max-sessions", str(clients)]
        + ["--teacher-token", teacher],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        _wait_until_warm(server, port, teacher, clients)  # the class arrives when its sessions are ready
        url = f"ws://127.0.0.1:{port}/ws?scene={scene}"
        t0 = time.monotonic()
        start = t0 + WARMUP
        stop = start + MEASURE
        results = [{} for _ in range(clients)]

        async def everyone():
            await asyncio.gather(*(_client(url, start, stop, r) for r in results))

        sampler = _Sampler(psutil.Process(server.pid), start, stop)
        sampler.start()
        before = os.times()
        asyncio.run(everyone())
        after = os.times()
        sampler.join()
    finally:
        server.terminate()
        server.wait(10)
    silent = sum(1 for r in results if not r.get("frames"))
    if silent:
        raise SandboxError(
            f"serve bench: {silent} of {clients} tabs received no picture in {MEASURE:.0f} s; expected every tab to "
            "be served (the machine is too busy, or the server failed)"
        )
    scene_cfg = load_scene(shipped_scene(scene))
    world = scene_cfg.world
    pace = (world.dt * world.substeps if world.substeps != "auto" else world.frame_time) * scene_cfg.render.fps
    fps = [r.get("frames", 0) / MEASURE for r in results]
    latencies = [x for r in results for x in r.get("latencies", [])]
    return {
        "clients": clients,
        "scene": scene,
        "picture": "960 x 540 JPEG",
        "fps_per_session": fps,
        "fps_median": statistics.median(fps) if fps else 0.0,
        "latency_median_ms": 1000 * statistics.median(latencies) if latencies else float("nan"),
        "slow_motion": [r.get("sim_seconds", 0.0) / MEASURE / pace for r in results],
        "cpu_percent_per_session": sampler.cpu / max(clients, 1),
        "memory_mb_per_session": sampler.memory / max(clients, 1) / 2**20,
        # the simulated tabs share the machine with the server: their CPU (over the whole run) is not the server's
        "clients_cpu_percent": 100 * (after.user + after.system - before.user - before.system) / (stop - t0),
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
    fps = ", ".join(f"{f:.1f}" for f in result["fps_per_session"])
    slow = statistics.median(result["slow_motion"]) if result["slow_motion"] else float("nan")
    return "\n".join(
        [
            f"serve: {result['clients']} sessions of {result['scene']} over loopback, {result['picture']} pictures",
            f"  frames per second per session: median {result['fps_median']:.1f} (each: {fps})",
            f"  input-to-picture latency: median {result['latency_median_ms']:.0f} ms",
            f"  simulated time runs at {slow:.2f} of the scene's own pace (1: real time as in its video)",
            f"  server per session: {result['cpu_percent_per_session']:.0f}% of a core, "
            f"{result['memory_mb_per_session']:.0f} MB resident; the simulated tabs took "
            f"{result['clients_cpu_percent']:.0f}% of a core",
        ]
    )
