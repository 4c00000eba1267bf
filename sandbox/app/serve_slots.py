"""The server's side of the classroom's hosts (serve_host.py): the host processes, each holding sessions of one
scene in its slots, and which slot is which tab's. A tab's session is a slot: taken built and free where one of its
scene waits (at once: it only starts its scene again), else built for it in a host of its scene with room, else in
a new host. A tab that leaves gives its slot back to the pool of its scene; a host none of whose slots is a tab's
ends (its memory with it) unless the warm pool needs it. The server's process never imports Taichi."""

from __future__ import annotations

import asyncio
import contextlib
import json
import signal
import threading
from dataclasses import dataclass, field

from ..core.cores import pinnable_cores
from .serve_host import host_main
from .serve_pipe import HOST, SLOT

LEAVE_SECONDS = 5.0  # how long an ended host may take to write its kernels to Taichi's cache (0.2 s for two sessions)


def next_core(cores: list[int], taken: list[int | None]) -> int | None:
    """Of `cores`, the one the fewest running hosts are pinned to (`taken`: theirs), the first of those; None where
    hosts are not pinned."""
    if not cores:
        return None
    return min(cores, key=lambda core: (taken.count(core), cores.index(core)))


def _reap(process) -> None:
    """Wait for an ended host's process to leave; kill it after LEAVE_SECONDS."""
    process.join(timeout=LEAVE_SECONDS)
    if process.is_alive():
        process.kill()
        process.join(timeout=1.0)


@dataclass(eq=False)
class Slot:
    """One session in a host: built (warmed up: serve_session.Session.warm_up) or being built, free or a tab's
    (`handle`)."""

    host: HostProcess = field(repr=False)
    index: int
    built: bool = False
    dead: bool = False  # it failed or its host ended: never given again
    handle: object = field(default=None, repr=False)  # the tab's serve.Handle whose session it is now

    @property
    def ready(self) -> bool:
        """A tab's messages go to the session now (before, the handle keeps them)."""
        return self.built and not self.dead and self.handle is not None

    def send_bytes(self, data: bytes) -> None:
        self.host.conn.send_bytes(SLOT.pack(self.index) + data)

    def attach(self) -> None:
        self.host.order({"t": "attach", "slot": self.index})

    def detach(self) -> None:
        self.handle = None
        if self.built and not self.dead:
            self.host.order({"t": "detach", "slot": self.index})


@dataclass(eq=False)
class HostProcess:
    """A host's process, its pipe and its slots."""

    scene: str
    process: object
    conn: object
    capacity: int
    slots: list[Slot] = field(default_factory=list)
    core: int | None = None  # the core its process runs on first (Hosts.cores, serve_host.Pinning)
    worlds: bool = False  # its tabs are the worlds of one simulation (serve_worlds.py): slots are built at once

    def order(self, message: dict) -> None:
        self.conn.send_bytes(SLOT.pack(HOST) + json.dumps(message).encode())

    def live(self) -> list[Slot]:
        return [s for s in self.slots if not s.dead]

    def tabs(self) -> int:
        return sum(1 for s in self.slots if s.handle is not None)

    def building(self) -> int:
        return sum(1 for s in self.live() if not s.built)

    def grow(self) -> Slot:
        """A slot asked for now, built by the host after those before it."""
        slot = Slot(self, len(self.slots))
        self.slots.append(slot)
        self.order({"t": "grow"})
        return slot


class Hosts:
    """Every host of the classroom, started with `context` (multiprocessing), each holding at most `per_host`
    sessions; `receive(host)` is called when a host's pipe has something to read."""

    def __init__(
        self,
        context,
        picture: tuple[int, int],
        max_fps: float,
        draw: str,
        per_host: int,
        receive,
        side_by_side: int,
        worlds: bool = False,
    ) -> None:
        """`side_by_side`: hosts of a scene that build at once (a build is one busy core); `worlds`: a scene that can
        run as worlds is held by world hosts (serve_worlds.py: `per_host` tabs each, the worlds of one simulation)."""
        self.context, self.picture, self.max_fps, self.draw = context, picture, max_fps, draw
        self.per_host, self.receive, self.side_by_side = max(per_host, 1), receive, max(side_by_side, 1)
        self.worlds = worlds
        self.sessions_only: set[str] = set()  # scenes whose world host said they cannot run as worlds
        self.hosts: list[HostProcess] = []
        # Each host is one thread, always busy while a class is on: it is pinned to a core, each in turn
        # (serve_host.Pinning). Left to the scheduler, two hosts and another busy program on two cores stayed as two
        # on one core and the program alone on the other (the class kept 39-43% of its quiet rate beside one CPU hog,
        # `sandbox bench --serve 30 --contended 1`); pinned, the program shares a core with one host, each in turn.
        self.cores = pinnable_cores()

    def free(self, scene: str) -> list[Slot]:
        """The slots of `scene` no tab has, built ones first."""
        slots = [s for h in self.hosts if h.scene == scene for s in h.live() if s.handle is None]
        return sorted(slots, key=lambda s: (not s.built, s.host.tabs()))  # a class shared among its scene's hosts

    def slots(self) -> int:
        """Every live slot, built or being built."""
        return sum(len(h.live()) for h in self.hosts)

    def building(self) -> int:
        return sum(h.building() for h in self.hosts)

    def new_slot(self, scene: str) -> Slot:
        """A slot of `scene` asked for now: in the host of that scene with room that has the fewest builds ahead of
        it and then the fewest tabs (a build pauses its host's tabs for a second or two); in a new host where there
        is none with room, or where every one is building and the scene has fewer than `side_by_side` hosts, so
        that a class's sessions (the warm pool's, or every tab's after the teacher sends a scene) build on every
        core (and no host is started for the last few slots while a host with room is still building)."""
        hosts = [h for h in self.hosts if h.scene == scene and h.process.is_alive()]
        roomy = [h for h in hosts if len(h.live()) < h.capacity]
        worlds = [h for h in roomy if h.worlds]
        if worlds:  # its slots are ready once its simulation is: no second build beside it
            return min(worlds, key=lambda h: len(h.live())).grow()
        idle = [h for h in roomy if h.building() == 0]
        if not roomy or (not idle and len(hosts) < self.side_by_side):
            return self.start(scene).grow()
        return min(idle or roomy, key=lambda h: (h.building(), h.tabs())).grow()

    def start(self, scene: str) -> HostProcess:
        """A new host process of `scene`, its pipe read by the event loop."""
        parent, child = self.context.Pipe()
        worlds = self.per_host if self.worlds and scene not in self.sessions_only else 0
        core = next_core(self.cores, [h.core for h in self.hosts])
        args = (child, scene, *self.picture, self.max_fps, self.draw, core, tuple(self.cores), worlds)
        process = self.context.Process(target=host_main, args=args, daemon=True)
        with _keyboard_interrupt_ignored():  # the host starts with Ctrl-C ignored (host_main says so too, later)
            process.start()
        child.close()
        host = HostProcess(scene, process, parent, self.per_host, core=core, worlds=bool(worlds))
        self.hosts.append(host)
        asyncio.get_running_loop().add_reader(parent.fileno(), self.receive, host)
        return host

    def end(self, host: HostProcess) -> threading.Thread:
        """Stop a host: its process and memory go; its slots are dead. The host leaves the normal way, writing its
        kernels to Taichi's cache (serve_host.py), which takes a moment: a thread waits for it (killing it after
        LEAVE_SECONDS), so the server's loop never does; returns that thread."""
        if host in self.hosts:
            self.hosts.remove(host)
        for slot in host.slots:
            slot.dead = True
        with contextlib.suppress(Exception):
            asyncio.get_running_loop().remove_reader(host.conn.fileno())
        with contextlib.suppress(Exception):
            host.conn.close()
        host.process.terminate()
        reaper = threading.Thread(target=_reap, args=(host.process,), daemon=True)
        reaper.start()
        return reaper

    def has_world_host(self, scene: str) -> bool:
        """Whether a host of `scene` holds its tabs as worlds and has room (a slot there is ready with the host)."""
        return any(h.scene == scene and h.worlds and len(h.live()) < h.capacity for h in self.hosts)

    def built(self, host: HostProcess, worlds: bool) -> None:
        """`host` built a slot and says whether its tabs are worlds: a world host of a scene that cannot run as
        worlds holds sessions (its scene's next hosts start as hosts of sessions)."""
        if host.worlds and not worlds:
            host.worlds = False
            self.sessions_only.add(host.scene)

    def unneeded(self, scene: str, warm_target: int) -> list[HostProcess]:
        """Hosts no tab uses and the warm pool (`warm_target` free slots of the default `scene`) can do without."""
        out = []
        spare = len(self.free(scene))
        for host in self.hosts:
            if host.tabs():
                continue
            if host.scene == scene:
                if spare - len(host.live()) < warm_target:
                    continue
                spare -= len(host.live())
            out.append(host)
        return out


@contextlib.contextmanager
def _keyboard_interrupt_ignored():
    """SIGINT ignored while a host process starts, so that it starts ignoring it (an ignored signal stays ignored in
    the process spawned, and Python installs no KeyboardInterrupt where it starts ignored): a Ctrl-C, which reaches
    the whole process group, is the server's to handle, not a half-started host's. Only the main thread sets
    signal handlers; elsewhere (a test's server in a thread) nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    before = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, before)
