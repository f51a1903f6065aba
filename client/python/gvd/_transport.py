"""How calls reach gvd-server: gRPC (grpcio), or HTTP/1.1 with the Connect protocol and
binary protobuf bodies (a socket, and httptools' parser for the answers). Both take and give
the generated messages; both raise GvdError."""
from __future__ import annotations

import json
import re
import socket
import ssl
import struct
import sys
import threading
import urllib.parse
from typing import Dict, Iterator, Optional, Sequence, Tuple, Type, TypeVar

import grpc
import httptools
from google.protobuf.message import DecodeError, Message

SERVICE = "gvd.v1.VoronoiService"
M = TypeVar("M", bound=Message)


class GvdError(Exception):
    """A call that failed: `code` is its status (a grpc.StatusCode, the same over HTTP) and
    `message` the server's words."""

    def __init__(self, code: grpc.StatusCode, message: str):
        super().__init__(f"{code.name}: {message}")
        self.code = code
        self.message = message


# The Connect protocol's code names, to gRPC's.
_CONNECT_CODES = {c.value[1].replace(" ", "_"): c for c in grpc.StatusCode}


def _serialize(request) -> bytes:
    """A request's bytes: those given as they are, or the message's."""
    return request if isinstance(request, bytes) else request.SerializeToString()


class GrpcTransport:
    """A gRPC channel to `target` ("host:port", or any gRPC target such as "unix:/path")."""

    def __init__(self, target: str, *, token: Optional[str], root_certificates: Optional[bytes],
                 private_key: Optional[bytes], certificate_chain: Optional[bytes],
                 tls: bool, max_message_bytes: int):
        # No channelz: nothing in this process reads it, and its bookkeeping costs grpcio
        # five clock readings a call, each a system call in grpcio's build (it reads the
        # clocks by syscall(), not the vDSO): a one-call round trip took 7-8 µs less CPU
        # without it, 58-61 against 65-68 µs.
        options = [("grpc.max_receive_message_length", max_message_bytes),
                   ("grpc.max_send_message_length", max_message_bytes),
                   ("grpc.enable_channelz", 0)]
        if tls or root_certificates or certificate_chain:
            credentials = grpc.ssl_channel_credentials(root_certificates, private_key,
                                                       certificate_chain)
            self.channel = grpc.secure_channel(target, credentials, options)
        else:
            self.channel = grpc.insecure_channel(target, options)
        self.metadata: Sequence[Tuple[str, str]] = (
            [("authorization", f"Bearer {token}")] if token else [])
        # Each method's callable, made once: making one costs about as much as a small call.
        self._unary: Dict[Tuple[str, type], grpc.UnaryUnaryMultiCallable] = {}

    def unary(self, method: str, request: Optional[Message], response: Type[M],
              timeout: Optional[float], body: Optional[bytes] = None) -> M:
        """`request`'s call, or with `body` given, the call whose bytes it is (request unused)."""
        call = self._unary.get((method, response))
        if call is None:
            call = self.channel.unary_unary(f"/{SERVICE}/{method}", request_serializer=_serialize,
                                            response_deserializer=response.FromString)
            self._unary[(method, response)] = call
        try:
            return call(body if body is not None else request, timeout=timeout,
                        metadata=self.metadata)
        except grpc.RpcError as e:
            raise GvdError(e.code(), e.details() or "") from None

    def stream(self, method: str, request: Optional[Message], response: Type[M],
               timeout: Optional[float], body: Optional[bytes] = None) -> Iterator[M]:
        call = self.channel.unary_stream(
            f"/{SERVICE}/{method}",
            request_serializer=(lambda _: body) if body is not None else type(request).SerializeToString,
            response_deserializer=response.FromString)
        responses = call(request, timeout=timeout, metadata=self.metadata)
        try:
            yield from responses
        except grpc.RpcError as e:
            raise GvdError(e.code(), e.details() or "") from None
        finally:
            responses.cancel()

    def close(self) -> None:
        self.channel.close()


class HttpTransport:
    """HTTP/1.1 to `url` ("http://host:port" or "https://..."): the Connect protocol, bodies in
    binary protobuf, one keep-alive connection per thread.

    A request is written to the socket whole, and its response read by httptools' parser
    (http-parser, in C). Through the standard library's http.client, which parses each
    answer's headers with the email package, a one-point query took 0.10-0.13 ms on
    loopback, against 0.04-0.06 ms this way; a one-site move and its read, 0.64-0.71 ms over
    gRPC against 0.46-0.54 ms this way (tests/bench/postgis.py)."""

    def __init__(self, url: str, *, token: Optional[str], root_certificates: Optional[bytes],
                 private_key: Optional[bytes], certificate_chain: Optional[bytes], tls: bool,
                 max_message_bytes: int):
        del max_message_bytes  # the server's limit is the one that holds
        parsed = urllib.parse.urlsplit(url)
        if parsed.scheme not in ("http", "https") or not parsed.hostname:
            raise ValueError(f"an HTTP target is http://HOST:PORT or https://HOST:PORT, not {url!r}")
        https = parsed.scheme == "https" or tls
        self.host = parsed.hostname
        self.port = parsed.port or (443 if https else 80)
        self.prefix = parsed.path.rstrip("/")
        if not _PATH_SAFE.fullmatch(self.prefix):
            raise ValueError(f"an HTTP target's path holds no spaces or control characters: {url!r}")
        if token is not None and not _HEADER_SAFE.fullmatch(token):
            raise ValueError("a token holds no control characters (it is sent in a header)")
        self.context = None
        if https:
            self.context = ssl.create_default_context(
                cadata=root_certificates.decode() if root_certificates else None)
            if certificate_chain and private_key:
                self.context.load_cert_chain(*_temporary_pem(certificate_chain, private_key))
        host = f"[{self.host}]" if ":" in self.host else self.host
        if parsed.port is not None:
            host = f"{host}:{self.port}"
        # Every request's header lines but its method's path, type, length and deadline.
        self.fixed = (f"Host: {host}\r\nConnect-Protocol-Version: 1\r\n"
                      + (f"Authorization: Bearer {token}\r\n" if token else ""))
        self.local = threading.local()

    def _connect(self, method: str, timeout: Optional[float]) -> "_Connection":
        try:
            sock = socket.create_connection((self.host, self.port), timeout)
        except OSError as e:
            raise _transport_error(method, e) from None
        try:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            if self.context is not None:
                sock = self.context.wrap_socket(sock, server_hostname=self.host)
        except OSError as e:
            sock.close()
            raise _transport_error(method, e) from None
        return _Connection(sock)

    def _request(self, method: str, content_type: str, body: bytes,
                 timeout: Optional[float]) -> bytes:
        # The Connect protocol's header holds at most 10 digits (some 115 days).
        deadline = ("" if timeout is None else
                    f"Connect-Timeout-Ms: {max(1, int(min(timeout * 1000, 9_999_999_999)))}\r\n")
        return (f"POST {self.prefix}/{SERVICE}/{method} HTTP/1.1\r\n{self.fixed}"
                f"Content-Type: {content_type}\r\nContent-Length: {len(body)}\r\n{deadline}\r\n"
                ).encode("latin-1") + body

    def unary(self, method: str, request: Optional[Message], response: Type[M],
              timeout: Optional[float], body: Optional[bytes] = None) -> M:
        data = self._request(method, "application/proto",
                             body if body is not None else request.SerializeToString(), timeout)
        for attempt in range(2):
            conn = getattr(self.local, "conn", None)
            reused = conn is not None
            if conn is None:
                conn = self.local.conn = self._connect(method, timeout)
            try:
                conn.set_timeout(timeout)
                conn.send(data)
                answer = conn.read_response()
            except _Closed as e:
                self._drop(conn)
                # A kept-alive connection that the server had closed while idle: the request
                # never reached it, so once more on a new one. A new connection's failure is
                # the answer.
                if attempt == 1 or not reused:
                    raise GvdError(grpc.StatusCode.UNAVAILABLE, f"{method}: {e}") from None
                continue
            except OSError as e:
                self._drop(conn)
                raise _transport_error(method, e) from None
            except httptools.HttpParserError as e:
                self._drop(conn)
                raise GvdError(grpc.StatusCode.UNAVAILABLE,
                               f"{method}: the answer is not HTTP: {e}") from None
            if not answer.keep_alive:
                self._drop(conn)
            payload = b"".join(answer.body)
            if answer.status != 200:
                raise _error(answer.status, payload)
            return _parse(method, response, payload)
        raise AssertionError("unreachable")

    def _drop(self, conn: "_Connection") -> None:
        conn.close()
        if getattr(self.local, "conn", None) is conn:
            self.local.conn = None

    def stream(self, method: str, request: Optional[Message], response: Type[M],
               timeout: Optional[float], body: Optional[bytes] = None) -> Iterator[M]:
        """A server stream, on a connection of its own (calls made while it is read use the
        thread's): each Connect envelope (a flags byte, a 4-byte length, the message) is parsed
        as soon as its last byte has come."""
        raw = body if body is not None else request.SerializeToString()
        conn = self._connect(method, timeout)
        try:
            conn.set_timeout(timeout)
            conn.send(self._request(method, "application/connect+proto",
                                    struct.pack(">BI", 0, len(raw)) + raw, timeout))
            answer = _Answer()
            pending = bytearray()
            while True:
                more = conn.read_more(answer)
                pending += b"".join(answer.body)
                answer.body.clear()
                if answer.status != 200:
                    if more:
                        continue
                    raise _error(answer.status, bytes(pending))
                while len(pending) >= 5:
                    flags, n = struct.unpack_from(">BI", pending)
                    if len(pending) < 5 + n:
                        break
                    data = bytes(pending[5:5 + n])
                    del pending[:5 + n]
                    if flags & 0x02:  # the end of the stream: JSON, with the error if any
                        end = json.loads(data or b"{}")
                        if "error" in end:
                            raise _error(200, json.dumps(end["error"]).encode())
                        return
                    yield _parse(method, response, data)
                if not more:
                    raise GvdError(grpc.StatusCode.UNAVAILABLE,
                                   f"{method}: the stream ended without its end message")
        except (OSError, _Closed) as e:
            raise _transport_error(method, e) from None
        except httptools.HttpParserError as e:
            raise GvdError(grpc.StatusCode.UNAVAILABLE,
                           f"{method}: the answer is not HTTP: {e}") from None
        finally:
            conn.close()

    def close(self) -> None:
        conn = getattr(self.local, "conn", None)
        if conn is not None:
            self._drop(conn)


# Header values: printable ASCII and tabs (no CR or LF to end a header early); a path, printable
# ASCII without spaces (one would end it in the request line).
_HEADER_SAFE = re.compile(r"[\t\x20-\x7e]*")
_PATH_SAFE = re.compile(r"[\x21-\x7e]*")
# Bytes asked of the socket at a time, into the connection's own buffer.
_RECV_BYTES = 256 << 10
# Whether the kernel's timeouts serve plain sockets (_Connection): Linux's, whose timeval is
# two longs.
_KERNEL_TIMEOUTS = sys.platform.startswith("linux") and struct.calcsize("@l") == 8
# A request larger than this is sent under Python's timeout (_Connection).
_ONE_WRITE = 64 << 10


class _Closed(Exception):
    """The server closed the connection before the first byte of its answer."""


class _Answer:
    """One response as httptools' parser reports it: its status, the body's pieces as they
    come, whether it is whole and whether the connection stays open after it."""

    def __init__(self) -> None:
        self.parser = httptools.HttpResponseParser(self)
        self.status = 0
        self.body: list = []
        self.complete = False
        self.keep_alive = False
        self.messages = 0

    # httptools' callbacks.
    def on_message_begin(self) -> None:
        self.messages += 1

    def on_headers_complete(self) -> None:
        if self.messages == 1:
            self.status = self.parser.get_status_code()

    def on_body(self, data: bytes) -> None:
        if self.messages == 1:
            self.body.append(data)

    def on_message_complete(self) -> None:
        if self.messages == 1:
            self.complete = True
            self.keep_alive = self.parser.should_keep_alive()


class _Connection:
    """A socket to the server (TLS-wrapped for https) and a buffer to read it into.

    On Linux a plain socket blocks, and the kernel times out each of its reads and writes
    (SO_RCVTIMEO, SO_SNDTIMEO): under Python's own timeouts each read and write polls the
    socket first, a system call more, and a one-point move (an upsert and a read at its
    version, 1.5 ms apart) took 0.014-0.016 ms longer at the median. A request larger than a
    write or two is sent under Python's timeout, which bounds the whole request (the kernel's
    bounds each write). A TLS socket keeps Python's timeouts: the ssl module reads again
    after a read the kernel timed out, without end."""

    def __init__(self, sock: socket.socket):
        self.sock = sock
        self.buffer = bytearray(_RECV_BYTES)
        self.timeout = sock.gettimeout()
        self.kernel_timeouts = _KERNEL_TIMEOUTS and not isinstance(sock, ssl.SSLSocket)
        if self.kernel_timeouts:
            sock.settimeout(None)
            self.timeout = None

    def set_timeout(self, timeout: Optional[float]) -> None:
        """Each read's and write's timeout, set only when it changes (a system call or two)."""
        if timeout == self.timeout:
            return
        if not self.kernel_timeouts:
            self.sock.settimeout(timeout)
        else:
            if timeout is not None and not timeout >= 0:
                raise ValueError(f"a timeout is None or 0 seconds or more, not {timeout}")
            # None: no timeout (a zero timeval); else at least a microsecond (and at most
            # some 30 years, which the kernel takes as none).
            us = 0 if timeout is None else max(1, round(min(timeout, 1e9) * 1e6))
            value = struct.pack("@ll", us // 1_000_000, us % 1_000_000)
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVTIMEO, value)
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDTIMEO, value)
        self.timeout = timeout

    def send(self, data: bytes) -> None:
        """Writes a request whole; _Closed where the server had closed the connection."""
        whole = self.kernel_timeouts and self.timeout is not None and len(data) > _ONE_WRITE
        try:
            if whole:
                self.sock.settimeout(self.timeout)
            self.sock.sendall(data)
        except ConnectionError as e:
            raise _Closed(f"the server closed the connection ({e!r})") from None
        except BlockingIOError:  # the kernel's timeout
            raise TimeoutError("timed out") from None
        finally:
            if whole:
                self.sock.settimeout(None)

    def read_more(self, answer: _Answer) -> bool:
        """Feeds what the socket has to `answer`'s parser (waiting for at least a byte);
        False once the response is whole. _Closed where the server closed the connection
        before the response's first byte."""
        if answer.complete:
            return False
        try:
            n = self.sock.recv_into(self.buffer)
        except BlockingIOError:  # the kernel's timeout
            raise TimeoutError("timed out") from None
        except ConnectionError as e:
            if answer.messages == 0:
                raise _Closed(f"the server closed the connection ({e!r})") from None
            raise OSError(f"the server closed the connection mid-answer ({e!r})") from None
        if n == 0:
            if answer.messages == 0:
                raise _Closed("the server closed the connection")
            try:
                answer.parser.feed_data(b"")  # the end of a body that runs to the close
            except httptools.HttpParserError:
                pass
            if not answer.complete:
                raise OSError("the server closed the connection mid-answer")
            return False
        answer.parser.feed_data(memoryview(self.buffer)[:n])
        if answer.messages > 1:  # bytes past the response: the connection is not reused
            answer.keep_alive = False
        return not answer.complete

    def read_response(self) -> _Answer:
        answer = _Answer()
        while self.read_more(answer):
            pass
        return answer

    def close(self) -> None:
        self.sock.close()


def _transport_error(method: str, e: BaseException) -> GvdError:
    code = (grpc.StatusCode.DEADLINE_EXCEEDED if isinstance(e, TimeoutError)
            else grpc.StatusCode.UNAVAILABLE)
    return GvdError(code, f"{method}: {e!r}")


def _parse(method: str, response: Type[M], data: bytes) -> M:
    """An answer's message; INTERNAL where its bytes are not one."""
    try:
        return response.FromString(data)
    except (DecodeError, ValueError) as e:
        raise GvdError(grpc.StatusCode.INTERNAL, f"{method}: the answer is not a "
                                                 f"{response.__name__}: {e}") from e


def _error(status: int, payload: bytes) -> GvdError:
    """The Connect error in a response body (JSON: code and message)."""
    try:
        err = json.loads(payload)
        code = _CONNECT_CODES.get(err.get("code", ""), grpc.StatusCode.UNKNOWN)
        return GvdError(code, err.get("message", ""))
    except ValueError:
        return GvdError(grpc.StatusCode.UNKNOWN,
                        f"HTTP {status}: {payload[:200].decode(errors='replace')}")


def _temporary_pem(chain: bytes, key: bytes) -> Tuple[str, str]:
    """ssl wants files: the certificate chain and key written to private temporary ones."""
    import tempfile  # pylint: disable=import-outside-toplevel
    paths = []
    for data in (chain, key):
        with tempfile.NamedTemporaryFile("wb", delete=False, suffix=".pem") as f:
            f.write(data)
            paths.append(f.name)
    return paths[0], paths[1]
