#!/usr/bin/python3
"""Where a one-site move's CPU goes, thread by thread, over each of the Python client's
transports: one gvd-server, a scene of random points, and moves in blocks alternating between
the client's gRPC and HTTP transports (and, with --postgis, PostGIS's moves of the same points).

Usage: move_threads.py GVD_SERVER [--points N] [--blocks B] [--block N] [--gap MS] [--postgis]
(run with a Python that has the gvd package: tests/python/run.sh builds such a venv, or
/usr/bin/python3 with PYTHONPATH=client/python after a build; --postgis needs psycopg2 and
PostGIS, as postgis.py does).

The scene: N uniform random points in the unit square at 1024x1024 (20,000 unless --points),
loaded, queried at its version and left to render for a second. Then B blocks (8) of N moves
(200) each, the blocks alternating between the transports, each move as postgis.py makes it
(an UpsertSites, SYNC, then a FindNearest at its version at the moved site) and --gap ms
after the last (1.5: about what a PostGIS move takes between gvd's moves there). Around each
block the server's threads are read from /proc/PID/task: each thread's CPU (user and system,
in clock ticks) and its context switches (voluntary and not), summed by thread name; the
client's CPU is its process's. Prints, for each side, the moves' p50 and, per move, the
client's CPU and each server thread name's CPU and switches (names with none left out).
Thread names are the kernel's, 15 characters at most (the gRPC port's one polling thread is
`gvd-grpc`; the HTTP transport's I/O threads `gvd-http`).

With --postgis, a PostgreSQL of its own holds the same points (postgis.py's table, COPY and
GiST index), and every third block is PostGIS's moves of the same kind (postgis.py's UPDATE
then KNN SELECT, psycopg2 on the Unix socket): the connection's backend process is read as
the server's threads are, and the client's CPU as for gvd.
"""
import argparse
import collections
import os
import shutil
import signal
import statistics
import sys
import tempfile
import time

import numpy as np
import psycopg2

import gvd

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from gvdtest import Postgres, read_ports, start_server, threads  # noqa: E402  pylint: disable=wrong-import-position
import postgis  # noqa: E402  pylint: disable=wrong-import-position

TICK_MS = 1000.0 / os.sysconf("SC_CLK_TCK")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("server")
    ap.add_argument("--points", type=int, default=20_000)
    ap.add_argument("--blocks", type=int, default=8)
    ap.add_argument("--block", type=int, default=200)
    ap.add_argument("--gap", type=float, default=1.5)
    ap.add_argument("--postgis", action="store_true")
    args = ap.parse_args()
    sides = ("http", "grpc", "postgis") if args.postgis else ("http", "grpc")
    if args.points < 1 or args.block < 1 or args.blocks < 1 or args.blocks % len(sides):
        ap.error("--points and --block must be 1 or more, --blocks a multiple of "
                 f"{len(sides)}, the sides moving")
    if args.gap < 0:
        ap.error(f"--gap must be 0 or more milliseconds, not {args.gap:g}")
    work = tempfile.mkdtemp(prefix="gvd-move-threads-")
    os.chmod(work, 0o755)
    server, pg = None, None
    try:
        ports = os.path.join(work, "ports")
        with open(os.path.join(work, "gvd.log"), "w", encoding="ascii") as log:
            server, http_port = start_server(args.server, os.path.join(work, "gvd"), ports,
                                             log, "--log-level", "warn")
        grpc_port = read_ports(ports)[0]
        clients = {"grpc": gvd.Client(f"127.0.0.1:{grpc_port}", timeout=60),
                   "http": gvd.Client(f"http://127.0.0.1:{http_port}", timeout=60)}
        rng = np.random.default_rng(7)
        points = rng.random((args.points, 2))
        ids = [str(i) for i in range(args.points)]
        first = clients["grpc"]
        first.create_scene("moves", window=(0, 0, 1, 1), size=(1024, 1024))
        version = first.upsert_points("moves", ids, points)
        first.find_nearest("moves", [[0.5, 0.5]], min_version=version)
        pids = dict.fromkeys(clients, server.pid)
        if args.postgis:
            pg = Postgres(work)
            conn = psycopg2.connect(host=pg.sock, port=pg.port, user="gvd", dbname="gvd")
            conn.autocommit = True
            cur = conn.cursor()
            cur.execute("CREATE EXTENSION postgis")
            postgis.pg_load(conn, "moves", [("point", p) for p in points])
            cur.execute("SELECT pg_backend_pid()")
            pids["postgis"] = cur.fetchone()[0]
        time.sleep(1)
        spent = {name: collections.Counter() for name in sides}
        client_cpu = dict.fromkeys(sides, 0.0)
        times = {name: [] for name in sides}
        for block in range(args.blocks):
            name = sides[block % len(sides)]
            before, cpu = threads(pids[name]), time.process_time()
            for _ in range(args.block):
                i = int(rng.integers(args.points))
                p = rng.random(2)
                t0 = time.perf_counter()
                if name == "postgis":
                    postgis.pg_move(cur, "moves", i, ("point", p), p[0], p[1])
                else:
                    version = clients[name].upsert_points("moves", [ids[i]], p[None, :])
                    clients[name].find_nearest("moves", [p], min_version=version)
                times[name].append(1000 * (time.perf_counter() - t0))
                time.sleep(args.gap / 1000)
            client_cpu[name] += time.process_time() - cpu
            after = threads(pids[name])
            after.subtract(before)
            spent[name].update(after)
        for name in sides:
            moves = len(times[name])
            print(f"{name}: {moves} moves, p50 {statistics.median(times[name]):.2f} ms; "
                  f"a move's CPU: the client {1000 * client_cpu[name] / moves:.3f} ms")
            for key in sorted(k for k in spent[name] if isinstance(k, str)):
                ms = spent[name][key] * TICK_MS / moves
                switches = spent[name][(key, "switches")] / moves
                if ms or switches:
                    print(f"  {key:16} {ms:6.3f} ms  {switches:6.2f} switches")
    finally:
        if server:
            server.send_signal(signal.SIGTERM)
            server.wait()
        if pg:
            pg.stop()
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
