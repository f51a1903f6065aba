"""The Python client's HTTP transport where the connection, not the call, goes wrong: a kept-alive
connection that a real server closed (it restarted) is made anew and the call goes through;
against a peer of the test's own, an answer that is not HTTP, one cut short, a close before
any answer on a new connection, and an answer that never comes are each the status a caller
can act on, and the connection is not used again. Over TLS, calls and streams reach a server
whose certificate chains to the CA given, and fail against one it does not."""
import socket
import subprocess
import threading
import time

import numpy as np
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
            # The whole request, its body too: a socket closed with bytes unread resets
            # the connection rather than ending it.
            request = b""
            while b"\r\n\r\n" not in request or len(request) < self._length(request):
                chunk = conn.recv(65536)
                if not chunk:
                    break
                request += chunk
            self.answer(conn, request)

    @staticmethod
    def _length(request):
        head, _, _ = request.partition(b"\r\n\r\n")
        for line in head.split(b"\r\n"):
            name, _, value = line.partition(b":")
            if name.strip().lower() == b"content-length":
                return len(head) + 4 + int(value)
        return len(head) + 4

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


@pytest.fixture(scope="module")
def tls_server(tmp_path_factory):
    """A server speaking TLS with a certificate for 127.0.0.1 from a CA of the test's own."""
    d = tmp_path_factory.mktemp("tls")
    ec = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"]
    (d / "san.ext").write_text("subjectAltName=IP:127.0.0.1\n")
    for command in (["openssl", "req", "-x509", *ec, "-keyout", "ca.key", "-out", "ca.pem",
                     "-days", "2", "-subj", "/CN=gvd-test-ca"],
                    ["openssl", "req", *ec, "-keyout", "server.key", "-out", "server.csr",
                     "-subj", "/CN=127.0.0.1"],
                    ["openssl", "x509", "-req", "-in", "server.csr", "-CA", "ca.pem", "-CAkey",
                     "ca.key", "-CAcreateserial", "-out", "server.pem", "-days", "2",
                     "-extfile", "san.ext"]):
        subprocess.run(command, cwd=d, check=True, capture_output=True)
    s = Server(SERVER, "--tls-cert", str(d / "server.pem"), "--tls-key", str(d / "server.key"))
    s.ca = (d / "ca.pem").read_bytes()
    yield s
    s.stop()


def test_https_calls_and_streams_check_the_servers_certificate(tls_server):
    url = f"https://127.0.0.1:{tls_server.http_port}"
    with gvd.Client(url, root_certificates=tls_server.ca, timeout=60) as c:
        c.create_scene("tls", window=(0, 0, 1, 1), size=(64, 64))
        v = c.upsert_points("tls", ["a", "b"], [[0.25, 0.5], [0.75, 0.5]])
        r = c.find_nearest("tls", [[0.2, 0.5], [0.9, 0.4]], min_version=v)
        assert r.site_ids.tolist() == ["a", "b"]
        # A batch past one chunk, followed, comes as a stream, on a TLS connection of its own.
        q = np.random.default_rng(3).random((gvd._client.CHUNK_POINTS + 5, 2))
        steps = []
        r = c.find_nearest("tls", q, min_version=v, progress=lambda done, n: steps.append(done))
        assert steps == [gvd._client.CHUNK_POINTS, len(q)]
        assert r.site_ids.tolist() == np.where(q[:, 0] < 0.5, "a", "b").tolist()
    # Without the CA the certificate is not trusted: the call fails, naming why.
    with gvd.Client(url, timeout=60) as c:
        with pytest.raises(gvd.GvdError) as e:
            c.list_scenes()
        assert e.value.code.name == "UNAVAILABLE"
        assert "CERTIFICATE_VERIFY_FAILED" in str(e.value), e.value
