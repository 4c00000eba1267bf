"""`sandbox serve`: its arguments, checked in one line each, then the classroom server (app/serve_routes.py)."""

from __future__ import annotations

import re

from ..config.resources import shipped_scenes
from ..config.schema import unknown
from ..errors import SandboxError
from .serve_session import DRAWS


def serve_arguments(sub) -> None:
    """`sandbox serve`'s arguments."""
    serve = sub.add_parser("serve", help="the classroom in a browser: serve the sandbox to a room of browsers")
    serve.add_argument("scene", nargs="?", default="melting_block", help="the scene a new tab opens (shipped name)")
    serve.add_argument("--host", default="127.0.0.1", help="address to listen on (other than loopback: needs a token)")
    serve.add_argument("--port", type=int, default=8000)
    serve.add_argument("--token", help="the token every request must carry (made up and printed when needed)")
    serve.add_argument(
        "--teacher-token", help="the teacher's secret, for /teacher and its routes (made up and printed when not given)"
    )
    serve.add_argument(
        "--max-sessions",
        type=int,
        default=30,
        help="browser tabs served at once (a class; 30 tabs of melting_block take about 1.5 GB)",
    )
    serve.add_argument(
        "--warm",
        type=int,
        metavar="N",
        help="sessions of the scene kept built ahead of the tabs, so a class joins at once (default: --max-sessions)",
    )
    serve.add_argument(
        "--per-client",
        type=int,
        default=2,
        metavar="N",
        help="sessions one browser (its address or cookie) may hold at once, so no student fills the class (0: no "
        "limit; raise it where a class shares one address)",
    )
    serve.add_argument(
        "--idle", type=float, default=300.0, metavar="SECONDS", help="a tab silent this long loses its session (60+)"
    )
    serve.add_argument("--max-fps", type=float, default=30.0, help="pictures a second a tab gets at most (1 to 60)")
    serve.add_argument(
        "--no-worlds",
        dest="worlds",
        action="store_false",
        help="give every tab a simulation of its own (hosts of sessions), even where its scene can run as the worlds "
        "of one simulation (the default: a scene's tabs are its worlds)",
    )
    draw_argument(
        serve, "who draws a 2D scene's particles: the page (particle frames: light on the server) or the server (JPEG)"
    )
    serve.set_defaults(func=cmd_serve)


def draw_argument(parser, words: str) -> None:
    """The `--draw page|server` option (serve_session.DRAWS) of `sandbox serve` and `sandbox bench --serve`."""
    parser.add_argument("--draw", choices=DRAWS, default="page", help=words)


def cmd_serve(args) -> int:
    names = sorted(p.stem for p in shipped_scenes())
    if args.scene not in names:
        raise SandboxError(unknown("scene", args.scene, names) + " (the classroom serves shipped scenes)")
    if not 0 < args.port < 65536:
        raise SandboxError(f"--port: expected 1 to 65535, got {args.port}")
    if args.max_sessions < 1:
        raise SandboxError(f"--max-sessions: expected at least 1, got {args.max_sessions}")
    if args.warm is not None and args.warm < 0:
        raise SandboxError(f"--warm: expected 0 or more sessions, got {args.warm}")
    if args.per_client < 0:
        raise SandboxError(f"--per-client: expected 0 (no limit) or more sessions, got {args.per_client}")
    if not 60.0 <= args.idle <= 86400.0:
        raise SandboxError(f"--idle: expected 60 to 86400 seconds, got {args.idle:g}")
    if not 1.0 <= args.max_fps <= 60.0:
        raise SandboxError(f"--max-fps: expected 1 to 60, got {args.max_fps:g}")
    for option, value in (("--token", args.token), ("--teacher-token", args.teacher_token)):
        if value is not None and (len(value) < 8 or not re.fullmatch(r"[A-Za-z0-9_-]+", value)):
            raise SandboxError(f"{option}: expected at least 8 characters, each a letter, a digit, '-' or '_'")
    if args.token is not None and args.token == args.teacher_token:
        raise SandboxError("--teacher-token: the same as --token; expected a secret of the teacher's own")
    try:
        from .serve_routes import serve
    except ImportError as exc:
        missing = f"sandbox serve needs the serve extra: pip install -e '.[serve]' ({exc.name} is missing)"
        raise SandboxError(missing) from None
    return serve(
        args.scene,
        args.host,
        args.port,
        args.token,
        args.max_sessions,
        args.max_fps,
        args.teacher_token,
        args.warm,
        args.draw,
        args.per_client,
        args.idle,
        args.worlds,
    )
