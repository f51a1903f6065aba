"""The Python client's HTTP transport where the connection, not the call, goes wrong: a kept-alive
connection that a real server closed (it restarted) is made anew and the call goes through;
against a peer of the test's own, an answer that is not HTTP, one cut short, a close before
any answer on a new connection, and an answer that never comes are each the status a caller
can act on, and the connection is not used again."""
import socket
import threading
import time

import pytest

import gvd

from conftest import SERVER
from gvdtest import Server


def test_a_kept_alive_connection_the_server_closed_is_made_anew():
    first = Server(SERVER)
    port = first.http_port
    second = None
    try:
        with gvd.Client(first.url, timeout=60) as c:
            c.create_scene("before", window=(0, 0, 1, 1), size=(64, 64))
            assert [s.scene_id for s in c.list_scenes()] == ["before"]  # on the kept connection
            first.stop()
            first = None
            second = Server(SERVER, "--http-listen", f"127.0.0.1:{port}")
            # The old connection is closed at the other end; the call is sent once more, on
            # a new connection, to the new server (whose store is empty).
            assert [s.scene_id for s in c.list_scenes()] == []
            c.create_scene("after", window=(0, 0, 1, 1), size=(64, 64))
            assert [s.scene_id for s in c.list_scenes()] == ["after"]
    finally:
        for s in (first, second):
            if s:
                s.stop()


class Peer:
    """A listening socket on loopback whose every connection is answered by `answer(conn,
    request_bytes)`; counts the connections."""

    def __init__(self, answer):
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        self.connections = 0
        self.answer = answer
        self.held = []
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self):
        while True:
            try:
                conn, _ = self.listener.accept()
            except OSError:
                return
            self.connections += 1
            self.held.append(conn)
            request = b""
            while b"\r\n\r\n" not in request:
                chunk = conn.recv(65536)
                if not chunk:
                    break
                request += chunk
            self.answer(conn, request)

    def close(self):
        self.listener.close()
        for conn in self.held:
            conn.close()


def close(conn, _request):
    conn.close()


@pytest.mark.parametrize("answer,code,words", [
    (lambda conn, _: conn.sendall(b"SSH-2.0-OpenSSH_9.2\r\n\r\n"), "UNAVAILABLE", "not HTTP"),
    (lambda conn, _: (conn.sendall(b"HTTP/1.1 200 OK\r\nContent-Length: 100\r\n\r\nabc"),
                      conn.close()), "UNAVAILABLE", "mid-answer"),
    (close, "UNAVAILABLE", "closed the connection"),
    (lambda conn, _: None, "DEADLINE_EXCEEDED", "timed out"),
])
def test_a_broken_connection_is_a_status_and_is_not_used_again(answer, code, words):
    peer = Peer(answer)
    try:
        with gvd.Client(f"http://127.0.0.1:{peer.port}", timeout=1) as c:
            for tries in (1, 2):
                started = time.monotonic()
                with pytest.raises(gvd.GvdError) as e:
                    c.list_scenes()
                assert e.value.code.name == code, e.value
                assert words in str(e.value), e.value
                assert time.monotonic() - started < 30
                # A new connection each time: a failed one is not kept (and a failure on a
                # new connection is not tried again).
                assert peer.connections == tries
    finally:
        peer.close()
