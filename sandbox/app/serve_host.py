"""A classroom host: one process that holds many tabs' sessions of one scene in one Taichi runtime, so that a class
does not pay a runtime per tab (about 110 MB and the kernels' compilation each, docs/classroom.md). The server
(serve.py) starts a host per scene in use and core, and talks to it over one pipe; every message carries the
index of the session it is for (its *slot*) in two bytes before it, HOST for the host's own:

- server to host: HOST + {"t": "grow"} builds one more session (its kernels compiled: Session.warm_up, unseen),
  answered HOST + {"t": "built", "slot": k} (or "failed" with the line why); HOST + {"t": "attach", "slot": k} gives
  session k to a tab (its scene as it opens, serve_session.Session.restart, then frames by its clock); HOST +
  {"t": "detach", "slot": k} takes it back (silent and still until the next tab); slot + a page's message (already
  checked by serve_protocol.py) is that session's.
- host to server: slot + what the session would send its tab (pictures, b"J" + JSON); HOST + b"J" + {"t":
  "ended", "slot": k, "text": ...} where a session failed (it is not used again; the others run on).

The host steps each attached session on its own clock, in turn (serve_session.Session.tick): where the host is
short of CPU every session slows alike, and a tab that asks for few pictures keeps its scene's pace. A host's
sessions never switch scenes: the server moves a tab that asks for another scene to that scene's host.

Ended (the server's SIGTERM, or its pipe closed) a host leaves the normal way, so Taichi writes the kernels it
compiled to its offline cache: a host's sessions compile the same kernels in the same order every time, so the next
class on the machine finds them there (a melting_block session ready in 0.7 s of a core instead of 2.5). Hosts keep
a cache of their own (CLASSROOM_CACHE), which other Taichi work cannot crowd out of the 100 MB Taichi keeps.
"""

from __future__ import annotations

import contextlib
import functools
import json
import math
import os
import signal
import sys
import time
from pathlib import Path

from .pacing import Turns
from .serve_pipe import HOST, SLOT, SlotConn
from .serve_session import MAX_FPS, SMOOTH_FPS, Session

# Taichi's offline cache for hosts where TI_OFFLINE_CACHE_FILE_PATH is not set: a class of 30 melting_block tabs
# compiles about 11 MB of kernels; many scenes' worth fit in CLASSROOM_CACHE_BYTES
CLASSROOM_CACHE = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "taichi-sandbox-classroom"
CLASSROOM_CACHE_BYTES = 512 << 20
ROTATE_SECONDS = 1.0  # how long a host stays on one core before the next (Pinning)


def host_main(
    conn,
    scene: str,
    width: int,
    height: int,
    max_fps: float = MAX_FPS,
    draw: str = "page",
    core: int | None = None,
    cores: tuple[int, ...] = (),
    worlds: int = 0,
) -> None:
    """Hold the sessions of the shipped scene `scene` the server asks for (module docstring), with `width` x
    `height` pictures at most `max_fps` a second, until the server closes the pipe. One Taichi thread: the server
    starts a host per core, and pins it to `core` of `cores`, the next one every ROTATE_SECONDS (Pinning).
    `worlds` > 0: hold up to that many tabs as the worlds of one simulation (serve_worlds.py), or, where the scene
    cannot run as worlds, sessions (the "built" answers say which)."""
    pinning = Pinning(core, cores)
    pinning.pin()
    os.environ.setdefault("SANDBOX_CPU_THREADS", "1")  # measured: two one-thread batches of 15 worlds step 1.5x
    # the particles a second of one two-thread batch of 30 (a small scene's step does not share well between threads)
    os.environ.setdefault("TI_LOG_LEVEL", "error")
    os.environ.setdefault("TI_OFFLINE_CACHE_FILE_PATH", str(CLASSROOM_CACHE))
    os.environ.setdefault("TI_OFFLINE_CACHE_MAX_SIZE_OF_FILES", str(CLASSROOM_CACHE_BYTES))
    signal.signal(signal.SIGTERM, _leave)  # ended by the server: leave the normal way (module docstring)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the server's whole process group: the server ends
    # its hosts itself (a host that took it while importing printed a traceback)
    from ..core import runtime

    runtime.own_process()  # the sandbox's own process: kernels compile the lighter way (a host compiles many)
    try:
        host = _world_host(conn, scene, width, height, max_fps, worlds, pinning) if worlds > 0 else None
        if host is None:
            host = Host(conn, scene, width, height, max_fps, draw, pinning)
        host.loop()
    except (EOFError, BrokenPipeError, KeyboardInterrupt):
        pass


def _world_host(conn, scene: str, width: int, height: int, max_fps: float, worlds: int, pinning: Pinning):
    """A WorldHost of `worlds` tabs, or None where the scene cannot run as worlds or be drawn by the page (Taichi
    is started again for a host of sessions)."""
    from ..core import runtime
    from ..errors import SandboxError
    from .serve_worlds import WorldHost

    try:
        return WorldHost(conn, scene, width, height, max_fps, worlds, pinning)
    except SandboxError:
        runtime.reset()
        return None


class Pinning:
    """Which core a host runs on (serve_slots.Hosts says why hosts are pinned): `core` of `cores` at first, then
    every ROTATE_SECONDS of the wall clock the next of `cores`. Every host turns at the same moments, so hosts that
    start on different cores stay on different cores, and a busy program beside the class shares each host's core in
    turn, not one host's (whose tabs then ran at half the others' pace)."""

    def __init__(self, core: int | None, cores: tuple[int, ...]) -> None:
        self.cores = tuple(cores) if core in cores else ()
        self.first = self.cores.index(core) if self.cores else 0
        self.turn = None

    def pin(self) -> None:
        """Pin this process to its core of now (nothing where it is not pinned, or where its core has gone)."""
        if not self.cores:
            return
        turn = int(time.time() // ROTATE_SECONDS)
        if turn != self.turn:
            self.turn = turn
            with contextlib.suppress(OSError):  # a core taken away since: the scheduler places the host
                os.sched_setaffinity(0, {self.cores[(self.first + turn) % len(self.cores)]})


def _leave(_signum, _frame) -> None:
    """SIGTERM: exit as at the end of the program (Taichi writes its compiled kernels to its cache as it stops)."""
    sys.exit(0)


class Host:
    """The sessions of one scene in one process (module docstring)."""

    def __init__(
        self,
        conn,
        scene: str,
        width: int,
        height: int,
        max_fps: float,
        draw: str,
        pinning: Pinning | None = None,
    ) -> None:
        self.conn, self.scene, self.size, self.max_fps, self.draw = conn, scene, (width, height), max_fps, draw
        self.pinning = pinning or Pinning(None, ())
        self.sessions: list[Session | None] = []  # by slot; None where one failed
        self.due: dict[int, float] = {}  # attached slots: when each one's next frame is due (perf_counter s)
        self.canvas = None  # the picture canvas every session of the host draws in (Renderer's `canvas`)
        self.turns = Turns(SMOOTH_FPS)  # the steps a frame may take where its sessions' turns would be too long

    def loop(self) -> None:
        """Messages first, then every due session's frame, in turn; then wait for the next due frame or message."""
        while True:
            if self.due:  # turning while the warm pool builds made every class 5 s slower to be ready
                self.pinning.pin()
            while self.conn.poll(0):
                self.receive(self.conn.recv_bytes())
            for slot in list(self.due):
                due = self.due.get(slot)
                if due is not None and due <= time.perf_counter():
                    self.guarded(slot, functools.partial(self.tick, slot, due))
            upcoming = min(self.due.values(), default=math.inf)
            wait = min(upcoming - time.perf_counter(), 1.0)
            if wait > 0:
                self.conn.poll(wait)

    def tick(self, slot: int, due: float, session: Session) -> None:
        self.due[slot] = session.tick(time.perf_counter(), due)

    def receive(self, data: bytes) -> None:
        (slot,) = SLOT.unpack_from(data)
        message = json.loads(data[SLOT.size :])
        if slot != HOST:
            if slot in self.due:  # a detached session hears nothing from a tab that has left
                self.guarded(slot, lambda s: s.handle(message))
            return
        kind = message["t"]
        if kind == "grow":
            self.grow()
        elif kind == "attach":
            self.attach(message["slot"])
        elif kind == "detach":
            self.detach(message["slot"])

    def grow(self) -> None:
        """One more session, built and warmed up unseen (Session.warm_up: its kernels compiled), then said to the
        server as built; "failed" with the line why where it could not be built."""
        slot = len(self.sessions)
        try:
            conn = SlotConn(self.conn, slot)
            session = Session(conn, self.scene, *self.size, self.max_fps, self.draw, shared=True, canvas=self.canvas)
            session.warm_up()
        except Exception as exc:  # noqa: BLE001 - a scene that cannot open is said, and the host serves on
            self.sessions.append(None)
            self.tell({"t": "failed", "slot": slot, "text": f"{type(exc).__name__}: {exc}"})
            return
        session.turns = self.turns
        self.sessions.append(session)
        self.canvas = session.renderer.canvas  # the next sessions draw in it too (17 MB each at 960 x 540)
        self.tell({"t": "built", "slot": slot})

    def attach(self, slot: int) -> None:
        session = self.sessions[slot] if 0 <= slot < len(self.sessions) else None
        if session is None:
            self.tell({"t": "ended", "slot": slot, "text": "no such session"})
            return
        session.conn.muted = False
        self.due[slot] = time.perf_counter()
        self.turns.share = len(self.due)  # the attached sessions take turns on this core
        self.guarded(slot, lambda s: s.restart())

    def detach(self, slot: int) -> None:
        self.due.pop(slot, None)
        self.turns.share = len(self.due)
        if 0 <= slot < len(self.sessions) and self.sessions[slot] is not None:
            self.sessions[slot].conn.muted = True

    def guarded(self, slot: int, act) -> None:
        """act(session) for the session in `slot`; where it raises, the session ends (its tab is told by the
        server) and the host's other sessions run on."""
        session = self.sessions[slot]
        try:
            act(session)
        except (EOFError, BrokenPipeError):
            raise
        except Exception as exc:  # noqa: BLE001 - one tab's failure must not end the others'
            self.due.pop(slot, None)
            self.sessions[slot] = None
            self.tell({"t": "ended", "slot": slot, "text": f"{type(exc).__name__}: {exc}"})

    def tell(self, message: dict) -> None:
        self.conn.send_bytes(SLOT.pack(HOST) + b"J" + json.dumps(message).encode())
