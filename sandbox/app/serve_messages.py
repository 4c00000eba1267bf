"""What a page's messages do, written once for whatever serves a tab: a session of its own (serve_session.Session)
or a world of a host's simulation (serve_world_tab.WorldTab). The messages arrive checked (serve_protocol.py); each
kind calls the server's own hook where the two differ (a page without WebGL2, a language, a scene, the clock)."""

from __future__ import annotations

import json
from pathlib import Path

from .serve_drawing import jpeg

FIRST_CREDITS = 2  # pictures a tab may be sent before the page's first "ready"


class PageMessages:
    """The page's messages (`handle`), its tools, readouts, state files and the pipe's JSON, over what the class
    keeps: `conn`, `sim`, `control` (app/controller.Controller), `credits`, `watched`, `pointer`, `seq`, `lang`,
    `legend_source`, and the hooks `world_at`, `action`, `view`, `no_webgl`, `set_words`, `open_scene`,
    `thumbnail`, `scene_time` and `stats_now`."""

    world: int | None = None  # the world of its simulation the tab is (serve_world_tab.py); None: all of its own

    def tell(self, message: dict) -> None:
        self.conn.send_bytes(b"J" + json.dumps(message, allow_nan=False, default=str).encode())

    def handle(self, msg: dict) -> None:
        kind = msg["t"]
        if kind == "ready":
            self.credits = min(self.credits + 1, FIRST_CREDITS + 1)
            self.watched = True
        elif kind == "tool":
            self.tool(msg)
        elif kind == "pointer":
            self.pointer = (msg["x"], msg["y"])
        elif kind == "set":
            self.seq = msg.get("seq", self.seq)
            try:
                self.control.set(msg["key"], msg["value"])
            except ValueError as exc:
                self.tell({"t": "error", "text": str(exc)})
        elif kind == "action":
            self.action(msg["name"])
        elif kind == "view":
            self.view(msg["move"], msg["dx"], msg["dy"])
        elif kind == "nogl":  # the page has no WebGL2
            self.no_webgl()
        elif kind == "lang":
            self.lang = msg["lang"]
            self.set_words()
        elif kind == "scene":
            self.open_scene(msg["name"])
        elif kind == "save":
            saved = self.control.save(Path(msg["path"]))
            self.tell({"t": "saved", "path": str(saved)})
        elif kind == "upload":
            self.upload(Path(msg["path"]))
        elif kind == "thumb":
            self.conn.send_bytes(b"T" + jpeg(self.thumbnail(), 70))

    def tool(self, msg: dict) -> None:
        """A tool pressed (held at the point under the page's pointer: `world_at`), moved or let go."""
        from ..errors import SandboxError

        if msg["tool"] not in self.control.tool_names():
            self.tell({"t": "error", "text": f"this scene has no {msg['tool']} tool"})
            return
        centre = self.world_at(msg["x"], msg["y"])
        if not msg["down"] or centre is None:
            self.control.release()
            return
        try:
            self.control.press(msg["tool"], centre, float(msg["radius"]), msg.get("material"))
        except SandboxError as exc:
            self.tell({"t": "error", "text": str(exc)})

    def readouts(self) -> dict:
        """The panel's description now (panel.py: of the tab's own scene, `stats_now()`) and the sentence for screen
        readers."""
        from . import panel
        from .serve_words import legend

        stats = self.stats_now()
        return {
            "legend": legend(self.legend_source),
            "readouts": panel.as_json(self.control.readouts(stats)),
            "settings": panel.as_json(self.control.settings()),
            "summary": self.control.summary(stats),
            "probe": self.probe(),
        }

    def probe(self) -> dict | None:
        """The probe's reading of the particle under the page's pointer (of the tab's world), or None."""
        from .probe import particle_at, probe

        point = None if self.pointer is None else self.world_at(*self.pointer)
        i = None if point is None else particle_at(self.sim, point, world=self.world)
        return None if i is None else probe(self.sim, i).fields()

    def upload(self, path: Path) -> None:
        """Load a state file the page uploaded (the server wrote it to `path`): checked before anything changes;
        refused with the checker's one line, the scene running on."""
        from ..errors import SandboxError

        try:
            self.control.load(path)
        except (SandboxError, OSError, ValueError, KeyError) as exc:
            said = str(exc).replace(str(path), "the uploaded file")  # the server's folders are not the page's news
            self.tell({"t": "error", "key": "upload_refused", "text": said})
        else:
            self.tell({"t": "notice", "key": "uploaded", "text": f"t = {self.scene_time():.2f} s"})
        finally:
            path.unlink(missing_ok=True)
            self.tell({"t": "upload_done"})  # the server takes this tab's next upload only now
