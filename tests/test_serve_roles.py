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

from sandbox.app.serve import MAX_BROADCAST, Classroom, Handle  # noqa: E402
from sandbox.app.serve_protocol import ProtocolError, parse  # noqa: E402
from sandbox.app.serve_routes import make_app  # noqa: E402

pytestmark = pytest.mark.xdist_group("serve")
TOKEN, TEACHER = "class-token-123", "teacher-secret-456"


class StandIn:
    """A session's pipe end that answers like a session: a picture for "thumb", a saved file for "save"."""

    def __init__(self) -> None:
        self.handle: Handle | None = None
        self.sent: list[dict] = []

    def send_bytes(self, data: bytes) -> None:
        message = json.loads(data)
        self.sent.append(message)
        loop = asyncio.get_running_loop()
        if message["t"] == "thumb":
            loop.call_soon(self.handle.answer, "thumb", b"\xff\xd8 a picture")
        elif message["t"] == "save":
            Path(message["path"]).write_bytes(b"PK saved state")
            loop.call_soon(self.handle.answer, "saved", {"t": "saved"})

    def fileno(self) -> int:
        return -1

    def close(self) -> None:
        pass


class NoProcess:
    def terminate(self) -> None:
        pass

    def join(self, timeout=None) -> None:
        pass

    def is_alive(self) -> bool:
        return False


@pytest.fixture(params=[None, TOKEN], ids=["loopback", "with a class token"])
def room(request):
    """A classroom with two stand-in sessions (a's and b's), and the client."""
    classroom = Classroom("melting_block", request.param, max_sessions=4, teacher=TEACHER)
    sessions = {}
    for name in ("a", "b"):
        conn = StandIn()
        handle = Handle(f"sid-{name}", "melting_block", NoProcess(), conn)
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
    assert [m["t"] for m in sessions["b"].conn.sent] == ["action"]  # the teacher's broadcast, once, to everyone


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
    assert upload.status_code == 202 and a.conn.sent[-1]["t"] == "upload"
    assert not any(m["t"] == "upload" for m in b.conn.sent)
    if token:  # the class's token is needed as well as the key
        assert client.get("/api/state" + query(None, sid=a.sid, key=a.key)).status_code == 403


def test_bodies_are_limited_before_they_are_read(room):
    classroom, client, sessions, token = room
    a = sessions["a"]
    huge = b"x" * (MAX_BROADCAST + 1)
    response = client.post("/api/broadcast" + query(token, teacher=TEACHER), content=huge)
    assert response.status_code == 413 and "2048 bytes" in response.text
    assert not sessions["b"].conn.sent  # nothing was sent on
    declared = client.post(
        "/api/state" + query(token, sid=a.sid, key=a.key), content=b"PK", headers={"content-length": str(1 << 40)}
    )
    assert declared.status_code in (400, 413)  # refused on its word, before a byte is read
    assert not list(classroom.scratch.iterdir())


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
