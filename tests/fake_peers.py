"""Fake Dask schedulers on loopback (test helper): a TCP server that accepts and then stays silent, or
answers every connection with fixed bytes (an HTTP server, garbage)."""
from __future__ import annotations

import socket
import threading

#: What a peer that is no Dask scheduler says on connecting.
REPLIES = {"silent": None,
           "http": b"HTTP/1.1 200 OK\r\nContent-Length: 5\r\n\r\nhello" * 4,
           "garbage": bytes(range(256)) * 8}


class FakeScheduler:
    """Listens on 127.0.0.1 (a free port); `address` is its tcp:// address."""

    def __init__(self, reply: bytes | None):
        self.reply, self.server = reply, socket.create_server(("127.0.0.1", 0))
        self.address = f"tcp://127.0.0.1:{self.server.getsockname()[1]}"
        self.connections: list = []
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self.server.accept()
            except OSError:
                return
            self.connections.append(conn)
            if self.reply is not None:
                conn.sendall(self.reply)

    def close(self) -> None:
        self.server.close()
        for c in self.connections:
            c.close()
