#!/usr/bin/python3
"""A million query points from NumPy to NumPy answers through the Python client (gRPC and
HTTP), beside the raw grpcio stub with a hand-built request and beside scipy's cKDTree in
process, on one scene of random points, in the same run.

Usage: python_client.py GVD_SERVER [--sites N] [--points M] [--repeat R] [--json FILE]
(run with a Python that has the gvd package: tests/python/run.sh builds such a venv).

Each figure is the best of R runs of one call of M points, raster answers (the client's
default), and the exact ones. The raw stub sends FindNearestStream the same packed request,
serialized by protobuf, and keeps the response messages as they come (no arrays): the
client's overhead is the difference.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import grpc
import numpy as np
from scipy.spatial import cKDTree

import gvd
from gvd.v1 import voronoi_pb2 as pb

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from gvdtest import read_ports, start_server  # noqa: E402  pylint: disable=wrong-import-position


def best(fn, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("server")
    ap.add_argument("--sites", type=int, default=10_000)
    ap.add_argument("--points", type=int, default=1_000_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json")
    args = ap.parse_args()
    work = tempfile.mkdtemp(prefix="gvd-pybench-")
    with open(os.path.join(work, "log"), "w") as log:
        proc, http_port = start_server(args.server, os.path.join(work, "data"),
                                       os.path.join(work, "ports"), log, "--log-level", "warn")
    grpc_port = read_ports(os.path.join(work, "ports"))[0]
    try:
        rng = np.random.default_rng(1)
        xy = rng.random((args.sites, 2))
        q = rng.random((args.points, 2))
        ids = [str(i) for i in range(args.sites)]
        figures = {}
        with gvd.Client(f"127.0.0.1:{grpc_port}", timeout=600) as c:
            c.create_scene("bench", window=(0, 0, 1, 1), size=(1024, 1024))
            v = c.upsert_points("bench", ids, xy)
            c.find_nearest("bench", q[:10], min_version=v)  # rendered
            for exact in (False, True):
                name = "exact" if exact else "raster"
                figures[f"client_grpc_{name}_s"] = best(
                    lambda: c.find_nearest("bench", q, exact=exact), args.repeat)
                with gvd.Client(f"http://127.0.0.1:{http_port}", timeout=600) as h:
                    figures[f"client_http_{name}_s"] = best(
                        lambda: h.find_nearest("bench", q, exact=exact), args.repeat)
                channel = grpc.insecure_channel(f"127.0.0.1:{grpc_port}", options=[
                    ("grpc.max_receive_message_length", -1), ("grpc.max_send_message_length", -1)])
                stream = channel.unary_stream(
                    "/gvd.v1.VoronoiService/FindNearestStream",
                    request_serializer=pb.FindNearestStreamRequest.SerializeToString,
                    response_deserializer=pb.FindNearestStreamResponse.FromString)

                def raw():
                    request = pb.FindNearestStreamRequest(scene_id="bench", exact=exact,
                                                          chunk_size=65536)
                    request.xy.extend(q.ravel().tolist())
                    return list(stream(request, timeout=600))
                figures[f"raw_stub_{name}_s"] = best(raw, args.repeat)
                channel.close()
        figures["ckdtree_build_s"] = best(lambda: cKDTree(xy), args.repeat)
        tree = cKDTree(xy)
        figures["ckdtree_query_1_worker_s"] = best(lambda: tree.query(q), args.repeat)
        figures["ckdtree_query_all_workers_s"] = best(lambda: tree.query(q, workers=-1),
                                                      args.repeat)
        for k, val in figures.items():
            print(f"{k:32s} {val:8.3f}  ({args.points / val / 1e6:6.2f} M points/s)")
        if args.json:
            with open(args.json, "w", encoding="ascii") as f:
                json.dump(dict(figures, sites=args.sites, points=args.points), f, indent=1)
    finally:
        proc.terminate()
        proc.wait()
        subprocess.run(["rm", "-rf", work], check=False)


if __name__ == "__main__":
    main()
