"""Who may do what in the classroom (issue 56, item 1), route by route, with no credentials, a student's (the
class's token, with or without a session's key) and the teacher's; bodies limited before they are read; and a
socket that sends bytes or floods is told once. The routes run in this process (Starlette's test client) over a
stand-in session that answers as a real one does, so no simulation is started for them."""

from __future__ import annotations

import asyncio
import concurrent.futures
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("starlette")
pytest.importorskip("httpx")

from starlette.testclient import TestClient  # noqa: E402

from sandbox.app.serve import MAX_BROADCAST, MAX_IN_FLIGHT, Classroom, Handle  # noqa: E402
from sandbox.app.serve_protocol import ProtocolError, parse  # noqa: E402
from sandbox.app.serve_routes import make_app  # noqa: E402

pytestmark = pytest.mark.xdist_group("serve")
TOKEN, TEACHER = "class-token-123", "teacher-secret-456"


class StandIn:
    """A session's pipe end that answers like a session: a picture for "thumb", a saved file for "save"."""

    def __init__(self) -> None:
        self.handle: Handle | None = None
        self.sent: list[dict] = []
        self.uploads: list[int] = []  # the size of each upload it was given
        self.checking = 0.0  # seconds it takes to check an upload

    def send_bytes(self, data: bytes) -> None:
        message = json.loads(data)
        self.sent.append(message)
        loop = asyncio.get_running_loop()
        if message["t"] == "thumb":
            loop.call_soon(self.handle.answer, "thumb", b"\xff\xd8 a picture")
        elif message["t"] == "save":
            Path(message["path"]).write_bytes(b"PK saved state")
            loop.call_soon(self.handle.answer, "saved", {"t": "saved"})
        elif message["t"] == "upload":  # checked a little later, as a session loading a file is
            self.uploads.append(Path(message["path"]).stat().st_size)
            loop.call_later(self.checking, self.handle.answer, "upload_done", {"t": "upload_done"})

    ready = built = True  # it takes a tab's messages at once (serve.Handle.link)

    def detach(self) -> None:  # the tab has gone: a session would go back to its pool
        pass


@pytest.fixture(params=[None, TOKEN], ids=["loopback", "with a class token"])
def room(request):
    """A classroom with two stand-in sessions (a's and b's), and the client."""
    classroom = Classroom("melting_block", request.param, max_sessions=4, teacher=TEACHER)
    sessions = {}
    for name in ("a", "b"):
        conn = StandIn()
        handle = Handle(f"sid-{name}", "melting_block", conn)
        conn.handle = handle
        classroom.sessions[handle.sid] = handle
        sessions[name] = handle
    with TestClient(make_app(classroom)) as client:
        yield classroom, client, sessions, request.param


def query(token_value, **params) -> str:
    if token_value:
        params["token"] = token_value
    return "?" + "&".join(f"{k}={v}" for k, v in params.items()) if params else ""


def test_teacher_routes_answer_only_the_teacher(room):
    _, client, sessions, token = room
    for path, method, body in [
        ("/teacher", "GET", None),
        ("/api/sessions", "GET", None),
        ("/api/thumb", "GET", None),
        ("/api/broadcast", "POST", json.dumps({"t": "action", "name": "pause"})),
    ]:
        extra = {"sid": sessions["a"].sid} if path == "/api/thumb" else {}
        for who, params in [
            ("nobody", {}),
            ("a student", {"token": token} if token else {}),
            ("a student with a session's key", {**({"token": token} if token else {}), "key": sessions["a"].key}),
        ]:
            client.cookies.clear()  # the teacher's page of an earlier round left its cookie
            response = client.request(method, path + query(None, **params, **extra), content=body)
            assert response.status_code == 403, (path, who, response.text)
        response = client.request(method, path + query(token, teacher=TEACHER, **extra), content=body)
        assert response.status_code == 200, (path, response.text)
    assert [m["t"] for m in sessions["b"].link.sent] == ["action"]  # the teacher's broadcast, once, to everyone


def test_a_students_state_routes_reach_only_their_own_session(room):
    _, client, sessions, token = room
    a, b = sessions["a"], sessions["b"]
    own = client.get("/api/state" + query(token, sid=a.sid, key=a.key))
    assert own.status_code == 200 and own.content == b"PK saved state"
    for params in ({"sid": b.sid, "key": a.key}, {"sid": b.sid}, {"sid": "no-such", "key": a.key}, {}):
        for method in ("GET", "POST"):
            response = client.request(method, "/api/state" + query(token, **params), content=b"PK x")
            assert response.status_code == 403, (method, params)  # the same answer whether it exists or not
    assert client.get("/api/state" + query(token, sid=b.sid, teacher=TEACHER)).status_code == 200
    upload = client.post("/api/state" + query(token, sid=a.sid, key=a.key), content=b"PK upload")
    assert upload.status_code == 202 and a.link.sent[-1]["t"] == "upload"
    assert not any(m["t"] == "upload" for m in b.link.sent)
    if token:  # the class's token is needed as well as the key
        assert client.get("/api/state" + query(None, sid=a.sid, key=a.key)).status_code == 403


def test_bodies_are_limited_before_they_are_read(room):
    classroom, client, sessions, token = room
    a = sessions["a"]
    huge = b"x" * (MAX_BROADCAST + 1)
    response = client.post("/api/broadcast" + query(token, teacher=TEACHER), content=huge)
    assert response.status_code == 413 and "2048 bytes" in response.text
    assert not sessions["b"].link.sent  # nothing was sent on
    declared = client.post(
        "/api/state" + query(token, sid=a.sid, key=a.key), content=b"PK", headers={"content-length": str(1 << 40)}
    )
    assert declared.status_code in (400, 413)  # refused on its word, before a byte is read
    assert not list(classroom.scratch.iterdir())


def stand_in_sessions(classroom: Classroom) -> None:
    """Make `classroom` open stand-in sessions (no process) for its tabs' sockets."""

    def open_stand_in(scene: str) -> Handle:
        conn = StandIn()
        handle = Handle(f"sid-{len(classroom.sessions)}-{time.monotonic_ns()}", scene, conn)
        handle.frames = 1
        conn.handle = handle
        classroom.sessions[handle.sid] = handle
        return handle

    classroom.open = open_stand_in


def first_message(ws) -> dict:
    return json.loads(ws.receive_text())


def test_a_client_over_its_share_of_sessions_is_refused_in_one_line(room):
    """Issue 74: one class link opened sessions until the class was full. A client holds at most `per_client`
    sessions, counted by its address and by its page's cookie alike (a new cookie from the same address is the same
    client); the third socket is told why in one line and closed; another client still gets in; 0 lifts the limit."""
    classroom, client, _, token = room
    classroom.sessions.clear()
    stand_in_sessions(classroom)
    page = client.get("/" + query(token))
    assert "sandbox_client" in page.headers.get("set-cookie", "")  # the page names its browser
    url = "/ws" + query(token)
    with client.websocket_connect(url) as one, client.websocket_connect(url) as two:
        assert first_message(one)["t"] == first_message(two)["t"] == "hello"
        with client.websocket_connect(url) as three:
            refused = first_message(three)
            assert refused["key"] == "per_client" and "already has 2 sessions open" in refused["text"]
        client.cookies.set("sandbox_client", "a-cookie-of-its-own")  # the same address with a fresh cookie
        with client.websocket_connect(url) as four:
            assert first_message(four)["key"] == "per_client"
        assert len(classroom.sessions) == 2
        classroom.per_client = 0
        with client.websocket_connect(url) as five:
            assert first_message(five)["t"] == "hello"
    classroom.per_client = 2
    other = Classroom("melting_block", token, max_sessions=4, teacher=TEACHER)
    other.sessions = {h.sid: h for h in classroom.sessions.values()}
    assert other.held_by("10.0.0.7", "another-cookie") == 0 and not other.over_share("10.0.0.7", "another-cookie")


def test_a_session_takes_one_upload_at_a_time_and_the_server_caps_the_bytes_in_flight(room):
    """Issue 74: 100 parallel uploads with one student's key raised the server's memory by 1.4 GB. A session's
    upload waits for the session to check it; a second one meanwhile is refused before its body is read, and so is
    one that would take the uploads in flight over MAX_IN_FLIGHT; each reservation is freed when its upload ends."""
    classroom, client, sessions, token = room
    a, b = sessions["a"], sessions["b"]
    url = "/api/state" + query(token, sid=a.sid, key=a.key)
    ok = client.post(url, content=b"PK one")
    assert ok.status_code == 202 and a.link.uploads == [6] and classroom.in_flight == 0 and a.upload_bytes == 0
    assert classroom.take_upload(a, 1000) is None  # an upload to a is under way ...
    busy = client.post(url, content=b"PK two")
    assert busy.status_code == 429 and "one upload at a time" in busy.text and a.link.uploads == [6]
    classroom.end_upload(a)
    classroom.in_flight = MAX_IN_FLIGHT - 10  # other sessions' uploads fill the server's allowance
    crowded = client.post("/api/state" + query(token, sid=b.sid, key=b.key), content=b"PK" * 100)
    assert crowded.status_code == 429 and "other uploads" in crowded.text and not b.link.uploads
    classroom.in_flight = 0
    assert not list(classroom.scratch.iterdir())


def test_parallel_uploads_to_one_session_are_taken_one_at_a_time():
    """A hundred uploads at once with one key: one is taken, the rest refused at once, the bytes in flight never
    above one upload's."""
    httpx = pytest.importorskip("httpx")
    classroom = Classroom("melting_block", None, max_sessions=4, teacher=TEACHER)
    conn = StandIn()
    conn.checking = 0.5
    handle = Handle("sid-a", "melting_block", conn)
    conn.handle = handle
    classroom.sessions[handle.sid] = handle
    peak = []
    take = classroom.take_upload
    classroom.take_upload = lambda h, size: (take(h, size), peak.append(classroom.in_flight))[0]
    body = b"PK" + b"x" * (1 << 20)

    async def everyone():
        transport = httpx.ASGITransport(app=make_app(classroom))
        async with httpx.AsyncClient(transport=transport, base_url="http://testserver") as http:
            url = f"/api/state?sid={handle.sid}&key={handle.key}"
            return await asyncio.gather(*(http.post(url, content=body) for _ in range(100)))

    answers = asyncio.run(everyone())
    codes = sorted(r.status_code for r in answers)
    assert codes.count(202) == 1 and codes.count(429) == 99
    assert max(peak) <= len(body) and classroom.in_flight == 0 and conn.uploads == [len(body)]


def test_a_silent_tab_loses_its_session_and_is_told_why():
    """Issue 74: idle sessions are reclaimed after the set time with a message on the tab (they went silently)."""
    classroom = Classroom("melting_block", None, max_sessions=4, idle=0.2, teacher=TEACHER)
    handle = Handle("sid-a", "melting_block", StandIn())
    handle.frames, handle.last_seen = 5, time.monotonic() - 1.0
    classroom.sessions[handle.sid] = handle

    async def reap_once():
        reaper = asyncio.create_task(classroom.reap_idle())
        await asyncio.sleep(0.3)
        reaper.cancel()

    asyncio.run(reap_once())
    assert not classroom.sessions
    kind, body = handle.outbox.get_nowait()
    said = json.loads(body)
    assert said["key"] == "idle" and "silent for 0.2 s" in said["text"] and handle.outbox.get_nowait() is None


def test_the_teacher_page_keeps_the_secret_in_a_cookie(room):
    _, client, _, token = room
    page = client.get("/teacher" + query(token, teacher=TEACHER))
    assert page.status_code == 200 and "sandbox_teacher" in page.headers.get("set-cookie", "")
    assert client.get("/api/sessions" + query(token)).status_code == 200  # the cookie carries it now
    client.cookies.clear()
    assert client.get("/api/sessions" + query(token)).status_code == 403


@pytest.mark.slow  # a real server and one session process
def test_a_socket_sending_bytes_or_flooding_is_told_once_and_the_server_leaves_no_folder(tmp_path):
    """A binary frame raised KeyError in the server; a flood was answered 46 times per burst; the server's scratch
    folder stayed behind after it stopped."""
    websockets = pytest.importorskip("websockets")
    from .test_serve import free_port

    port = free_port()
    env = {**os.environ, "TMPDIR": str(tmp_path)}
    proc = subprocess.Popen(
        [sys.executable, "-m", "sandbox", "serve", "lj_box", "--port", str(port), "--max-fps", "5"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env,
    )
    try:
        proc.stdout.readline(), proc.stdout.readline()

        async def misbehave():
            for _ in range(100):
                try:
                    socket = await websockets.connect(f"ws://127.0.0.1:{port}/ws")
                    break
                except OSError:
                    await asyncio.sleep(0.1)
            async with socket:
                hello = json.loads(await socket.recv())
                await socket.send(b"\x00\x01 binary")
                await socket.send(json.dumps({"t": "pointer", "x": 0.5, "y": 0.5}))
                for _ in range(500):
                    await socket.send(json.dumps({"t": "pointer", "x": 0.5, "y": 0.5}))
                said, end = [], time.monotonic() + 1.5
                while time.monotonic() < end:
                    try:
                        text = await asyncio.wait_for(socket.recv(), 0.2)
                    except asyncio.TimeoutError:
                        continue
                    if isinstance(text, str) and json.loads(text).get("t") == "error":
                        said.append(json.loads(text)["text"])
                return hello, said

        with concurrent.futures.ThreadPoolExecutor(1) as pool:  # a thread of its own: no other event loop there
            hello, said = pool.submit(asyncio.run, misbehave()).result(120)
        assert hello["t"] == "hello" and len(hello["key"]) >= 20
        assert said.count("expected text (JSON), not bytes") == 1
        assert 1 <= sum("too many messages" in s for s in said) <= 1
        assert proc.poll() is None  # the server runs on
    finally:
        proc.send_signal(signal.SIGINT)
        output, _ = proc.communicate(timeout=30)
    assert "Traceback" not in output and "KeyError" not in output, output
    assert not list(tmp_path.glob("sandbox-serve-*")), "the server's scratch folder was left behind"


JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=20),
    lambda children: st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=8), children, max_size=4),
    max_leaves=12,
)
KINDS = ["ready", "pointer", "tool", "action", "scene", "set", "lang", "thumb", "upload", "save", "x"]


@settings(max_examples=3000 if os.environ.get("SANDBOX_FUZZ") == "campaign" else 300, deadline=None)
@given(
    raw=st.one_of(
        st.binary(max_size=64),
        st.text(max_size=64),
        st.builds(
            lambda kind, fields: json.dumps({"t": kind, **fields}),
            st.sampled_from(KINDS),
            st.dictionaries(st.sampled_from(["x", "y", "down", "name", "key", "value", "tool", "lang"]), JSON_VALUES),
        ),
    )
)
def test_any_message_is_a_checked_message_or_one_line_refusal(raw):
    """Whatever a page sends (bytes, text, any JSON under any known type): a message of a known type with checked
    fields, or one ProtocolError line; never another exception."""
    try:
        message = parse(raw, ["melting_block", "lj_box"])
    except ProtocolError as exc:
        assert "\n" not in str(exc)
        return
    assert message["t"] in KINDS and json.dumps(message, allow_nan=False)


def test_the_serve_bench_fails_in_one_line_when_the_server_does_not_serve():
    """`sandbox bench --serve` waited a fixed 3 s for the server (and crashed when it took longer) and reported
    0.0 pictures a second with exit 0 when tabs got nothing: it now waits for the warm sessions and says so."""
    from sandbox.errors import SandboxError
    from sandbox.research.serve_bench import _wait_until_warm

    stopped = subprocess.Popen(
        [sys.executable, "-c", "import sys; sys.stderr.write('port in use\\n'); sys.exit(1)"],
        stderr=subprocess.PIPE,
        text=True,
    )
    stopped.wait(10)
    with pytest.raises(SandboxError, match=r"the server stopped \(port in use\)"):
        _wait_until_warm(stopped, 9, "secret-123", 2, limit=5)
    silent = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"], stderr=subprocess.PIPE, text=True)
    try:
        with pytest.raises(SandboxError, match="did not start 2 sessions within 1 s"):
            _wait_until_warm(silent, 9, "secret-123", 2, limit=1)
    finally:
        silent.kill()
        silent.wait()
