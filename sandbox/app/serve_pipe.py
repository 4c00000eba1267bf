"""The pipe between the classroom server and a host (serve_host.py, serve_worlds.py): every message carries the
index of the tab's place it is for (its *slot*) in two bytes before it, HOST for the host's own."""

from __future__ import annotations

import struct

SLOT = struct.Struct("<H")  # the slot index before every message, both ways
HOST = 0xFFFF  # ... and the index of the host's own messages


class SlotConn:
    """A session's end of the host's pipe: what it sends goes out after its slot's index, and nothing while no tab
    has the session (`muted`: while it is built, and after its tab has gone)."""

    def __init__(self, conn, slot: int) -> None:
        self.conn, self.prefix, self.muted = conn, SLOT.pack(slot), True

    def send_bytes(self, data: bytes) -> None:
        if not self.muted:
            self.conn.send_bytes(self.prefix + data)
