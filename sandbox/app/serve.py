"""The classroom in a browser: `sandbox serve` serves the sandbox to a room of browsers with nothing installed on
them. Each tab gets a session, its own simulation (serve_session.py), held with the class's other sessions of its
scene in a host process (serve_host.py: a host per scene in use and core, so thirty tabs share two Taichi runtimes
instead of starting thirty; which slot of which host is whose: serve_slots.py); the page (web/) draws its
particles, or shows its pictures drawn by the project's renderer, and its panel from the shared description
(panel.py). A teacher's page
lists the sessions with a small live picture of each, and pauses them or pushes a scene or a setting to all.

Safe on a school network: it binds 127.0.0.1 unless told otherwise; any other address requires a token (made and
printed with the address when not given) on every request and WebSocket, whose Origin must be the page's own; every
message is checked (serve_protocol.py); sessions are limited in number, upload size and idle time; nothing a
client sends names a file on the server; scripts and styles come from the package (no CDN).

Fair shares: a client (its address, and the page's `sandbox_client` cookie) holds at most `per_client` sessions at
once (2 unless the teacher says otherwise), so one student cannot fill the class; a session takes one upload at a
time (the next is refused until the session has checked the last), and the uploads in flight over the whole server
hold at most MAX_IN_FLIGHT bytes (beyond it an upload is refused at once, before its body is read); a tab silent
for `idle` seconds loses its session and is told so.

Roles: the teacher's page and routes (the sessions, their pictures, broadcasts, any session's state) need the
teacher's secret, separate from the class's link (always made up and printed in the teacher's address; the page
keeps it in a cookie). A student's session answers only to the socket that opened it: the hello gives that socket
the session's key, which the page's state download and upload carry; without it (or the teacher's secret) they are
refused alike whether the session exists or not. Every body is limited before it is read.
"""

from __future__ import annotations

import asyncio
import ipaddress
import json
import math
import multiprocessing
import secrets
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import urlsplit

from ..config.resources import shipped_scenes
from ..core.cores import usable_cores
from .serve_pipe import HOST, SLOT
from .serve_session import FRAMES, PICTURES, scratch_dir
from .serve_slots import HostProcess, Hosts

WEB = Path(__file__).resolve().parent / "web"
PICTURE = (960, 540)  # the sessions' picture size (the page scales it to fit)
MAX_UPLOAD = 16 * 1024 * 1024  # bytes of an uploaded state file
MAX_IN_FLIGHT = 4 * MAX_UPLOAD  # bytes of uploads the whole server holds at once (module docstring)
PER_CLIENT = 2  # sessions one client (address or cookie) may hold at once, unless the teacher says otherwise
MAX_BROADCAST = 2048  # bytes of a teacher's broadcast message
WARN_SECONDS = 2.0  # "too many messages" is said at most once in this long
IDLE_SECONDS = 300.0  # a tab silent this long (closed, asleep) loses its session
START_SECONDS = 60.0  # a session that has not drawn its first picture by then is given up
BUILD_SECONDS = 300.0  # ... nor been built by then (behind the builds of a class that changed scene)
MAX_PENDING = 256  # a tab's messages kept while its session is readied (the oldest dropped beyond)


@dataclass
class Handle:
    """The server's side of one tab's session: its slot in a host (serve_slots.py), the tab's WebSocket queue and
    what the server knows of it. `link` is the slot (or a test's stand-in): `send_bytes(data)`, `ready` (the session
    takes the tab's messages now), `built` and `detach()`."""

    sid: str
    scene: str
    link: object = None
    key: str = field(default_factory=lambda: secrets.token_urlsafe(18))  # the opening socket's, for HTTP calls
    outbox: asyncio.Queue = field(default_factory=asyncio.Queue)
    waiters: dict = field(default_factory=dict)  # message type -> future (saved, thumbnail)
    last_seen: float = field(default_factory=time.monotonic)
    started: float = field(default_factory=time.monotonic)
    frames: int = 0
    info: dict = field(default_factory=dict)
    address: str = ""  # the tab's network address and its page's client cookie: whose session it is (per_client)
    client: str = ""
    upload_bytes: int = 0  # bytes of the upload this session is taking (0: none; one at a time)
    pending: deque = field(default_factory=lambda: deque(maxlen=MAX_PENDING))  # the tab's, until `link.ready`

    def send(self, message: dict) -> None:
        """A message to the session (kept until its session is ready to take it)."""
        data = json.dumps(message).encode()
        if self.link is not None and self.link.ready:
            self.link.send_bytes(data)
        else:
            self.pending.append(data)

    def flush(self) -> None:
        """What the tab said while its session was being readied, to the session now."""
        while self.pending and self.link is not None and self.link.ready:
            self.link.send_bytes(self.pending.popleft())

    def expect(self, kind: str) -> asyncio.Future:
        """A future that answer(kind, ...) resolves."""
        future = asyncio.get_running_loop().create_future()
        self.waiters[kind] = future
        return future

    def answer(self, kind: str, value) -> None:
        """Resolve the future expect(kind) made, if one waits."""
        future = self.waiters.pop(kind, None)
        if future and not future.done():
            future.set_result(value)

    def say(self, key: str, text: str) -> None:
        """An error line for the tab."""
        self.outbox.put_nowait(("text", json.dumps({"t": "error", "key": key, "text": text})))


class Classroom:
    """The sessions, their hosts, their limits and the token (module docstring)."""

    def __init__(
        self,
        scene: str,
        token: str | None,
        max_sessions: int,
        idle: float = IDLE_SECONDS,
        max_fps: float = 30.0,
        teacher: str | None = None,
        warm: int | None = None,
        draw: str = "page",
        per_client: int = PER_CLIENT,
        per_host: int | None = None,
        worlds: bool = True,
    ):
        """`worlds`: a scene that can run as worlds is held as the worlds of one simulation (serve_worlds.py), its
        tabs each a world, where the page draws (else every scene's tabs are sessions, per_host to a host)."""
        self.per_client = per_client  # sessions a client may hold at once (0: no limit)
        self.in_flight = 0  # bytes of uploads being taken now, over every session
        self.draw = draw  # who draws a 2D scene's particles (serve_session.DRAWS)
        self.scene, self.token, self.max_sessions, self.idle, self.max_fps = scene, token, max_sessions, idle, max_fps
        self.teacher = teacher or secrets.token_urlsafe(12)
        self.warm_target = max_sessions if warm is None else min(warm, max_sessions)
        self.scenes = sorted(p.stem for p in shipped_scenes())
        self.sessions: dict[str, Handle] = {}
        # a host per core holds the class's sessions of a scene (one Taichi thread each), unless told otherwise
        per_host = per_host or math.ceil(max_sessions / usable_cores())
        context = multiprocessing.get_context("spawn")
        worlds = worlds and draw == "page"
        self.hosts = Hosts(context, PICTURE, max_fps, draw, per_host, self._readable, usable_cores(), worlds)
        self.scratch = scratch_dir()

    # ------------------------------------------------------------------ sessions
    def open(self, scene: str) -> Handle:
        """A session of `scene` (a shipped scene's name) for a tab: a built one of that scene where one is free
        (it starts its scene again for the tab at once), else one built for it."""
        handle = Handle(secrets.token_urlsafe(8), scene)
        self.sessions[handle.sid] = handle
        self.place(handle, scene)
        return handle

    def place(self, handle: Handle, scene: str) -> None:
        """Give `handle` a slot of `scene`: a free built one, one being built, or a new one (where the class is at
        its limit of slots, hosts no tab uses are ended first, other scenes' before the default's)."""
        handle.scene, handle.started, handle.frames, handle.info = scene, time.monotonic(), 0, {}
        free = self.hosts.free(scene)
        if free:
            slot = free[0]
        else:
            unused = sorted((h for h in self.hosts.hosts if not h.tabs()), key=lambda h: h.scene == self.scene)
            while unused and self.hosts.slots() >= self.max_sessions:
                self.hosts.end(unused.pop(0))
            slot = self.hosts.new_slot(scene)
        slot.handle, handle.link = handle, slot
        if slot.built:
            slot.attach()
            handle.flush()

    def move(self, handle: Handle, scene: str) -> None:
        """The tab asks for another scene: its session goes back to its scene's pool, and it gets one of `scene`."""
        self.release(handle)
        self.place(handle, scene)

    def release(self, handle: Handle) -> None:
        """The tab's slot goes back to the pool of its scene (started again for the next tab)."""
        slot, handle.link = handle.link, None
        handle.pending.clear()
        if slot is not None:
            slot.detach()

    def ready(self) -> int:
        """Sessions of the default scene built and free for the next tab (the warm pool)."""
        return sum(1 for s in self.hosts.free(self.scene) if s.built)

    def held_by(self, address: str, client: str) -> int:
        """Sessions held now by the client at `address` or with the cookie `client` (the larger count: a student
        who clears the cookie keeps the address, one who moves keeps the cookie)."""
        by_address = sum(1 for h in self.sessions.values() if address and h.address == address)
        by_cookie = sum(1 for h in self.sessions.values() if client and h.client == client)
        return max(by_address, by_cookie)

    def over_share(self, address: str, client: str) -> bool:
        """Whether a new session would give this client more than `per_client`."""
        return self.per_client > 0 and self.held_by(address, client) >= self.per_client

    def take_upload(self, handle: Handle, size: int) -> str | None:
        """Reserve `size` bytes for an upload to `handle`'s session: None when taken, else why not (one line)."""
        if handle.upload_bytes:
            return "one upload at a time: the last one is still being checked"
        if self.in_flight + size > MAX_IN_FLIGHT:
            return "the server is taking other uploads: try again in a few seconds"
        handle.upload_bytes = size
        self.in_flight += size
        return None

    def end_upload(self, handle: Handle) -> None:
        """The session has checked its upload (or it failed): its bytes are free again."""
        self.in_flight -= handle.upload_bytes
        handle.upload_bytes = 0

    def starting(self) -> int:
        """Tabs' sessions that have not drawn their first picture yet (a newcomer is behind them)."""
        return sum(1 for h in self.sessions.values() if h.frames == 0)

    async def keep_warm(self) -> None:
        """Keep up to `warm_target` sessions of the default scene built ahead of the tabs (every slot, free or a
        tab's, at most max_sessions), building as many at once as the machine has cores, each in its own host (a
        build is one busy core: importing, compiling or loading kernels), so that a small machine is not swamped;
        end the hosts no tab and not the pool needs."""
        at_once = usable_cores()
        while True:
            for host in list(self.hosts.hosts):
                if not host.process.is_alive():
                    self.host_ended(host)
            for host in self.hosts.unneeded(self.scene, self.warm_target):
                self.hosts.end(host)
            free = len(self.hosts.free(self.scene))
            room = self.max_sessions - self.hosts.slots()
            for _ in range(min(self.warm_target - free, room)):  # a world host's slots at once: nothing to build
                if self.hosts.building() >= at_once and not self.hosts.has_world_host(self.scene):
                    break
                self.hosts.new_slot(self.scene)
            await asyncio.sleep(0.25)

    def close(self, handle: Handle) -> None:
        """End a tab's session: its slot goes back to its scene's pool; the tab's queue ends."""
        self.sessions.pop(handle.sid, None)
        self.end_upload(handle)
        self.release(handle)
        handle.outbox.put_nowait(None)

    def close_all(self) -> None:
        """Every session and host ended (the server stops)."""
        for handle in list(self.sessions.values()):
            self.close(handle)
        reapers = [self.hosts.end(host) for host in list(self.hosts.hosts)]  # all leave at once
        for reaper in reapers:
            reaper.join()

    def _readable(self, host: HostProcess) -> None:
        try:
            data = host.conn.recv_bytes()
        except (EOFError, OSError):  # the host's process ended (a crash): tell its tabs, free the rest
            self.host_ended(host)
            return
        (index,) = SLOT.unpack_from(data)
        body = data[SLOT.size :]
        if index == HOST:
            self.host_said(host, json.loads(body[1:]))
        elif index < len(host.slots) and host.slots[index].handle is not None:  # else: the last words of a freed one
            self.deliver(host.slots[index].handle, body)

    def host_said(self, host: HostProcess, message: dict) -> None:
        """A host's own message: a slot built, or one that failed or ended."""
        slot = host.slots[message["slot"]]
        handle = slot.handle
        if message["t"] == "built":
            slot.built = True
            self.hosts.built(host, bool(message.get("worlds", False)))
            if handle is not None:
                handle.started = time.monotonic()  # its first picture is due START_SECONDS from now
                slot.attach()
                handle.flush()
            return
        slot.dead = True  # failed (could not be built) or ended (a session's error): told, never given again
        if handle is not None:
            handle.say("session_ended", "your sandbox stopped on an error: reload the page")
            self.close(handle)

    def host_ended(self, host: HostProcess) -> None:
        for slot in host.slots:
            if slot.handle is not None:
                slot.handle.say("session_ended", "your sandbox stopped: reload the page")
                self.close(slot.handle)
        self.hosts.end(host)

    def deliver(self, handle: Handle, data: bytes) -> None:
        """What a session sent its tab: pictures to the page as they are, answers to whoever waits for them."""
        kind, body = data[:1], data[1:]
        if kind in PICTURES:  # to the page as they are: it reads the kind from the first byte
            handle.frames += kind in FRAMES
            handle.outbox.put_nowait(("bytes", data))
        elif kind == b"T":
            handle.answer("thumb", body)
        else:
            message = json.loads(body)
            if message.get("t") == "info":
                handle.info = message
            handle.answer(message.get("t"), message)
            handle.outbox.put_nowait(("text", body.decode()))

    async def reap_idle(self) -> None:
        """Close the sessions of tabs that have gone silent."""
        while True:
            await asyncio.sleep(min(self.idle / 4, 15.0))
            now = time.monotonic()
            for handle in list(self.sessions.values()):
                # a tab's session may wait for others' builds first
                limit = START_SECONDS if handle.link.built else BUILD_SECONDS
                if handle.frames == 0 and now - handle.started > limit:
                    text = f"your sandbox did not start within {limit:.0f} s (the server is busy): reload"
                    handle.say("start_failed", text)
                    self.close(handle)
                elif now - handle.last_seen > self.idle:  # said on the tab, so a student knows why it stopped
                    handle.say(
                        "idle", f"this tab was silent for {self.idle:g} s and its sandbox was closed: reload the page"
                    )
                    self.close(handle)

    # ------------------------------------------------------------------ checks
    def allowed(self, request) -> bool:
        """The request carries the token (query or cookie), where one is set."""
        if self.token is None:
            return True
        given = request.query_params.get("token") or request.cookies.get("sandbox_token") or ""
        return secrets.compare_digest(given, self.token)

    def is_teacher(self, request) -> bool:
        """The request carries the class token (where set) and the teacher's secret (query or cookie)."""
        given = request.query_params.get("teacher") or request.cookies.get("sandbox_teacher") or ""
        return self.allowed(request) and secrets.compare_digest(given, self.teacher)

    @staticmethod
    def owns(request, handle) -> bool:
        """The request carries the key the session's own socket was given."""
        return handle is not None and secrets.compare_digest(request.query_params.get("key", ""), handle.key)

    @staticmethod
    def same_origin(websocket) -> bool:
        """A WebSocket's Origin, where the browser sent one, is the page's own host."""
        origin = websocket.headers.get("origin")
        return origin is None or urlsplit(origin).netloc == websocket.headers.get("host")


def lan_address() -> str:
    """This machine's address on its network (what the students' browsers open when the server listens on every
    address): the one it would send from; no packet is sent. 127.0.0.1 where there is no network."""
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        try:
            probe.connect(("10.255.255.255", 1))
            return probe.getsockname()[0]
        except OSError:
            return "127.0.0.1"


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False
