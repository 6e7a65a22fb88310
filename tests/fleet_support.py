"""Test helpers for fleets: a TCP link between the leaves' bridges and the hub that can be cut."""

from __future__ import annotations

import socket
import threading
from contextlib import suppress

from umlbot.fleet import free_port


class TcpLink:
    """Forwards 127.0.0.1:`port` to 127.0.0.1:`target`; `cut()` drops every connection at once
    (a Wi-Fi drop as the robot sees it), `down`/`up` refuse or accept new ones."""

    def __init__(self, target: int) -> None:
        self.target = target
        self.port = free_port()
        self._server = socket.create_server(("127.0.0.1", self.port))
        self._server.settimeout(0.1)
        self._lock = threading.Lock()
        self._sockets: list[socket.socket] = []
        self._closed = False
        self.is_up = True
        self.cuts = 0
        self._thread = threading.Thread(target=self._accept, name="tcp-link", daemon=True)
        self._thread.start()

    def _accept(self) -> None:
        while not self._closed:
            try:
                client, _ = self._server.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            if not self.is_up:
                client.close()
                continue
            try:
                upstream = socket.create_connection(("127.0.0.1", self.target), timeout=2)
            except OSError:
                client.close()
                continue
            for sock in (client, upstream):
                sock.settimeout(None)
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            with self._lock:
                self._sockets += [client, upstream]
            for a, b in ((client, upstream), (upstream, client)):
                threading.Thread(target=self._pump, args=(a, b), daemon=True).start()

    @staticmethod
    def _pump(src: socket.socket, dst: socket.socket) -> None:
        with suppress(OSError):
            while data := src.recv(65536):
                dst.sendall(data)
        for sock in (src, dst):
            with suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)

    def cut(self) -> None:
        """Drop every connection through the link now."""
        with self._lock:
            sockets, self._sockets = self._sockets, []
            self.cuts += 1
        for sock in sockets:
            with suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)
            sock.close()

    def down(self) -> None:
        self.is_up = False
        self.cut()

    def up(self) -> None:
        self.is_up = True

    def close(self) -> None:
        self._closed = True
        self.cut()
        self._server.close()
        self._thread.join(2)
