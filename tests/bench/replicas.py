#!/usr/bin/python3
"""Replicas on PostgreSQL beside one server on SQLite, through real gvd-servers and a stock
Python grpcio client.

Usage: replicas.py GVD_SERVER [--writes N] [--batches N] [--lag N] [--queries N] [--json FILE]

Starts a PostgreSQL of its own (Debian's postgresql package: a cluster made by initdb in a
temporary directory, fsync on, run as the postgres user when this runs as root), two
gvd-servers on it (--store postgresql://...) and one on SQLite (--data), and measures:
  - one-site upserts per second, one writer at a time, on SQLite and on a replica;
  - 1,000-site batches per second, the same way;
  - replication lag: a one-site upsert acknowledged by replica A, until replica B's
    WatchScene stream announces a frame of that version (p50 and p99);
  - read lag: three writers at once, each a one-site upsert acknowledged by one replica,
    until the other answers a one-point FindNearest at its version (p50 and p99);
  - FindNearest throughput (packed, 1,000 random points a call, raster answers) from 4
    client threads, against one replica and split over two.
"""
import argparse
import json
import os
import shutil
import signal
import statistics
import sys
import tempfile
import threading
import time

import grpc
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from serve import Voronoi, load_messages, start_server  # noqa: E402  pylint: disable=wrong-import-position
from gvdtest import Postgres  # noqa: E402  pylint: disable=wrong-import-position


def create(api, pb, scene):
    request = pb.CreateSceneRequest(scene_id=scene, width_px=512, height_px=512)
    request.window.max_x = 1
    request.window.max_y = 1
    try:
        api.CreateScene(request)
    except grpc.RpcError as e:
        if e.code() != grpc.StatusCode.ALREADY_EXISTS:
            raise


def upserts_per_second(api, pb, scene, writes, batch):
    rng = np.random.default_rng(3)
    request = pb.UpsertSitesRequest(scene_id=scene)
    sites = [request.sites.add() for _ in range(batch)]
    t0 = time.perf_counter()
    for k in range(writes):
        for i, site in enumerate(sites):
            site.id = str((k * batch + i) % 5000)
            site.point.x, site.point.y = rng.random(2)
        api.UpsertSites(request)
    return writes / (time.perf_counter() - t0)


def lag(a, b, pb, scene, writes):
    """Seconds from A's acknowledgement of a write to B's announcement of its frame."""
    events = b.WatchScene(pb.WatchSceneRequest(scene_id=scene))
    seen, cv, latest = {}, threading.Condition(), [0]

    def read():
        try:
            for e in events:
                with cv:
                    latest[0] = max(latest[0], e.version)
                    seen[e.version] = time.perf_counter()
                    cv.notify_all()
        except grpc.RpcError as e:
            if e.code() != grpc.StatusCode.CANCELLED:
                print("WatchScene:", e, file=sys.stderr)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    rng = np.random.default_rng(5)
    request = pb.UpsertSitesRequest(scene_id=scene)
    site = request.sites.add()
    out = []
    for k in range(writes):
        site.id = str(k % 100)
        site.point.x, site.point.y = rng.random(2)
        version = a.UpsertSites(request).version
        acked = time.perf_counter()
        with cv:
            cv.wait_for(lambda: latest[0] >= version, timeout=30)
            at = min((t for v, t in seen.items() if v >= version), default=None)
        if at is None:
            raise SystemExit(f"replica B never showed version {version}")
        out.append(max(0.0, at - acked))
        time.sleep(0.005)
    events.cancel()
    return out


def read_lag(apis, pb, writes, writers=3):
    """Seconds from one replica's acknowledgement of a one-site write to the other's answer
    to a one-point FindNearest at its version, `writers` writers at once: writer k writes
    scene read-k through replica k % 2 and reads it through the other."""
    out, lock, failed = [], threading.Lock(), []

    def write(k):
        scene = f"read-{k}"
        rng = np.random.default_rng(100 + k)
        mine = []
        request = pb.UpsertSitesRequest(scene_id=scene)
        site = request.sites.add()
        try:
            for n in range(writes):
                site.id = str(n % 100)
                site.point.x, site.point.y = rng.random(2)
                version = apis[k % 2].UpsertSites(request).version
                acked = time.perf_counter()
                answer = apis[1 - k % 2].FindNearest(pb.FindNearestRequest(
                    scene_id=scene, xy=[site.point.x, site.point.y], min_version=version))
                mine.append(time.perf_counter() - acked)
                if answer.version < version or answer.packed.distance[0] > answer.packed.error_bound[0]:
                    raise SystemExit(f"{scene}: the write of version {version} unseen")
                time.sleep(0.002)
        except BaseException as e:  # pylint: disable=broad-except
            failed.append(e)
        with lock:
            out.extend(mine)

    for k in range(writers):
        create(apis[k % 2], pb, f"read-{k}")
    time.sleep(0.5)
    threads = [threading.Thread(target=write, args=(k,)) for k in range(writers)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    if failed:
        raise failed[0]
    return out


def queries_per_second(apis, pb, scene, calls):
    rng = np.random.default_rng(7)
    xy = rng.random(2000).tolist()
    request = pb.FindNearestRequest(scene_id=scene, xy=xy)
    threads, per = [], calls // 4

    def run(api):
        for _ in range(per):
            api.FindNearest(request)

    for t in range(4):
        threads.append(threading.Thread(target=run, args=(apis[t % len(apis)],)))
    t0 = time.perf_counter()
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return 4 * per * 1000 / (time.perf_counter() - t0)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("server")
    ap.add_argument("--writes", type=int, default=500)
    ap.add_argument("--batches", type=int, default=40)
    ap.add_argument("--lag", type=int, default=300)
    ap.add_argument("--queries", type=int, default=400, help="FindNearest calls of 1,000 points")
    ap.add_argument("--json")
    args = ap.parse_args()
    work = tempfile.mkdtemp(prefix="gvd-replicas-")
    os.chmod(work, 0o755)
    servers, pg = [], None
    try:
        pb = load_messages(work)
        pg = Postgres(work)
        url = pg.url
        sqlite, sqlite_at = start_server(args.server, os.path.join(work, "sqlite"))
        a, a_at = start_server(args.server, os.path.join(work, "a"), url)
        b, b_at = start_server(args.server, os.path.join(work, "b"), url)
        servers = [sqlite, a, b]
        api = {name: Voronoi(grpc.insecure_channel(at), pb)
               for name, at in (("sqlite", sqlite_at), ("a", a_at), ("b", b_at))}
        figures = {}
        for name in ("sqlite", "a"):
            create(api[name], pb, "one")
            create(api[name], pb, "batch")
            figures[f"{name}_upserts_per_s"] = upserts_per_second(api[name], pb, "one", args.writes, 1)
            figures[f"{name}_batches_per_s"] = upserts_per_second(api[name], pb, "batch", args.batches, 1000)
        create(api["a"], pb, "lag")
        time.sleep(0.5)
        lags = sorted(lag(api["a"], api["b"], pb, "lag", args.lag))
        figures["lag_p50_ms"] = 1000 * statistics.median(lags)
        figures["lag_p99_ms"] = 1000 * lags[min(len(lags) - 1, int(0.99 * len(lags)))]
        reads = sorted(read_lag([api["a"], api["b"]], pb, args.lag))
        figures["read_lag_p50_ms"] = 1000 * statistics.median(reads)
        figures["read_lag_p99_ms"] = 1000 * reads[min(len(reads) - 1, int(0.99 * len(reads)))]
        create(api["a"], pb, "query")
        rng = np.random.default_rng(11)
        load = pb.UpsertSitesRequest(scene_id="query")
        for i, (x, y) in enumerate(rng.random((10_000, 2))):
            site = load.sites.add()
            site.id, site.point.x, site.point.y = str(i), x, y
        version = api["a"].UpsertSites(load).version
        for name in ("a", "b"):  # both at the loaded version, rendered
            api[name].FindNearest(pb.FindNearestRequest(scene_id="query", xy=[0.5, 0.5],
                                                        min_version=version))
        figures["one_replica_points_per_s"] = queries_per_second([api["a"]], pb, "query", args.queries)
        figures["two_replicas_points_per_s"] = queries_per_second([api["a"], api["b"]], pb, "query", args.queries)
        for k, v in figures.items():
            print(f"{k:28s} {v:12.1f}")
        if args.json:
            with open(args.json, "w", encoding="ascii") as f:
                json.dump(figures, f, indent=1)
    finally:
        for s in servers:
            s.send_signal(signal.SIGTERM)
            s.wait()
        if pg:
            pg.stop()
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
