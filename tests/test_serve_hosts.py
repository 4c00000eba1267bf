"""Issue 74: a class's sessions live in hosts, a process per scene and core holding many sessions in one Taichi
runtime (serve_host.py), instead of a process per tab. The server's side (serve_slots.py) runs here over stand-in
hosts: which slot a tab gets, that a tab's slot goes back to its scene's pool and is given again, that a tab asking
for another scene moves to that scene's host, and that one session's failure ends only its tab. A real host then
builds two sessions in this process: a session given back and started again for the next tab runs, to the bit, as a
freshly built one does."""

from __future__ import annotations

import asyncio
import json
import os
import time

import numpy as np
import pytest

pytest.importorskip("starlette")

from sandbox.app import serve  # noqa: E402
from sandbox.app.serve import Classroom  # noqa: E402
from sandbox.app.serve_host import HOST, SLOT, Host  # noqa: E402
from sandbox.app.serve_slots import HostProcess  # noqa: E402

pytestmark = pytest.mark.xdist_group("serve")


class Pipe:
    """A host's pipe end as the server sees it: what the server sends, by slot."""

    def __init__(self) -> None:
        self.sent: list[tuple[int, dict]] = []

    def send_bytes(self, data: bytes) -> None:
        (slot,) = SLOT.unpack_from(data)
        self.sent.append((slot, json.loads(data[SLOT.size :])))

    def orders(self, kind: str) -> list[int]:
        """The slots of the host orders of `kind` sent so far."""
        return [m["slot"] if "slot" in m else None for s, m in self.sent if s == HOST and m["t"] == kind]

    def fileno(self) -> int:
        return -1

    def close(self) -> None:
        pass


class Process:
    def __init__(self) -> None:
        self.alive = True

    def is_alive(self) -> bool:
        return self.alive

    def terminate(self) -> None:
        self.alive = False

    def join(self, timeout=None) -> None:
        pass


def stand_in_hosts(classroom: Classroom) -> list[HostProcess]:
    """Make `classroom` start stand-in hosts (no process); returns the list they are added to."""
    started = []

    def start(scene: str) -> HostProcess:
        host = HostProcess(scene, Process(), Pipe(), classroom.hosts.per_host)
        classroom.hosts.hosts.append(host)
        started.append(host)
        return host

    classroom.hosts.start = start
    return started


def built(classroom: Classroom, host: HostProcess, *slots: int) -> None:
    for slot in slots:
        classroom.host_said(host, {"t": "built", "slot": slot})


def warm_for(classroom: Classroom, seconds: float) -> None:
    async def run():
        task = asyncio.create_task(classroom.keep_warm())
        await asyncio.sleep(seconds)
        task.cancel()

    asyncio.run(run())


def test_the_warm_pool_builds_in_a_host_per_core_side_by_side(monkeypatch):
    """A class's sessions are built ahead of the tabs, one at a time in each host and as many hosts at once as the
    machine has cores; a host holds max_sessions / cores of them, so the class fills every core and no more."""
    monkeypatch.setattr(serve, "usable_cores", lambda: 2)
    classroom = Classroom("melting_block", None, max_sessions=6)
    hosts = stand_in_hosts(classroom)
    warm_for(classroom, 0.6)
    assert len(hosts) == 2 and [h.conn.orders("grow") for h in hosts] == [[None], [None]]
    assert classroom.hosts.per_host == 3 and classroom.ready() == 0
    built(classroom, hosts[0], 0)
    built(classroom, hosts[1], 0)
    assert classroom.ready() == 2
    warm_for(classroom, 0.6)  # the next two in those hosts, side by side, and no third host
    assert len(hosts) == 2 and [len(h.slots) for h in hosts] == [2, 2]
    built(classroom, hosts[0], 1)
    built(classroom, hosts[1], 1)
    warm_for(classroom, 1.0)
    built(classroom, hosts[0], 2)
    built(classroom, hosts[1], 2)
    warm_for(classroom, 0.6)
    assert classroom.ready() == 6 and classroom.hosts.slots() == 6 and len(hosts) == 2  # full: nothing more


def test_a_host_that_builds_faster_does_not_make_the_pool_start_a_third_host(monkeypatch):
    """Issue 74 (seen in `sandbox bench --serve 30`: a third host holding one tab): where one host has built its
    share while the other is still building, the last slots queue in the host with room; no host is started only to
    build beside a busy one once the scene has a host per core."""
    monkeypatch.setattr(serve, "usable_cores", lambda: 2)
    classroom = Classroom("melting_block", None, max_sessions=6)
    hosts = stand_in_hosts(classroom)
    warm_for(classroom, 0.6)
    built(classroom, hosts[0], 0)
    warm_for(classroom, 0.6)
    built(classroom, hosts[0], 1)
    warm_for(classroom, 0.6)
    built(classroom, hosts[0], 2)  # the first host is full; the second is still building its first session
    warm_for(classroom, 0.6)
    assert len(hosts) == 2 and [len(h.slots) for h in hosts] == [3, 2]  # the next one queued behind its build
    built(classroom, hosts[1], 0)
    warm_for(classroom, 0.6)
    assert len(hosts) == 2 and [len(h.slots) for h in hosts] == [3, 3]


def test_hosts_are_pinned_a_core_each_in_turn(monkeypatch):
    """A host is one always-busy thread: each goes to the core the fewest hosts have (so another busy program shares
    a core with one host, not a core to itself beside two hosts on the other); none where pinning is off or the
    process has one core."""
    from sandbox.app import serve_slots
    from sandbox.core import cores

    assert serve_slots.next_core([0, 1], []) == 0
    assert serve_slots.next_core([0, 1], [0]) == 1
    assert serve_slots.next_core([0, 1], [0, 1]) == 0
    assert serve_slots.next_core([2, 5, 7], [2, 5, 2, None]) == 7
    assert serve_slots.next_core([], [0]) is None
    monkeypatch.setattr(cores.os, "sched_getaffinity", lambda pid: {3, 1}, raising=False)
    assert cores.pinnable_cores() == [1, 3]
    monkeypatch.setenv("SANDBOX_PIN_THREADS", "0")
    assert cores.pinnable_cores() == []
    monkeypatch.delenv("SANDBOX_PIN_THREADS")
    monkeypatch.setattr(cores.os, "sched_getaffinity", lambda pid: {4}, raising=False)
    assert cores.pinnable_cores() == []


def test_pinned_hosts_turn_to_the_next_core_together_and_never_meet(monkeypatch):
    """Every ROTATE_SECONDS each host moves to the next core, all at the same moments: hosts that started on
    different cores are always on different cores, and each spends its turn on every core (a busy program beside the
    class slows every host's tabs alike)."""
    from sandbox.app import serve_host

    now, pinned = [100.2], []
    monkeypatch.setattr(serve_host.time, "time", lambda: now[0])
    monkeypatch.setattr(serve_host.os, "sched_setaffinity", lambda pid, cores: pinned.append(set(cores)), raising=False)
    hosts = [serve_host.Pinning(core, (0, 1, 2)) for core in (0, 1, 2)]
    seen = []
    for second in range(3):
        now[0] = 100.2 + second * serve_host.ROTATE_SECONDS
        pinned.clear()
        for host in hosts:
            host.pin()
            host.pin()  # again within the turn: nothing
        assert len(pinned) == 3 and set().union(*pinned) == {0, 1, 2}  # three hosts on three cores
        seen.append([next(iter(c)) for c in pinned])
    assert [sorted(turns) for turns in zip(*seen)] == [[0, 1, 2]] * 3  # each host on every core in turn
    serve_host.Pinning(None, (0, 1)).pin()
    serve_host.Pinning(5, (0, 1)).pin()  # a core no longer its own: left to the scheduler
    assert len(pinned) == 3


def test_an_ended_host_is_waited_for_by_a_thread_not_by_the_server(monkeypatch):
    """An ended host leaves the normal way, writing its kernels to Taichi's cache: the server's loop must not wait
    for that (every tab's frames would stall), so a thread does, and kills a host that takes over LEAVE_SECONDS."""
    from sandbox.app import serve_slots

    monkeypatch.setattr(serve_slots, "LEAVE_SECONDS", 0.3)

    class Slow(Process):
        killed = False

        def join(self, timeout=None) -> None:
            time.sleep(timeout or 0)

        def is_alive(self) -> bool:
            return not self.killed

        def kill(self) -> None:
            self.killed = True

    hosts = serve_slots.Hosts(None, (16, 9), 30.0, "page", 2, None, 1)
    host = HostProcess("melting_block", Slow(), Pipe(), 2)
    hosts.hosts.append(host)
    start = time.perf_counter()
    reaper = hosts.end(host)
    assert time.perf_counter() - start < 0.1 and host not in hosts.hosts
    reaper.join(5)
    assert host.process.killed


def test_a_tab_takes_a_built_session_and_gives_it_back_for_the_next_tab():
    """A tab gets a built session at once (started again for it: "attach"), with nothing built anew; when it
    leaves, the session goes back to the pool ("detach") and the next tab gets the same one. What a tab says while
    its session is being built waits, in order, and reaches the session once it is built and given to it."""
    classroom = Classroom("melting_block", None, max_sessions=4, per_host=2)
    hosts = stand_in_hosts(classroom)
    first = classroom.open("melting_block")  # nothing built yet: a host is started and asked for one
    assert len(hosts) == 1 and hosts[0].conn.orders("grow") == [None] and not first.link.built
    first.send({"t": "ready"})
    first.send({"t": "action", "name": "pause"})
    assert not any(s != HOST for s, _ in hosts[0].conn.sent)  # kept until the session is built
    built(classroom, hosts[0], 0)
    pipe = hosts[0].conn
    assert pipe.orders("attach") == [0]
    assert [m for s, m in pipe.sent if s == 0] == [{"t": "ready"}, {"t": "action", "name": "pause"}]
    slot = first.link
    classroom.close(first)
    assert pipe.orders("detach") == [0] and classroom.ready() == 1 and first.link is None
    second = classroom.open("melting_block")
    assert second.link is slot and second.link.built and pipe.orders("attach") == [0, 0]
    assert pipe.orders("grow") == [None]  # nothing was built for the second tab
    second.send({"t": "ready"})
    assert pipe.sent[-1] == (0, {"t": "ready"})


def test_a_tab_that_asks_for_another_scene_moves_to_that_scenes_host():
    """A host's sessions never switch scenes: the tab's session goes back to its pool and the tab gets one of the
    scene it asked for, in a host of that scene; what the old session still sends no longer reaches the tab; a
    host no tab uses ends (its memory with it) unless the warm pool needs it."""
    classroom = Classroom("melting_block", None, max_sessions=4, warm=1, per_host=2)
    hosts = stand_in_hosts(classroom)
    handle = classroom.open("melting_block")
    built(classroom, hosts[0], 0)
    classroom.move(handle, "lj_box")
    assert hosts[0].conn.orders("detach") == [0]
    assert len(hosts) == 2 and hosts[1].scene == "lj_box" and handle.link.host is hosts[1] and handle.scene == "lj_box"
    old = hosts[0].slots[0]
    assert old.handle is None  # the old session's last pictures are for nobody now
    built(classroom, hosts[1], 0)
    assert hosts[1].conn.orders("attach") == [0]
    classroom.move(handle, "melting_block")  # back: the free built session of the default scene, at once
    assert handle.link is old and hosts[0].conn.orders("attach") == [0, 0]
    warm_for(classroom, 0.6)
    assert hosts[1] not in classroom.hosts.hosts and not hosts[1].process.alive  # lj_box's host: nobody's
    assert hosts[0] in classroom.hosts.hosts  # the default scene's, a tab's


def test_one_sessions_failure_ends_only_its_tab(monkeypatch):
    """A session that fails in a host (an error in its step or its message) is said to its tab, which is closed,
    and is never given again; the host's other tabs run on. A host whose process ends tells each of its tabs."""
    monkeypatch.setattr(serve, "usable_cores", lambda: 1)  # one host builds them all
    classroom = Classroom("melting_block", None, max_sessions=4, per_host=4)
    hosts = stand_in_hosts(classroom)
    a, b = classroom.open("melting_block"), classroom.open("melting_block")
    built(classroom, hosts[0], 0, 1)
    classroom.host_said(hosts[0], {"t": "ended", "slot": 0, "text": "RuntimeError: boom"})
    said = json.loads(a.outbox.get_nowait()[1])
    assert said["key"] == "session_ended" and a.outbox.get_nowait() is None
    assert a.sid not in classroom.sessions and b.sid in classroom.sessions
    c = classroom.open("melting_block")
    assert c.link is not a.link and c.link.index == 2  # the failed one is not given again
    classroom.host_ended(hosts[0])
    assert json.loads(b.outbox.get_nowait()[1])["key"] == "session_ended" and not classroom.sessions


class Collect:
    """A host's pipe end as the host sees it: what its sessions and itself send."""

    def __init__(self) -> None:
        self.sent: list[tuple[int, bytes]] = []

    def send_bytes(self, data: bytes) -> None:
        (slot,) = SLOT.unpack_from(data)
        self.sent.append((slot, data[SLOT.size :]))

    def said(self) -> list[dict]:
        return [json.loads(b[1:]) for s, b in self.sent if s == HOST]


def order(host: Host, slot: int, message: dict) -> None:
    host.receive(SLOT.pack(slot) + json.dumps(message).encode())


def run_frames(control, frames: int) -> dict:
    """`frames` frames of the scene's own steps each (the pacer's would follow this machine's speed) through
    `control` (a session's, or a lone simulation's controller); what they leave."""
    for _ in range(frames):
        control.advance(int(control.sim.scene.world.substeps))
    sim = control.sim
    n = sim.state.live_count()
    p = sim.particles
    return {
        "x": p.x.to_numpy()[:n],
        "v": p.v.to_numpy()[:n],
        "T": p.T.to_numpy()[:n] if hasattr(p, "T") else None,  # where the scene has heat
        "time": sim.time,
        "controls": sim.controls.values(),
    }


STROKES = ("heat", "impulse", "drag")  # a tool each scene below has, held where the tab presses


@pytest.mark.parametrize(
    "scene",
    [
        pytest.param("melting_block", marks=pytest.mark.long),  # the classroom's default holds it as worlds now
        pytest.param("lj_box", marks=pytest.mark.long),  # periodic
        pytest.param("atoms", marks=pytest.mark.long),  # molecular
        pytest.param("candle", marks=pytest.mark.long),  # an emitter
    ],
)
def test_a_session_given_back_starts_again_as_the_scene_run_alone_to_the_bit(scene):
    """Two sessions built in one host share its runtime and canvas. A tab uses the first: every slider moved, a
    tool held, frames stepped. The tab leaves and the next one gets that session: its scene, settings, clock and
    trajectory are those of the second, never used, session and of the scene run alone, bit for bit."""
    from sandbox.app.controller import Controller, open_scene

    conn = Collect()
    host = Host(conn, scene, 160, 90, 30.0, "page")
    order(host, HOST, {"t": "grow"})
    order(host, HOST, {"t": "grow"})
    assert host.sessions[0].sim.model is not host.sessions[1].sim.model
    assert [m["t"] for m in conn.said()] == ["built", "built"] and not [s for s, _ in conn.sent if s != HOST]
    order(host, HOST, {"t": "attach", "slot": 0})
    said = [json.loads(b[1:]) for s, b in conn.sent if s == 0 and b[:1] == b"J"]
    assert said[0]["t"] == "scene" and said[0]["scene"] == scene
    used = host.sessions[0]
    for setting in used.control.settings():
        order(host, 0, {"t": "set", "key": setting.key, "value": setting.lo + 0.7 * (setting.hi - setting.lo)})
    tool = next(t for t in STROKES if t in used.tool_names())
    order(host, 0, {"t": "tool", "tool": tool, "x": 0.5, "y": 0.6, "radius": 1.0, "down": True})
    run_frames(used.control, 12)
    order(host, HOST, {"t": "detach", "slot": 0})
    sent = len(conn.sent)
    order(host, 0, {"t": "action", "name": "pause"})  # a tab that has left is not heard
    assert not used.control.paused and len(conn.sent) == sent
    order(host, HOST, {"t": "attach", "slot": 0})
    order(host, HOST, {"t": "attach", "slot": 1})
    lone = Controller(open_scene(scene, restart=False))
    again, fresh, alone = (run_frames(c, 20) for c in (used.control, host.sessions[1].control, lone))
    assert again["time"] == fresh["time"] == alone["time"] > 0
    assert again["controls"] == fresh["controls"] == alone["controls"]
    for key in ("x", "v", "T"):
        assert np.array_equal(again[key], fresh[key]) and np.array_equal(again[key], alone[key]), key
    assert len(again["x"]) > 0


@pytest.mark.long
def test_what_one_tab_does_changes_nothing_in_another_session_of_its_host(tmp_path):
    """Two tabs on sessions of one host, stepped in turn: one moves every slider, holds a tool, undoes it and loads a
    saved state; the other tab's scene runs on, to the bit, as the scene run alone."""
    from sandbox.app.controller import Controller, open_scene

    conn = Collect()
    host = Host(conn, "melting_block", 160, 90, 30.0, "page")
    order(host, HOST, {"t": "grow"})
    order(host, HOST, {"t": "grow"})
    order(host, HOST, {"t": "attach", "slot": 0})
    order(host, HOST, {"t": "attach", "slot": 1})
    busy, quiet = host.sessions
    lone = Controller(open_scene("melting_block", restart=False))
    saved = lone.save(tmp_path / "saved.npz")  # the scene at its start, for the busy tab to load
    for frame in range(14):
        if frame == 2:
            for setting in busy.control.settings():
                order(host, 0, {"t": "set", "key": setting.key, "value": setting.hi})
        if frame == 4:
            order(host, 0, {"t": "tool", "tool": "heat", "x": 0.5, "y": 0.4, "radius": 1.0, "down": True})
        if frame == 6:
            order(host, 0, {"t": "tool", "tool": "heat", "x": 0.5, "y": 0.4, "radius": 1.0, "down": False})
            order(host, 0, {"t": "action", "name": "undo"})
        if frame == 9:
            order(host, 0, {"t": "upload", "path": str(saved)})
        for control in (busy.control, quiet.control, lone):
            run_frames(control, 1)
    busy_said = [json.loads(b[1:]) for s, b in conn.sent if s == 0 and b[:1] == b"J"]
    assert any(m.get("key") == "uploaded" for m in busy_said), busy_said  # the busy tab did all that
    assert busy.control.settings() != quiet.control.settings() or busy.sim.time != quiet.sim.time
    alone, other = run_frames(lone, 0), run_frames(quiet.control, 0)
    assert other["time"] == alone["time"] > 0 and other["controls"] == alone["controls"]
    for key in ("x", "v", "T"):
        assert np.array_equal(other[key], alone[key]), key


@pytest.mark.long  # a host of sessions (melting_block's class runs as worlds now): `python3 -m pytest -m long`
@pytest.mark.parametrize("scene", ["melting_block", "melting_block_3d"])
def test_a_hosts_sessions_share_one_canvas_and_each_picture_is_its_own(scene):
    """A host's sessions draw in one canvas (17 MB each at 960 x 540 saved): a session's picture drawn after
    another session drew a different state (its heat source hotter, wax spawned where the first has nothing), and
    after whatever else was drawn there, is to the byte the picture it drew before, and not the other's."""
    host = Host(Collect(), scene, 160, 90, 30.0, "server")
    order(host, HOST, {"t": "grow"})
    order(host, HOST, {"t": "grow"})
    a, b = host.sessions
    assert a.renderer.canvas is b.renderer.canvas and a.renderer.canvas.shared
    order(host, HOST, {"t": "attach", "slot": 0})
    order(host, HOST, {"t": "attach", "slot": 1})
    hotter = next(s for s in b.control.settings() if s.key.startswith("source"))
    order(host, 1, {"t": "set", "key": hotter.key, "value": hotter.hi})
    run_frames(a.control, 6)
    if scene == "melting_block":  # wax where the other's picture has none (3D: the tool acts on a particle)
        spawn = {"t": "tool", "tool": "spawn", "x": 0.15, "y": 0.3, "radius": 0.5, "down": True, "material": "wax"}
        order(host, 1, spawn)
    run_frames(b.control, 6)
    first = a.renderer.frame().copy()
    other = b.renderer.frame().copy()
    a.renderer.canvas.out[:] = 0  # ... and where a third session drew over every pixel of it
    again = a.renderer.frame().copy()
    assert np.array_equal(first, again) and not np.array_equal(first, other)


def test_when_the_teacher_sends_a_scene_the_class_builds_it_on_every_core(monkeypatch):
    """Every tab moves to a session of the scene sent: they are built in as many new hosts at once as there are
    cores, not one after another in one host; a tab whose session waits behind others' builds is not given up at
    START_SECONDS (it is, once built, if it draws nothing by then)."""
    monkeypatch.setattr(serve, "usable_cores", lambda: 2)
    classroom = Classroom("melting_block", None, max_sessions=6, warm=0)
    hosts = stand_in_hosts(classroom)
    tabs = [classroom.open("melting_block") for _ in range(4)]
    assert len(hosts) == 2  # even the first tabs' sessions build side by side
    for host in hosts:
        built(classroom, host, *range(len(host.slots)))
    for tab in tabs:
        classroom.move(tab, "lj_box")
    boxes = [h for h in hosts if h.scene == "lj_box"]
    assert len(boxes) == 2 and sorted(len(h.slots) for h in boxes) == [2, 2]
    waiting = next(t for t in tabs if not t.link.built)
    waiting.started -= serve.START_SECONDS + 5

    async def reap_once():
        reaper = asyncio.create_task(classroom.reap_idle())
        await asyncio.sleep(0.1)
        reaper.cancel()

    classroom.idle = 0.2
    for tab in tabs:
        tab.last_seen = time.monotonic() + 60  # not idle
    asyncio.run(reap_once())
    assert waiting.sid in classroom.sessions  # still building: waits on
    built(classroom, waiting.link.host, waiting.link.index)
    waiting.started -= serve.START_SECONDS + 5  # built, and no picture since
    asyncio.run(reap_once())
    assert waiting.sid not in classroom.sessions
    assert json.loads(waiting.outbox.get_nowait()[1])["key"] == "start_failed"


@pytest.mark.long
def test_a_host_the_server_ends_leaves_its_kernels_in_taichis_cache(tmp_path, monkeypatch):
    """Ended by the server (SIGTERM), a host leaves the normal way and Taichi writes the kernels it compiled to its
    offline cache, which the next class on the machine reads instead of compiling (killed, it wrote nothing)."""
    import multiprocessing

    from sandbox.app.serve_host import host_main

    cache = tmp_path / "cache"
    monkeypatch.setenv("TI_OFFLINE_CACHE_FILE_PATH", str(cache))
    context = multiprocessing.get_context("spawn")
    parent, child = context.Pipe()
    core = max(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None
    pinned = (core,) if core is not None else ()
    process = context.Process(target=host_main, args=(child, "melting_block", 320, 180, 30.0, "page", core, pinned))
    process.daemon = True
    process.start()
    child.close()
    parent.send_bytes(SLOT.pack(HOST) + json.dumps({"t": "grow"}).encode())
    said = []
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and not any(m.get("t") in ("built", "failed") for m in said):
        if parent.poll(1):
            data = parent.recv_bytes()
            if SLOT.unpack_from(data)[0] == HOST:
                said.append(json.loads(data[SLOT.size + 1 :]))
    assert said and said[-1] == {"t": "built", "slot": 0}, said
    if core is not None:
        assert os.sched_getaffinity(process.pid) == {core}  # pinned as the server asked
    process.terminate()
    process.join(60)
    assert process.exitcode == 0
    assert sum(f.stat().st_size for f in cache.rglob("*") if f.is_file()) > 100_000  # the session's kernels


def test_a_glowing_emitter_scenes_session_compiles_in_its_warm_up_not_in_the_class(compiled_kernels):
    """Fireworks starts empty: its spawning, retiring and the frames' packing compiled at the first burst, in the
    class, while the host's other tabs waited (a fireworks host's tabs stalled 0.7 s). The warm-up now runs the scene
    until its emitters have added and retired particles; the tab's frames then compile nothing."""
    conn = Collect()
    host = Host(conn, "fireworks", 160, 90, 30.0, "page")
    order(host, HOST, {"t": "grow"})
    order(host, HOST, {"t": "attach", "slot": 0})
    session = host.sessions[0]
    before = len(compiled_kernels)
    now = due = 0.0
    counts = set()
    for _ in range(90):  # three seconds of the scene: bursts, sparks fading and retired
        session.handle({"t": "ready"})
        due = session.tick(now, due)
        counts.add(session.sim.state.live_count())
        now += session.interval
    assert len(counts) > 10 and compiled_kernels[before:] == []


@pytest.mark.skipif(not os.path.exists("/proc/self/status"), reason="reads a process's signal mask from /proc")
def test_a_host_process_starts_with_ctrl_c_ignored_and_the_server_keeps_its_own():
    """Ctrl-C reaches the server's whole process group; a host still importing took it as a KeyboardInterrupt and
    printed a traceback (the clean-clone run's flood test). A host now starts with SIGINT ignored, and the server's
    own handler is as it was."""
    import multiprocessing
    import signal

    from sandbox.app.serve_slots import _keyboard_interrupt_ignored

    before = signal.getsignal(signal.SIGINT)
    with _keyboard_interrupt_ignored():
        process = multiprocessing.get_context("spawn").Process(target=time.sleep, args=(30,), daemon=True)
        process.start()
    try:
        with open(f"/proc/{process.pid}/status") as status:
            ignored = int(next(line for line in status if line.startswith("SigIgn:")).split()[1], 16)
        assert ignored & (1 << (signal.SIGINT - 1))
        assert signal.getsignal(signal.SIGINT) is before
    finally:
        process.kill()
        process.join()
