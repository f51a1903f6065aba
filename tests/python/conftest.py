"""The fixtures of the Python client's tests: a real gvd-server on loopback for each test
module, and a client of it over gRPC and over HTTP (each test that takes one runs twice)."""
import os
import sys

import pytest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import gvd  # noqa: E402
from gvdtest import Server, read_ports  # noqa: E402

SERVER = os.environ.get("GVD_SERVER", "build/test/server/gvd-server")


@pytest.fixture(scope="module")
def server():
    s = Server(SERVER)
    grpc_port, _ = read_ports(os.path.join(s.dir, "ports"))
    s.targets = {"grpc": f"127.0.0.1:{grpc_port}", "http": s.url}
    yield s
    s.stop()


@pytest.fixture(params=["grpc", "http"])
def client(request, server):
    with gvd.Client(server.targets[request.param]) as c:
        c.kind = request.param
        yield c
