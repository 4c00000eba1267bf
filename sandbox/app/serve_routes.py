"""The classroom server's routes (Starlette): the pages, the WebSocket each tab talks through, state files in and
out, and the teacher's list, pictures and broadcasts. Who may call what is decided here, before anything reaches a
session: the class token for everything, the teacher's secret for the teacher's routes, and a session's own key (or
the teacher's secret) for its state file. serve.py holds the classroom these routes serve; `serve()` runs them
(Starlette and uvicorn come with the serve extra)."""

from __future__ import annotations

import asyncio
import contextlib
import json
import secrets
import shutil
import time

from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, PlainTextResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocketDisconnect

from .serve import (
    IDLE_SECONDS,
    MAX_BROADCAST,
    MAX_UPLOAD,
    PER_CLIENT,
    WARN_SECONDS,
    WEB,
    Classroom,
    Handle,
    is_loopback,
    lan_address,
)
from .serve_protocol import ProtocolError, RateLimit, parse

CLIENT_COOKIE = "sandbox_client"


def declared_size(request, limit: int) -> int:
    """The bytes a request says its body holds, at most `limit`; `limit` where it does not say."""
    declared = request.headers.get("content-length", "")
    return min(int(declared), limit) if declared.isdigit() else limit


async def bounded_body(request, limit: int) -> bytes | None:
    """The request's body, or None as soon as it is (or says it will be) longer than `limit` bytes."""
    declared = request.headers.get("content-length", "")
    if declared.isdigit() and int(declared) > limit:
        return None
    body = bytearray()
    async for chunk in request.stream():
        body += chunk
        if len(body) > limit:
            return None
    return bytes(body)


async def ask(handle: Handle, kind: str, message: dict, seconds: float):
    """Send the session `message` and wait for its answer of type `kind` (None after `seconds`)."""
    answer = handle.expect(kind)
    handle.send(message)
    try:
        return await asyncio.wait_for(answer, seconds)
    except asyncio.TimeoutError:
        return None


class ClassroomRoutes:
    """The endpoints of one classroom; app() puts them together."""

    def __init__(self, classroom: Classroom) -> None:
        self.classroom = classroom

    def app(self) -> Starlette:
        """The Starlette application."""
        return Starlette(
            routes=[
                Route("/", self.page("index.html")),
                Route("/teacher", self.page("teacher.html", teacher=True)),
                Route("/api/scenes", self.gated(self.scenes)),
                Route("/api/state", self.gated(self.state, "owner"), methods=["GET", "POST"]),
                Route("/api/sessions", self.gated(self.sessions, "teacher")),
                Route("/api/thumb", self.gated(self.thumb, "teacher")),
                Route("/api/broadcast", self.gated(self.broadcast, "teacher"), methods=["POST"]),
                WebSocketRoute("/ws", self.socket),
                Mount("/static", app=TokenGate(StaticFiles(directory=WEB), self.classroom)),
            ],
            lifespan=self.lifespan,
        )

    # ------------------------------------------------------------------ who may call what
    def page(self, name: str, teacher: bool = False):
        """The endpoint of the page `name` (the teacher's page with `teacher`), setting the cookies it needs."""
        classroom = self.classroom

        async def endpoint(request):
            if not classroom.allowed(request):
                return PlainTextResponse("403: this classroom needs its token (the address the server printed)", 403)
            if teacher and not classroom.is_teacher(request):
                return PlainTextResponse("403: the teacher's page needs the teacher's address (printed second)", 403)
            response = FileResponse(WEB / name, headers={"Cache-Control": "no-store"})
            if classroom.token:
                response.set_cookie("sandbox_token", classroom.token, httponly=True, samesite="strict")
            if teacher:
                response.set_cookie("sandbox_teacher", classroom.teacher, httponly=True, samesite="strict")
            if not request.cookies.get(CLIENT_COOKIE):  # whose sessions a tab's are (Classroom.per_client)
                response.set_cookie(CLIENT_COOKIE, secrets.token_urlsafe(12), httponly=True, samesite="strict")
            return response

        return endpoint

    def gated(self, endpoint, role: str = "class"):
        """The endpoint for requests allowed in `role`: "class" (the class token), "teacher" (the teacher's secret),
        or "owner" (a session named by `sid`, for the teacher or the socket that opened it, given its handle)."""
        classroom = self.classroom

        async def checked(request):
            if not classroom.allowed(request):
                return PlainTextResponse("403", 403)
            if role == "teacher" and not classroom.is_teacher(request):
                return PlainTextResponse("403: for the teacher", 403)
            if role != "owner":
                return await endpoint(request)
            handle = classroom.sessions.get(request.query_params.get("sid", ""))
            if not (classroom.is_teacher(request) or classroom.owns(request, handle)):
                return PlainTextResponse("403: not your session", 403)  # said alike whether it exists or not
            if handle is None:
                return PlainTextResponse("no such session", 404)
            return await endpoint(request, handle)

        return checked

    # ------------------------------------------------------------------ the endpoints
    async def scenes(self, request):
        return JSONResponse({"scenes": self.classroom.scenes, "default": self.classroom.scene})

    async def state(self, request, handle: Handle):
        """GET: the session's state file, saved for this download; POST: a state file for the session to check."""
        path = self.classroom.scratch / f"{secrets.token_hex(8)}.npz"
        if request.method == "GET":  # download: the session saves, the file goes to the tab, then away
            if await ask(handle, "saved", {"t": "save", "path": str(path)}, 30) is None:
                return PlainTextResponse("the session did not save in time", 504)
            data = path.read_bytes()
            path.unlink(missing_ok=True)
            name = f"{handle.scene}.npz"
            return Response(
                data,
                media_type="application/octet-stream",
                headers={"Content-Disposition": f'attachment; filename="{name}"'},
            )
        refused = self.classroom.take_upload(handle, declared_size(request, MAX_UPLOAD))
        if refused:
            return PlainTextResponse(f"state file refused: {refused}", 429)
        try:
            body = await bounded_body(request, MAX_UPLOAD)
            if body is None:
                return PlainTextResponse(f"state file refused: larger than {MAX_UPLOAD // 2**20} MB", 413)
            path.write_bytes(body)
            del body
            # checked by the session, which tells the tab by WebSocket; its next upload waits until then
            await ask(handle, "upload_done", {"t": "upload", "path": str(path)}, 60)
        finally:
            path.unlink(missing_ok=True)
            self.classroom.end_upload(handle)
        return PlainTextResponse("checked", 202)

    async def sessions(self, request):
        """The teacher's list: each session's scene, frames, simulated time and frame rate; the warm ones ready."""
        now = time.monotonic()
        classroom = self.classroom
        rows = [
            {
                "sid": h.sid,
                "scene": h.scene,
                "frames": h.frames,
                "time": h.info.get("time", 0.0),
                "fps": h.frames / max(now - h.started, 1e-9),
            }
            for h in classroom.sessions.values()
        ]
        return JSONResponse({"sessions": rows, "max": classroom.max_sessions, "warm": classroom.ready()})

    async def thumb(self, request):
        """A small picture of the session `sid` now."""
        handle = self.classroom.sessions.get(request.query_params.get("sid", ""))
        if handle is None:
            return PlainTextResponse("no such session", 404)
        data = await ask(handle, "thumb", {"t": "thumb"}, 10)
        if data is None:
            return PlainTextResponse("no picture in time", 504)
        return Response(data, media_type="image/jpeg", headers={"Cache-Control": "no-store"})

    async def broadcast(self, request):
        """The teacher's message (an action, a scene or a setting) to every session."""
        classroom = self.classroom
        body = await bounded_body(request, MAX_BROADCAST)
        if body is None:
            return PlainTextResponse(f"broadcast: larger than {MAX_BROADCAST} bytes; expected one message", 413)
        try:
            message = parse(body, classroom.scenes)
        except ProtocolError as exc:
            return PlainTextResponse(str(exc), 400)
        if message["t"] not in ("action", "scene", "set"):
            return PlainTextResponse("broadcast: expected an action, a scene or a setting", 400)
        for handle in list(classroom.sessions.values()):
            if message["t"] == "scene":  # each tab to a session of that scene (serve_slots.py)
                classroom.move(handle, message["name"])
            else:
                handle.send(message)
        return JSONResponse({"sent": len(classroom.sessions)})

    # ------------------------------------------------------------------ a tab's socket
    async def socket(self, websocket):
        """A tab's WebSocket: its session opened (or the class told it is full), then its messages checked and
        relayed until it closes, the session's answers pumped back meanwhile."""
        classroom = self.classroom
        if not classroom.allowed(websocket) or not classroom.same_origin(websocket):
            await websocket.close(code=1008)
            return
        await websocket.accept()
        if len(classroom.sessions) >= classroom.max_sessions:
            text = f"the classroom is full ({classroom.max_sessions} sessions): try again later"
            await websocket.send_text(json.dumps({"t": "error", "key": "full", "text": text}))
            await websocket.close(code=1013)
            return
        address = websocket.client.host if websocket.client else ""
        client = websocket.cookies.get(CLIENT_COOKIE, "")
        if classroom.over_share(address, client):
            text = (f"this browser already has {classroom.per_client} sessions open, as many as the class allows one "
                    "student: close another tab of the sandbox and reload")  # fmt: skip
            await websocket.send_text(json.dumps({"t": "error", "key": "per_client", "text": text}))
            await websocket.close(code=1013)
            return
        scene = websocket.query_params.get("scene", classroom.scene)
        if scene not in classroom.scenes:
            scene = classroom.scene
        ahead = classroom.starting()
        handle = classroom.open(scene)
        handle.address, handle.client = address, client
        hello = {"t": "hello", "sid": handle.sid, "key": handle.key, "scenes": classroom.scenes}
        await websocket.send_text(json.dumps(hello))
        if not handle.link.built:  # not a warm one: say so, and how many are starting before it
            await websocket.send_text(json.dumps({"t": "notice", "key": "starting", "text": str(ahead)}))

        async def pump():
            while (item := await handle.outbox.get()) is not None:
                kind, body = item
                await (websocket.send_bytes(body) if kind == "bytes" else websocket.send_text(body))

        sender = asyncio.create_task(pump())
        try:
            await self.relay(websocket, handle)
        except (WebSocketDisconnect, RuntimeError, OSError):
            pass
        finally:
            classroom.close(handle)
            sender.cancel()

    async def relay(self, websocket, handle: Handle) -> None:
        """The tab's messages to its session, each checked; too many, bytes or malformed ones answered in a line."""
        limit, warned = RateLimit(), -WARN_SECONDS
        while True:
            received = await websocket.receive()
            if received["type"] == "websocket.disconnect":
                return
            handle.last_seen = time.monotonic()
            if not limit.allow():
                if handle.last_seen - warned > WARN_SECONDS:  # said once a burst, not once a message
                    warned = handle.last_seen
                    slow = {"t": "error", "key": "too_many", "text": "too many messages: slow down"}
                    await websocket.send_text(json.dumps(slow))
                continue
            text = received.get("text")
            if text is None:
                said = {"t": "error", "key": "not_text", "text": "expected text (JSON), not bytes"}
                await websocket.send_text(json.dumps(said))
                continue
            try:
                message = parse(text, self.classroom.scenes)
            except ProtocolError as exc:
                await websocket.send_text(json.dumps({"t": "error", "text": str(exc)}))
                continue
            if message["t"] == "scene":  # a session of that scene, in its host (serve_slots.py)
                self.classroom.move(handle, message["name"])
            else:
                handle.send(message)

    @contextlib.asynccontextmanager
    async def lifespan(self, app):
        """The idle reaper and the warm pool while the server runs; every session closed and the scratch folder
        removed when it stops."""
        classroom = self.classroom
        tasks = [asyncio.create_task(classroom.reap_idle()), asyncio.create_task(classroom.keep_warm())]
        yield
        for task in tasks:
            task.cancel()
        classroom.close_all()
        shutil.rmtree(classroom.scratch, ignore_errors=True)


class TokenGate:
    """ASGI middleware: the wrapped app only for requests that carry the classroom's token."""

    def __init__(self, app, classroom: Classroom):
        self.app, self.classroom = app, classroom

    async def __call__(self, scope, receive, send):
        if scope["type"] == "http" and not self.classroom.allowed(Request(scope)):
            await PlainTextResponse("403", 403)(scope, receive, send)
            return
        await self.app(scope, receive, send)


def make_app(classroom: Classroom) -> Starlette:
    """The Starlette application of `classroom`: the page, its assets, the WebSocket, state files, the teacher."""
    return ClassroomRoutes(classroom).app()


def serve(
    scene: str,
    host: str,
    port: int,
    token: str | None,
    max_sessions: int,
    max_fps: float = 30.0,
    teacher: str | None = None,
    warm: int | None = None,
    draw: str = "page",
    per_client: int = PER_CLIENT,
    idle: float = IDLE_SECONDS,
    worlds: bool = True,
) -> int:
    """Run the classroom server until Ctrl-C; prints the address to open (with the token where one is needed) and
    the teacher's (with the teacher's secret, made up when not given)."""
    import uvicorn

    if token is None and not is_loopback(host):
        token = secrets.token_urlsafe(12)
    classroom = Classroom(
        scene,
        token,
        max_sessions,
        idle,
        max_fps,
        teacher=teacher,
        warm=warm,
        draw=draw,
        per_client=per_client,
        worlds=worlds,
    )
    query = f"?token={token}" if token else ""
    shown = lan_address() if host in ("0.0.0.0", "::") else host
    print(f"the classroom: http://{shown}:{port}/{query}", flush=True)
    teacher_query = f"?teacher={classroom.teacher}" + (f"&token={token}" if token else "")
    print(f"the teacher's view (yours alone): http://{shown}:{port}/teacher{teacher_query}", flush=True)
    # no per-message deflate: pictures and particle frames hardly compress, and deflating each costs the server a
    # fifth of a millisecond
    uvicorn.run(
        make_app(classroom),
        host=host,
        port=port,
        log_level="warning",
        ws_max_size=64 * 1024,
        ws_per_message_deflate=False,
    )
    return 0
