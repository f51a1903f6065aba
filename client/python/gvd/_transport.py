"""How calls reach gvd-server: gRPC (grpcio), or HTTP with the Connect protocol and binary
protobuf bodies (the standard library's http.client). Both take and give the generated
messages; both raise GvdError."""
from __future__ import annotations

import http.client
import json
import ssl
import struct
import threading
import urllib.parse
from typing import Dict, Iterator, Optional, Sequence, Tuple, Type, TypeVar

import grpc
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
        options = [("grpc.max_receive_message_length", max_message_bytes),
                   ("grpc.max_send_message_length", max_message_bytes)]
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

    def unary(self, method: str, request: Message, response: Type[M],
              timeout: Optional[float], body: Optional[bytes] = None) -> M:
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

    def stream(self, method: str, request: Message, response: Type[M],
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
    binary protobuf, one keep-alive connection per thread."""

    def __init__(self, url: str, *, token: Optional[str], root_certificates: Optional[bytes],
                 private_key: Optional[bytes], certificate_chain: Optional[bytes], tls: bool,
                 max_message_bytes: int):
        del max_message_bytes  # the server's limit is the one that holds
        parsed = urllib.parse.urlsplit(url)
        if parsed.scheme not in ("http", "https") or not parsed.hostname:
            raise ValueError(f"an HTTP target is http://HOST:PORT or https://HOST:PORT, not {url!r}")
        self.https = parsed.scheme == "https" or tls
        self.host = parsed.hostname
        self.port = parsed.port or (443 if self.https else 80)
        self.prefix = parsed.path.rstrip("/")
        self.context = None
        if self.https:
            self.context = ssl.create_default_context(
                cadata=root_certificates.decode() if root_certificates else None)
            if certificate_chain and private_key:
                self.context.load_cert_chain(*_temporary_pem(certificate_chain, private_key))
        self.headers = {"Connect-Protocol-Version": "1"}
        if token:
            self.headers["Authorization"] = f"Bearer {token}"
        self.local = threading.local()

    def _new_connection(self) -> http.client.HTTPConnection:
        if self.https:
            return http.client.HTTPSConnection(self.host, self.port, context=self.context)
        return http.client.HTTPConnection(self.host, self.port)

    def _connection(self, timeout: Optional[float]) -> http.client.HTTPConnection:
        conn = getattr(self.local, "conn", None)
        if conn is None:
            conn = self._new_connection()
            self.local.conn = conn
        conn.timeout = timeout
        if conn.sock is not None:
            conn.sock.settimeout(timeout)
        return conn

    def _post(self, method: str, content_type: str, body: bytes,
              timeout: Optional[float]) -> http.client.HTTPResponse:
        headers = dict(self.headers, **{"Content-Type": content_type})
        if timeout is not None:
            headers["Connect-Timeout-Ms"] = str(max(1, int(timeout * 1000)))
        for attempt in range(2):
            conn = self._connection(timeout)
            reused = getattr(conn, "gvd_used", False)
            try:
                conn.request("POST", f"{self.prefix}/{SERVICE}/{method}", body, headers)
                answer = conn.getresponse()
                conn.gvd_used = True
                return answer
            except (ConnectionError, http.client.RemoteDisconnected, http.client.BadStatusLine) as e:
                conn.close()
                self.local.conn = None
                # A kept-alive connection that the server had closed while idle: the request
                # never reached it, so once more on a new one. A new connection's failure is
                # the answer.
                if attempt == 1 or not reused:
                    raise GvdError(grpc.StatusCode.UNAVAILABLE, f"{method}: {e!r}") from None
            except OSError as e:
                conn.close()
                self.local.conn = None
                code = (grpc.StatusCode.DEADLINE_EXCEEDED if isinstance(e, TimeoutError)
                        else grpc.StatusCode.UNAVAILABLE)
                raise GvdError(code, f"{method}: {e!r}") from None
        raise AssertionError("unreachable")

    def unary(self, method: str, request: Message, response: Type[M],
              timeout: Optional[float], body: Optional[bytes] = None) -> M:
        answer = self._post(method, "application/proto",
                            body if body is not None else request.SerializeToString(), timeout)
        payload = answer.read()
        if answer.status != 200:
            raise _error(answer.status, payload)
        return _parse(method, response, payload)

    def stream(self, method: str, request: Message, response: Type[M],
               timeout: Optional[float], body: Optional[bytes] = None) -> Iterator[M]:
        """A server stream, on a connection of its own (calls made while it is read use the
        thread's)."""
        raw = body if body is not None else request.SerializeToString()
        conn = self._new_connection()
        conn.timeout = timeout
        headers = dict(self.headers, **{"Content-Type": "application/connect+proto"})
        if timeout is not None:
            headers["Connect-Timeout-Ms"] = str(max(1, int(timeout * 1000)))
        try:
            conn.request("POST", f"{self.prefix}/{SERVICE}/{method}",
                         struct.pack(">BI", 0, len(raw)) + raw, headers)
            answer = conn.getresponse()
        except OSError as e:
            conn.close()
            code = (grpc.StatusCode.DEADLINE_EXCEEDED if isinstance(e, TimeoutError)
                    else grpc.StatusCode.UNAVAILABLE)
            raise GvdError(code, f"{method}: {e!r}") from None
        if answer.status != 200:
            payload = answer.read()
            conn.close()
            raise _error(answer.status, payload)
        try:
            while True:
                head = answer.read(5)
                if len(head) < 5:
                    raise GvdError(grpc.StatusCode.UNAVAILABLE,
                                   f"{method}: the stream ended without its end message")
                flags, n = struct.unpack(">BI", head)
                data = answer.read(n)
                if flags & 0x02:  # the end of the stream: JSON, with the error if any
                    end = json.loads(data or b"{}")
                    if "error" in end:
                        raise _error(200, json.dumps(end["error"]).encode())
                    return
                yield _parse(method, response, data)
        finally:
            conn.close()

    def close(self) -> None:
        conn = getattr(self.local, "conn", None)
        if conn is not None:
            conn.close()
            self.local.conn = None


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
