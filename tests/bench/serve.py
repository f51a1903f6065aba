#!/usr/bin/python3
"""What users wait for, through a real gvd-server and a stock Python grpcio client, beside
what they would use instead (OpenCV, scipy) in the same run.

Usage: serve.py GVD_SERVER [--points N] [--size PX] [--queries N] [--moves N] [--json FILE]

Starts GVD_SERVER on loopback with its default flags and a store on disk (acknowledged means
committed), then measures:
  - bulk load: one UpsertSites of N points into a new scene (serialized beforehand), until
    acknowledged, and until a FindNearest with min_version is answered (the frame is
    published); their ids decimal, then (into another scene) 32 random hex digits;
  - one-site move: UpsertSites of one point, then FindNearest with min_version at the new
    position (the round trip to a published frame), repeated, SYNC and RELAXED, beside the
    disk's floor (a 4 KiB append and fdatasync, in a loop);
  - one-site upserts from 1 and from 8 concurrent writers, each on a scene of its own;
  - one packed FindNearest (`xy`) of Q random points, raster answers and exact answers, with
    the default columns, with the site and distance alone (`fields`), and with the closest
    point and the gradient added to them.
References: OpenCV's distanceTransformWithLabels (DIST_L2, DIST_MASK_PRECISE, labels per
pixel) on the points snapped to the grid, scipy's cKDTree build and query (one worker and
all cores).
"""
import argparse
import json
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time

import cv2
import grpc
import numpy as np
from scipy.spatial import cKDTree

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def load_messages(workdir):
    """Compiles voronoi.proto to Python messages with protoc; the RPCs are called by name."""
    subprocess.run(["protoc", "-I", os.path.join(ROOT, "proto"), "--python_out", workdir,
                    "gvd/v1/voronoi.proto"], check=True)
    sys.path.insert(0, workdir)
    from gvd.v1 import voronoi_pb2  # pylint: disable=import-outside-toplevel
    return voronoi_pb2


class Voronoi:
    """The gvd.v1.VoronoiService calls this script makes."""

    def __init__(self, channel, pb):
        def call(name, request, response):
            return channel.unary_unary("/gvd.v1.VoronoiService/" + name,
                                       request_serializer=request.SerializeToString,
                                       response_deserializer=response.FromString)
        self.CreateScene = call("CreateScene", pb.CreateSceneRequest, pb.CreateSceneResponse)
        self.UpsertSites = call("UpsertSites", pb.UpsertSitesRequest, pb.UpsertSitesResponse)
        # Takes the request already serialized: times the server, not the client's encoder.
        self.UpsertSitesBytes = channel.unary_unary(
            "/gvd.v1.VoronoiService/UpsertSites", request_serializer=lambda body: body,
            response_deserializer=pb.UpsertSitesResponse.FromString)
        self.FindNearest = call("FindNearest", pb.FindNearestRequest, pb.FindNearestResponse)
        self.DeleteScene = call("DeleteScene", pb.DeleteSceneRequest, pb.DeleteSceneResponse)
        self.WatchScene = channel.unary_stream(
            "/gvd.v1.VoronoiService/WatchScene",
            request_serializer=pb.WatchSceneRequest.SerializeToString,
            response_deserializer=pb.WatchSceneResponse.FromString)


def start_server(binary, workdir, store=None):
    """Starts gvd-server with its store in workdir (or `store`, a --store URL); returns the
    process and its gRPC address."""
    os.makedirs(workdir, exist_ok=True)
    port_file = os.path.join(workdir, "port")
    where = ["--store", store] if store else ["--data", os.path.join(workdir, "store")]
    server = subprocess.Popen([binary, "--listen", "127.0.0.1:0", "--port-file", port_file,
                               *where, "--log-level", os.environ.get("GVD_LOG", "warn")])
    deadline = time.monotonic() + 60
    while not (os.path.exists(port_file) and os.path.getsize(port_file) > 0):
        if server.poll() is not None or time.monotonic() > deadline:
            raise SystemExit("gvd-server did not start")
        time.sleep(0.05)
    with open(port_file, encoding="ascii") as f:
        return server, "127.0.0.1:" + f.read().strip()


def best(fn, repeat):
    """The least time of `repeat` calls of fn, in seconds, and fn's last result."""
    times, result = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
    return min(times), result


def opencv_labels(points, size):
    """OpenCV's exact labelled distance transform of the points snapped to size x size pixels."""
    image = np.ones((size, size), np.uint8)
    px = np.clip((points * size).astype(np.int64), 0, size - 1)
    image[px[:, 1], px[:, 0]] = 0
    cv2.setNumThreads(1)
    return lambda: cv2.distanceTransformWithLabels(image, cv2.DIST_L2, cv2.DIST_MASK_PRECISE,
                                                   labelType=cv2.DIST_LABEL_PIXEL)


def concurrent_upserts(api, pb, writers, writes):
    """Seconds per acknowledged one-site upsert with `writers` threads, each on a 256x256
    scene of its own."""
    for w in range(writers):
        create = pb.CreateSceneRequest(scene_id=f"w{writers}-{w}", width_px=256, height_px=256)
        create.window.max_x = 1
        create.window.max_y = 1
        api.CreateScene(create)

    def write(w):
        rng = np.random.default_rng(100 + w)
        move = pb.UpsertSitesRequest(scene_id=f"w{writers}-{w}")
        site = move.sites.add()
        for k in range(writes):
            site.id = str(k % 50)
            site.point.x, site.point.y = rng.random(2)
            api.UpsertSites(move)

    threads = [threading.Thread(target=write, args=(w,)) for w in range(writers)]
    t0 = time.perf_counter()
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return (time.perf_counter() - t0) / (writers * writes)


def fdatasync_floor(directory, n):
    """The median of n appends of 4 KiB to a file, each followed by fdatasync: what one
    durable commit costs at least on this disk."""
    path = os.path.join(directory, "fdatasync-floor")
    fd = os.open(path, os.O_WRONLY | os.O_CREAT, 0o600)
    try:
        block = os.urandom(4096)
        times = []
        for _ in range(n):
            t0 = time.perf_counter()
            os.write(fd, block)
            os.fdatasync(fd)
            times.append(time.perf_counter() - t0)
        return statistics.median(times)
    finally:
        os.close(fd)
        os.unlink(path)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("server")
    ap.add_argument("--points", type=int, default=100_000)
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--queries", type=int, default=1_000_000)
    ap.add_argument("--moves", type=int, default=300)
    ap.add_argument("--writes", type=int, default=200, help="upserts per concurrent writer")
    ap.add_argument("--json", help="also write the figures here")
    args = ap.parse_args()

    rng = np.random.default_rng(1)
    points = rng.random((args.points, 2))
    queries = rng.random((args.queries, 2))
    workdir = tempfile.mkdtemp(prefix="gvd-serve-")
    pb = load_messages(workdir)
    server, address = start_server(args.server, workdir)
    rows = []
    try:
        channel = grpc.insecure_channel(address, options=[
            ("grpc.max_send_message_length", 1 << 30),
            ("grpc.max_receive_message_length", 1 << 30)])
        api = Voronoi(channel, pb)
        create = pb.CreateSceneRequest(scene_id="load", width_px=args.size, height_px=args.size)
        create.window.max_x = 1
        create.window.max_y = 1
        api.CreateScene(create)
        upsert = pb.UpsertSitesRequest(scene_id="load")
        for i, (x, y) in enumerate(points):
            site = upsert.sites.add(id=str(i))
            site.point.x = x
            site.point.y = y
        body = upsert.SerializeToString()
        print(f"gvd-server at {address}; UpsertSites of {args.points} points: "
              f"{len(body) / 1e6:.1f} MB", file=sys.stderr)

        # Bulk load, until acknowledged and until a query can read the frame (the request
        # serialized beforehand).
        def bulk_load(scene_id, body):
            t0 = time.perf_counter()
            version = api.UpsertSitesBytes(body).version
            acked = time.perf_counter() - t0
            probe = pb.FindNearestRequest(scene_id=scene_id, min_version=version)
            probe.points.add(x=0.5, y=0.5)
            api.FindNearest(probe, timeout=600)
            return acked, time.perf_counter() - t0
        acked, queryable = bulk_load("load", body)
        cv_full, _ = best(opencv_labels(points, args.size), 5)
        kd_build, tree = best(lambda: cKDTree(points), 5)
        rows.append(("bulk load, until acknowledged", acked, None))
        rows.append(("bulk load, until queryable", queryable, cv_full))
        # The same points named by 32 random hex digits, as UUIDs would name them, into a
        # scene of their own, dropped afterwards (the ids from a generator of their own).
        create.scene_id = "load-hex"
        api.CreateScene(create)
        upsert.scene_id = "load-hex"
        ids = np.random.default_rng(2)  # the moves' positions below stay as they were
        for site in upsert.sites:
            site.id = ids.bytes(16).hex()
        acked, queryable = bulk_load("load-hex", upsert.SerializeToString())
        rows.append(("bulk load, random hex ids, until acknowledged", acked, None))
        rows.append(("bulk load, random hex ids, until queryable", queryable, cv_full))
        api.DeleteScene(pb.DeleteSceneRequest(scene_id="load-hex"))
        rows.append(("scipy cKDTree build", kd_build, None))

        # One-site moves, each until a query at the new position sees it: SYNC (answered once
        # on disk) and RELAXED (answered once written), beside the disk's own floor for one
        # small append made durable.
        for durability in ("SYNC", "RELAXED"):
            move = pb.UpsertSitesRequest(scene_id="load",
                                         durability=pb.Durability.Value("DURABILITY_" + durability))
            site = move.sites.add(id="0")
            ask = pb.FindNearestRequest(scene_id="load")
            at = ask.points.add()
            trips = []
            for k in range(args.moves):
                x, y = rng.random(2)
                site.point.x, site.point.y = x, y
                t0 = time.perf_counter()
                ask.min_version = api.UpsertSites(move).version
                at.x, at.y = x, y
                answer = api.FindNearest(ask).results[0]
                trips.append(time.perf_counter() - t0)
                # The moved site, or one as near within the raster answer's bound (another
                # site a fraction of a pixel away).
                if answer.site_id != "0" and answer.distance > answer.error_bound:
                    raise SystemExit(f"{durability} move {k}: the query at ({x}, {y}) saw "
                                     f"{answer.site_id}")
            name = "one-site move" + (", RELAXED" if durability == "RELAXED" else "")
            rows.append((f"{name}, round trip (median)", statistics.median(trips), cv_full))
            rows.append((f"{name}, round trip (p99)", sorted(trips)[len(trips) * 99 // 100],
                         cv_full))
        rows.append(("the disk's floor: a 4 KiB append and fdatasync (median)",
                     fdatasync_floor(workdir, args.moves), None))
        # What any call costs this client: a one-point FindNearest on a published frame.
        ask = pb.FindNearestRequest(scene_id="load")
        ask.points.add(x=0.5, y=0.5)
        floor = []
        for _ in range(args.moves):
            t0 = time.perf_counter()
            api.FindNearest(ask)
            floor.append(time.perf_counter() - t0)
        rows.append(("the call's floor: a one-point FindNearest (median)",
                     statistics.median(floor), None))

        # Concurrent writers, each moving sites of a small scene of its own, one site per call:
        # commits that arrive together share one fsync.
        for writers in (1, 8):
            rows.append((f"{writers} writer{'s' if writers > 1 else ''}, one-site upserts, "
                         "each acknowledged (per upsert, all writers together)",
                         concurrent_upserts(api, pb, writers, args.writes), None))

        # One packed batch of queries, raster then exact answers; cKDTree beside them.
        batch = pb.FindNearestRequest(scene_id="load")
        batch.xy.extend(queries.ravel().tolist())
        closest = ["SITE", "DISTANCE", "CLOSEST", "GRADIENT"]
        for exact, fields in ((False, []), (True, []), (False, ["SITE", "DISTANCE"]),
                              (True, ["SITE", "DISTANCE"]), (False, closest), (True, closest)):
            batch.exact = exact
            del batch.fields[:]
            batch.fields.extend(pb.NearestField.Value("NEAREST_FIELD_" + f) for f in fields)
            seconds, reply = best(lambda: api.FindNearest(batch, timeout=600), 3)
            if len(reply.packed.site) != args.queries:
                raise SystemExit("the batch came back short")
            rows.append((f"{args.queries} points in one packed FindNearest, "
                         f"{'exact' if exact else 'raster'}"
                         f"{', fields ' + ' and '.join(fields) if fields else ''}", seconds, None))
        kd1, _ = best(lambda: tree.query(queries, workers=1), 3)
        kdn, _ = best(lambda: tree.query(queries, workers=-1), 3)
        rows.append((f"scipy cKDTree query, {args.queries} points, one worker", kd1, None))
        rows.append((f"scipy cKDTree query, {args.queries} points, all cores", kdn, None))
        rows.append(("OpenCV distanceTransformWithLabels, exact mask", cv_full, None))
    finally:
        server.send_signal(signal.SIGTERM)
        server.wait(timeout=60)
        shutil.rmtree(workdir, ignore_errors=True)

    print(f"\n{args.points} random points, {args.size}x{args.size}, gvd-server defaults, "
          f"store on disk; {os.cpu_count()} CPUs\n")
    print("| what a user does | time | OpenCV exact labels, same run | ratio |")
    print("|---|---|---|---|")
    for name, seconds, reference in rows:
        ratio = f"{reference / seconds:.2f}x" if reference else ""
        ref = f"{reference * 1e3:.1f} ms" if reference else ""
        print(f"| {name} | {seconds * 1e3:.2f} ms | {ref} | {ratio} |")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump([{"name": n, "seconds": s, "opencv_seconds": r} for n, s, r in rows], f,
                      indent=1)


if __name__ == "__main__":
    main()
