#!/usr/bin/python3
"""Where a one-site move's time goes right after a bulk load: postgis.py's scenes and moves
against gvd-server alone, each move split into its upsert and its read, the slow ones listed
with the time they came after the load.

Usage: moves.py GVD_SERVER [--settle S] [--moves N] [--gap MS] [--bursts B] [--slow MS]
                [--transport grpc|http]
(run with a Python that has the gvd package: tests/python/run.sh builds such a venv).

For each scene: the load (CreateScene, UpsertSites, a FindNearest at its version), S seconds
of rest (0: the moves begin at once, meeting the load's render and the store's fold of its
pack), then N moves as postgis.py makes them (an UpsertSites, SYNC, then a FindNearest at its
version at the moved site), --gap ms apart (0.5; 0: back to back, as a script's edits come,
where a drag's come 8-16 ms apart), through the Python client over gRPC or HTTP, in B
bursts (a drag's worth each) with 0.5 s of rest after each. Prints each scene's p50, p99 and
largest move, the p50 of its upsert and of its read, how long after each burst its frame held
the burst's last move (the reads need no frame: this is what a render lags a drag), and the
moves over MS milliseconds: (seconds after the first move, upsert ms, read ms).
"""
import argparse
import os
import shutil
import signal
import statistics
import sys
import tempfile
import time

import numpy as np

import gvd

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import postgis  # noqa: E402  pylint: disable=wrong-import-position
from gvdtest import percentile, read_ports, start_server  # noqa: E402  pylint: disable=wrong-import-position


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("server")
    ap.add_argument("--settle", type=float, default=0.0)
    ap.add_argument("--moves", type=int, default=300)
    ap.add_argument("--gap", type=float, default=0.5)
    ap.add_argument("--bursts", type=int, default=1)
    ap.add_argument("--slow", type=float, default=2.0)
    ap.add_argument("--transport", choices=("grpc", "http"), default="grpc")
    args = ap.parse_args()
    if not 1 <= args.bursts <= args.moves:
        ap.error(f"--bursts must be from 1 to --moves ({args.moves}), not {args.bursts}")
    if args.gap < 0:
        ap.error(f"--gap must be 0 or more milliseconds, not {args.gap:g}")
    work = tempfile.mkdtemp(prefix="gvd-moves-")
    server = None
    try:
        ports = os.path.join(work, "ports")
        with open(os.path.join(work, "gvd.log"), "w", encoding="ascii") as log:
            server, http_port = start_server(args.server, os.path.join(work, "gvd"), ports,
                                             log, "--log-level", "warn")
        grpc_port = read_ports(ports)[0]
        client = gvd.Client(f"http://127.0.0.1:{http_port}" if args.transport == "http"
                            else f"127.0.0.1:{grpc_port}", timeout=600)
        for name, make in (("points", postgis.scene_points), ("segments", postgis.scene_segments),
                           ("curves", postgis.scene_curves)):
            rng = np.random.default_rng(7)
            sites = make(rng)
            postgis.gvd_load(client, name, sites)
            time.sleep(args.settle)
            total, upserts, reads, slow, lags = [], [], [], [], []
            first = time.perf_counter()
            for k in range(args.moves):
                i = int(rng.integers(len(sites)))
                sites[i] = postgis.moved(rng, sites[i])
                x, y = postgis.anchor(sites[i])
                t0 = time.perf_counter()
                version = client.upsert_sites(name, [postgis.to_pb(str(i), sites[i])])
                t1 = time.perf_counter()
                answer = client.find_nearest(name, [[x, y]], min_version=version)
                t2 = time.perf_counter()
                if answer.distances[0] > answer.error_bounds[0]:
                    raise SystemExit(f"{name}: the move of {i} unseen")
                total.append(1000 * (t2 - t0))
                upserts.append(1000 * (t1 - t0))
                reads.append(1000 * (t2 - t1))
                if total[-1] > args.slow:
                    slow.append((round(t0 - first, 3), round(1000 * (t1 - t0), 2),
                                 round(1000 * (t2 - t1), 2)))
                if args.gap:
                    time.sleep(args.gap / 1000)
                if (k + 1) * args.bursts % args.moves < args.bursts:  # a burst's last move
                    t0 = time.perf_counter()
                    while client.get_scene(name).rendered_version < version:
                        time.sleep(0.001)
                    lags.append(1000 * (time.perf_counter() - t0))
                    time.sleep(0.5)
            print(f"{name}: p50 {statistics.median(total):.2f} ms, p99 "
                  f"{percentile(total, 0.99):.2f} ms, largest {max(total):.2f} ms; upsert p50 "
                  f"{statistics.median(upserts):.3f} ms, read p50 {statistics.median(reads):.3f} "
                  f"ms; frame after each burst p50 {statistics.median(lags):.0f} ms, largest "
                  f"{max(lags):.0f} ms; over "
                  f"{args.slow:g} ms (s, upsert ms, read ms): {slow}", flush=True)
    finally:
        if server:
            server.send_signal(signal.SIGTERM)
            server.wait()
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
