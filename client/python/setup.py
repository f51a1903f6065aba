"""Builds the package, generating its protobuf messages from proto/ with protoc: the
repository's ../../proto, or the directory GVD_PROTO_DIR names."""
import os
import shutil
import subprocess

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = os.path.dirname(os.path.abspath(__file__))
PROTO = "gvd/v1/voronoi.proto"


def proto_dir():
    for d in (os.environ.get("GVD_PROTO_DIR"), os.path.join(HERE, "..", "..", "proto"),
              os.path.join(HERE, "proto")):
        if d and os.path.exists(os.path.join(d, PROTO)):
            return d
    raise SystemExit(f"gvd: {PROTO} not found: build from the repository, or set GVD_PROTO_DIR")


def protoc(args):
    """protoc from PATH (Debian's protobuf-compiler), else grpc_tools' bundled one."""
    if shutil.which("protoc"):
        subprocess.run(["protoc", *args], check=True)
        return
    try:
        from grpc_tools import protoc as bundled  # pylint: disable=import-outside-toplevel
    except ImportError as e:
        raise SystemExit("gvd: no protoc (Debian: apt-get install protobuf-compiler; or pip "
                         "install grpcio-tools)") from e
    if bundled.main(["protoc", *args]) != 0:
        raise SystemExit("gvd: protoc failed")


class BuildWithMessages(build_py):
    """Writes gvd/v1/voronoi_pb2.py into the build, from the .proto."""

    def run(self):
        super().run()
        protoc(["-I", proto_dir(), "--python_out", self.build_lib, PROTO])


setup(cmdclass={"build_py": BuildWithMessages})
