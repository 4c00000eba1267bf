"""What a browser may send the classroom server, checked before anything acts on it: each WebSocket message is a
small JSON object of a known type whose fields have the expected types and ranges; a tab sending too much, too
fast or malformed is answered with one clear line and slows only itself. Nothing a client sends names a file."""

from __future__ import annotations

import json
import math
import time

from . import tool_table

MAX_MESSAGE = 2048  # bytes of one message from the page
MAX_RATE = 120.0  # messages per second a tab may send (a pointer stroke sends ~60)
BURST = 240.0  # messages a tab may send at once before the rate applies
ACTIONS = ("pause", "play", "step", "reset", "undo")
# a 3D picture's camera: a drag turns it, zooms or pans (window_parts.OrbitCamera)
VIEW_MOVES = ("orbit", "zoom", "pan")
LANGUAGES = ("en", "fr", "ar")


class ProtocolError(ValueError):
    """A message the server refuses; its text is sent back to the tab."""


def _number(msg: dict, key: str, lo: float, hi: float) -> float:
    value = msg.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ProtocolError(f"{msg['t']}: {key} must be a number, got {value!r}")
    if not lo <= value <= hi:
        raise ProtocolError(f"{msg['t']}: {key} must be between {lo:g} and {hi:g}, got {value:g}")
    return float(value)


def _choice(msg: dict, key: str, allowed) -> str:
    value = msg.get(key)
    if value not in allowed:
        raise ProtocolError(f"{msg['t']}: {key} must be one of {', '.join(map(str, allowed))}, got {value!r}")
    return value


def parse(text: str | bytes, scenes) -> dict:
    """The checked message in `text` (a WebSocket message from the page); `scenes`: the names it may ask for.
    ProtocolError with one line saying what is wrong and what was expected."""
    if len(text) > MAX_MESSAGE:
        raise ProtocolError(f"message of {len(text)} bytes refused: at most {MAX_MESSAGE}")
    try:
        msg = json.loads(text)
    except (ValueError, UnicodeDecodeError):
        raise ProtocolError("message refused: expected a JSON object") from None
    if not isinstance(msg, dict) or not isinstance(msg.get("t"), str):
        raise ProtocolError('message refused: expected a JSON object with a "t" (type)')
    kind = msg["t"]
    if kind == "ready":
        return {"t": "ready"}
    if kind == "pointer":
        return {"t": "pointer", "x": _number(msg, "x", 0, 1), "y": _number(msg, "y", 0, 1)}
    if kind == "tool":
        down = msg.get("down")
        if not isinstance(down, bool):
            raise ProtocolError("tool: down must be true or false")
        out = {
            "t": "tool",
            "tool": _choice(msg, "tool", tool_table.names()),
            "x": _number(msg, "x", 0, 1),
            "y": _number(msg, "y", 0, 1),
            "radius": _number(msg, "radius", 0.5, 30.0),
            "down": down,
        }
        material = msg.get("material")
        if material is not None:  # the spawn tool's material: a name the session checks against its scene's
            if not isinstance(material, str) or not material.isidentifier() or len(material) > 32:
                raise ProtocolError("tool: material must be a material's name")
            out["material"] = material
        return out
    if kind == "set":
        key = msg.get("key")
        if not isinstance(key, str) or not key.isidentifier() or len(key) > 32:
            raise ProtocolError("set: key must be a setting's name")
        out = {"t": "set", "key": key, "value": _number(msg, "value", -1e6, 1e6)}
        if "seq" in msg:  # a number the session echoes in its next readouts (the benchmark's latency probe)
            out["seq"] = int(_number(msg, "seq", 0, 2**31))
        return out
    if kind == "action":
        return {"t": "action", "name": _choice(msg, "name", ACTIONS)}
    if kind == "nogl":  # the page cannot draw 3D spheres (no WebGL2): it asks for pictures instead
        return {"t": "nogl"}
    if kind == "lang":  # the page's language: the picture's chart words follow it
        return {"t": "lang", "lang": _choice(msg, "lang", LANGUAGES)}
    if kind == "view":  # dx, dy: the drag in fractions of the picture
        move = _choice(msg, "move", VIEW_MOVES)
        return {"t": "view", "move": move, "dx": _number(msg, "dx", -1, 1), "dy": _number(msg, "dy", -1, 1)}
    if kind == "scene":
        return {"t": "scene", "name": _choice(msg, "name", tuple(scenes))}
    raise ProtocolError(
        f"message type {kind!r} refused: expected ready, pointer, tool, set, action, view, nogl, lang or scene"
    )


class RateLimit:
    """A token bucket: `allow()` is False once a tab sends faster than MAX_RATE for longer than BURST allows."""

    def __init__(self, rate: float = MAX_RATE, burst: float = BURST):
        self.rate, self.burst = rate, burst
        self.tokens, self.last = burst, time.monotonic()

    def allow(self) -> bool:
        now = time.monotonic()
        self.tokens = min(self.burst, self.tokens + (now - self.last) * self.rate)
        self.last = now
        if self.tokens < 1.0:
            return False
        self.tokens -= 1.0
        return True
