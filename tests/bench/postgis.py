#!/usr/bin/python3
"""gvd-server beside PostGIS, the database a team would pick instead for "which object is
nearest to this point, over the network", each driven by its ecosystem's own tools.

Usage: postgis.py GVD_SERVER [--moves N] [--seconds S] [--rounds R] [--batch N] [--json FILE]
(run with a Python that has the gvd package: tests/python/run.sh builds such a venv;
psycopg2 and PostGIS are Debian's python3-psycopg2 and postgresql-15-postgis-3).

Starts a PostgreSQL 15 with PostGIS 3 of its own (initdb in a temporary directory, fsync on,
as gvd's store syncs each acknowledged write) and gvd-server on its default flags with its
store on the same disk, then, on three scenes in the unit square (gvd at 1024x1024):
  - points: 100,000 uniform random points;
  - segments: 20,000 random segments, each up to 0.02 long;
  - curves: 300 cubic Beziers and 249 segments, 92% of them packed into a corner and the
    rest scattered, so that cells range from a few pixels to a few percent of the window
    (PostGIS gets each Bezier flattened to 64 pieces),
measures:
  - load until queryable: gvd CreateScene, UpsertSites of every site (points and segments
    from arrays, upsert_points and upsert_segments; other sites as the API's messages,
    upsert_sites), and a FindNearest at the new version; PostGIS CREATE TABLE, COPY, a GiST
    index, ANALYZE and a KNN query;
  - a one-site move until a read sees it, p50 and p99 over N moves of a random site to a
    random place (often into empty space, where it takes a large cell): gvd an UpsertSites
    (SYNC) and a FindNearest at its version at the moved site, through the client's two
    transports (gRPC and HTTP) and the same two calls made through grpcio alone (N/3 each);
    PostGIS's of the same sites to the same places, an UPDATE (autocommit) and a KNN SELECT
    at that point; in blocks of 50 moves a side, 1 ms apart, gvd's then PostGIS's, 50 ms of
    rest after each block, so that neither side's work after its moves falls on the other's
    (moved one after the other, gvd's renders of its moves ran during PostGIS's: its p50
    came out 0.2-0.5 ms slower). Each gvd block is one client's, the three taking turns
    block by block (N a multiple of 150 gives each a third; the first block after each load,
    which meets the load's render and store work, each client's in one scene), as each
    PostGIS block is psycopg2's: a user's process runs one client,
    and with the three alternating move by move, each call found the caches holding another
    client's code (over HTTP, p50 0.2-0.25 ms slower a move: 1.44-1.46x PostGIS's on the
    points against 1.17-1.18x, two runs each way);
  - a batch of N random query points in one call, the median of three runs on each side
    after a first run on each that is reported apart: gvd FindNearest (one packed call),
    PostGIS a LATERAL KNN join over arrays passed as parameters;
then a call that does nothing, N times on each side, alternating: grpcio's call of gRPC's
standard health Check (answered on the gRPC port's thread, none of the core) and psycopg2's SELECT 1, p50 and p99,
the floor of each side's stock client and transport under a move's two calls; back to back,
then each call after 1 ms idle, as a move's calls come after the wait on the other side's;
and on the points scene the single-point query capacity at 8 connections, in R rounds
(3) of S seconds (10) a side, the sides taking turns: pgbench (-M prepared -c 8 -j 2, a
KNN script at random points) against h2load (-c 8 -m 1 -t 2, a FindNearest over gRPC at
one point: h2load sends one body) and wrk (-c 8 -t 2, a FindNearest over HTTP/JSON at
random points), with p50 and p99 from their per-request logs (wrk: its latency
distribution); each side's median round, and gvd's ratio to PostGIS the median of the
rounds' ratios (on this shared machine one 10-second run a side gives ratios that differ
by up to 1.8 times from run to run).
Clients: psycopg2 and the project's Python client (over gRPC; over HTTP as well for the
moves), one connection each, on loopback (PostgreSQL on its Unix socket, as a local
deployment would use it). For the moves also grpcio alone (GrpcioAlone): the API's
messages through grpcio's own stubs, with none of the client's code, the floor that any
Python gRPC client of gvd stands on.
"""
import argparse
import io
import json
import os
import re
import resource
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np
import psycopg2

import gvd
from gvd.v1 import voronoi_pb2 as pb

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from gvdtest import Postgres, percentile, read_ports, start_server, threads  # noqa: E402  pylint: disable=wrong-import-position

SIDE = 1024
BEZIER_PIECES = 64


def scene_points(rng):
    return [("point", p) for p in rng.random((100_000, 2))]


def random_segment(rng, center):
    angle = 2 * np.pi * rng.random()
    half = 0.01 * rng.random() * np.array([np.cos(angle), np.sin(angle)])
    return ("segment", np.array([center - half, center + half]))


def scene_segments(rng):
    return [random_segment(rng, c) for c in rng.random((20_000, 2))]


def scene_curves(rng):
    sites = []
    for i in range(549):
        center = rng.random(2) * 0.3 if rng.random() < 0.92 else rng.random(2)
        if i < 300:
            sites.append(("bezier", center + (rng.random((4, 2)) - 0.5) * 0.02))
        else:
            sites.append(random_segment(rng, center))
    return sites


def moved(rng, site):
    """The site carried to a random place of the window."""
    kind, geometry = site
    if kind == "point":
        return kind, rng.random(2)
    return kind, geometry - geometry.mean(axis=0) + rng.random(2) * 0.96 + 0.02


def anchor(site):
    """A point on the site: where a read after its move looks."""
    kind, geometry = site
    return geometry if kind == "point" else geometry[0]


def to_pb(sid, site):
    kind, g = site
    s = pb.Site(id=sid)
    if kind == "point":
        s.point.x, s.point.y = g
    elif kind == "segment":
        s.segment.a.x, s.segment.a.y = g[0]
        s.segment.b.x, s.segment.b.y = g[1]
    else:
        s.bezier.control_points.extend(pb.Point(x=x, y=y) for x, y in g)
    return s


def flatten(control):
    """A cubic Bezier as BEZIER_PIECES segments (PostGIS has no curves of this kind)."""
    t = np.linspace(0, 1, BEZIER_PIECES + 1)[:, None]
    p0, p1, p2, p3 = control
    return (1 - t) ** 3 * p0 + 3 * (1 - t) ** 2 * t * p1 + 3 * (1 - t) * t ** 2 * p2 + t ** 3 * p3


def to_wkt(site):
    kind, g = site
    if kind == "point":
        return f"POINT({g[0]!r} {g[1]!r})"
    line = g if kind == "segment" else flatten(g)
    return "LINESTRING(" + ",".join(f"{x!r} {y!r}" for x, y in line) + ")"


class GrpcioAlone:
    """A move's two calls through grpcio's generic stubs with the API's messages (the query
    point as a Point, the answer as the FindNearestResponse protobuf parses): what a move
    costs over gRPC before any of the client's own code."""

    def __init__(self, target):
        import grpc  # pylint: disable=import-outside-toplevel
        self.channel = grpc.insecure_channel(target)
        service = "/gvd.v1.VoronoiService/"
        self.upsert = self.channel.unary_unary(
            service + "UpsertSites", request_serializer=pb.UpsertSitesRequest.SerializeToString,
            response_deserializer=pb.UpsertSitesResponse.FromString)
        self.find = self.channel.unary_unary(
            service + "FindNearest", request_serializer=pb.FindNearestRequest.SerializeToString,
            response_deserializer=pb.FindNearestResponse.FromString)
        self.check = self.channel.unary_unary("/grpc.health.v1.Health/Check")

    def upsert_sites(self, name, sites):
        return self.upsert(pb.UpsertSitesRequest(scene_id=name, sites=sites), timeout=600).version

    def find_nearest(self, name, points, *, min_version):
        (x, y), = points
        return self.find(pb.FindNearestRequest(scene_id=name, min_version=min_version,
                                               points=[pb.Point(x=x, y=y)]), timeout=600)

    def nothing(self):
        """gRPC's standard health Check (an empty request: the whole server), answered on the
        gRPC port's thread from a table, with none of the core's code."""
        return self.check(b"", timeout=600)


def first_answer(answer):
    """The first answer's site id, distance and error bound, from the client's NearestResult
    or from a FindNearestResponse."""
    if isinstance(answer, pb.FindNearestResponse):
        r = answer.results[0]
        return r.site_id, r.distance, r.error_bound
    return answer.site_ids[0], answer.distances[0], answer.error_bounds[0]


def gvd_load(client, name, sites):
    """A scene of points or of segments goes in as arrays (upsert_points, upsert_segments),
    any other as the API's messages (upsert_sites), each made before the clock starts, as
    PostGIS's COPY text is."""
    ids = [str(i) for i in range(len(sites))]
    kinds = {kind for kind, _ in sites}
    upsert = ({"point": client.upsert_points, "segment": client.upsert_segments}.get(kinds.pop())
              if len(kinds) == 1 else None)
    if upsert:
        arrays = np.array([g for _, g in sites])
    else:
        messages = [to_pb(i, s) for i, s in zip(ids, sites)]
    t0 = time.perf_counter()
    client.create_scene(name, window=(0, 0, 1, 1), size=(SIDE, SIDE))
    version = upsert(name, ids, arrays) if upsert else client.upsert_sites(name, messages)
    client.find_nearest(name, [[0.5, 0.5]], min_version=version)
    return time.perf_counter() - t0


def pg_load(conn, name, sites):
    text = "".join(f"{i}\t{to_wkt(s)}\n" for i, s in enumerate(sites))
    t0 = time.perf_counter()
    with conn.cursor() as cur:
        cur.execute(f"CREATE TABLE {name} (id integer PRIMARY KEY, geom geometry NOT NULL)")
        cur.copy_expert(f"COPY {name} (id, geom) FROM STDIN", io.StringIO(text))
        cur.execute(f"CREATE INDEX ON {name} USING gist (geom)")
        cur.execute(f"ANALYZE {name}")
        cur.execute(f"SELECT id FROM {name} ORDER BY geom <-> ST_MakePoint(0.5, 0.5) LIMIT 1")
        cur.fetchone()
    return time.perf_counter() - t0


def pg_move(cur, name, i, site, x, y):
    """PostGIS's move: site i carried to `site` (an UPDATE, committed on its own), then the
    nearest site to (x, y) read (a KNN SELECT); that site's row."""
    cur.execute(f"UPDATE {name} SET geom = ST_GeomFromText(%s) WHERE id = %s", (to_wkt(site), i))
    cur.execute(f"SELECT id FROM {name} ORDER BY geom <-> ST_MakePoint(%s, %s) LIMIT 1", (x, y))
    return cur.fetchone()


def moves(clients, conn, name, sites, count, rng, first=0, block=50, gap_ms=1.0, rest_ms=50.0):
    """`count` moves on each side, in blocks of `block`: gvd's, each block through one of the
    clients (a dict: transport name to client) in turn from the `first`, then PostGIS's of the
    same sites to the same places, `gap_ms` apart, with `rest_ms` after each block, so that
    neither side's work after its moves (gvd's renders of them, on the other core) falls on
    the other's."""
    gvd_ms = {kind: [] for kind in clients}
    pg_ms = []
    kinds = list(clients)
    if count < block * len(kinds):
        raise SystemExit(f"--moves is at least {block * len(kinds)}: a block of {block} "
                         f"for each of {len(kinds)} clients")
    with conn.cursor() as cur:
        for start in range(0, count, block):
            done = []
            for k in range(start, min(start + block, count)):
                kind = kinds[(first + start // block) % len(kinds)]
                i = int(rng.integers(len(sites)))
                site = moved(rng, sites[i])
                sites[i] = site
                x, y = anchor(site)
                message = to_pb(str(i), site)
                t0 = time.perf_counter()
                version = clients[kind].upsert_sites(name, [message])
                answer = clients[kind].find_nearest(name, [[x, y]], min_version=version)
                gvd_ms[kind].append(1000 * (time.perf_counter() - t0))
                # The read saw the move: the site is at distance 0 from the point read (the
                # answer may be another site within its bound).
                site_id, distance, bound = first_answer(answer)
                if distance > bound:
                    raise SystemExit(f"move of {i} unseen by gvd ({kind}): {site_id} at "
                                     f"{distance}, bound {bound}")
                done.append((i, site, x, y))
                time.sleep(gap_ms / 1000)
            time.sleep(rest_ms / 1000)
            for i, site, x, y in done:
                t0 = time.perf_counter()
                row = pg_move(cur, name, i, site, x, y)
                pg_ms.append(1000 * (time.perf_counter() - t0))
                if row[0] != i:
                    raise SystemExit(f"move of {i} unseen by PostGIS: {row[0]}")
                time.sleep(gap_ms / 1000)
            time.sleep(rest_ms / 1000)
    out = {}
    for kind, ms in gvd_ms.items():
        out[f"gvd_{kind}_p50_ms"] = statistics.median(ms)
        out[f"gvd_{kind}_p99_ms"] = percentile(ms, 0.99)
    out["postgis_p50_ms"] = statistics.median(pg_ms)
    out["postgis_p99_ms"] = percentile(pg_ms, 0.99)
    return out


def floor(bare, conn, count, idle_ms=1.0):
    """A call that does nothing, `count` times on each side, alternating: grpcio's call of
    gRPC's health Check and psycopg2's SELECT 1, p50 and p99 (ms). What each side's stock
    client and its transport cost before any work: a move makes two calls on each side.
    Then the same with `idle_ms` of sleep after each call ("paced"): a move's calls come after
    the client has waited about that long on the other side's move, and a call made after
    a wait costs more than one made back to back (its code and data no longer in the
    caches), the more so the more code it runs."""
    out = {}
    with conn.cursor() as cur:
        for prefix, idle in (("", 0.0), ("paced_", idle_ms / 1000)):
            gvd_ms, pg_ms = [], []
            for _ in range(count):
                t0 = time.perf_counter()
                bare.nothing()
                gvd_ms.append(1000 * (time.perf_counter() - t0))
                time.sleep(idle)
                t0 = time.perf_counter()
                cur.execute("SELECT 1")
                cur.fetchone()
                pg_ms.append(1000 * (time.perf_counter() - t0))
                time.sleep(idle)
            out.update({f"grpcio_{prefix}p50_ms": statistics.median(gvd_ms),
                        f"grpcio_{prefix}p99_ms": percentile(gvd_ms, 0.99),
                        f"psycopg2_{prefix}p50_ms": statistics.median(pg_ms),
                        f"psycopg2_{prefix}p99_ms": percentile(pg_ms, 0.99)})
    return out


def batch(client, conn, name, q, runs=3):
    """The median of `runs` runs of the batch on each side, after a first run on each, timed
    apart: the first gvd run may still wait for the render that follows a load or the last
    move (which the load and move rows count), and a process's first large calls fault in
    the memory its allocator keeps from then on (in this process, gvd's first two batches
    of a scene took 2.5 k page faults each, later ones 0.1-0.4 k)."""
    gvd_s, pg_s = [], []
    for _ in range(1 + runs):
        t0 = time.perf_counter()
        client.find_nearest(name, q)
        gvd_s.append(time.perf_counter() - t0)
        with conn.cursor() as cur:
            t0 = time.perf_counter()
            cur.execute(f"""SELECT q.i, s.id FROM unnest(%s::float8[], %s::float8[])
                              WITH ORDINALITY AS q(x, y, i)
                            CROSS JOIN LATERAL (SELECT id FROM {name}
                              ORDER BY geom <-> ST_MakePoint(q.x, q.y) LIMIT 1) s""",
                        (q[:, 0].tolist(), q[:, 1].tolist()))
            rows = cur.fetchall()
            pg_s.append(time.perf_counter() - t0)
        assert len(rows) == len(q)
    return {"gvd_ms": 1000 * statistics.median(gvd_s[1:]),
            "postgis_ms": 1000 * statistics.median(pg_s[1:]),
            "gvd_first_ms": 1000 * gvd_s[0], "postgis_first_ms": 1000 * pg_s[0]}


def load(command, server_pid=None):
    """Runs a load generator's `command` to its end; its stdout, and its CPU beside the
    server's: "generator_s" (the generator's CPU, user and system, over its wall time), and
    with `server_pid` "server_thread" (the thread name that took the most of the server's CPU
    in the run: `gvd-grpc` is the gRPC port's one thread, `gvd-http` the HTTP transport's I/O
    threads, one on two cores) and "server_s" (the CPU of the threads of that name over the
    wall time)."""
    before, used = (threads(server_pid) if server_pid else None), resource.getrusage(
        resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    run = subprocess.run(command, check=True, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    now = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = {"generator_s": (now.ru_utime + now.ru_stime - used.ru_utime - used.ru_stime) / wall}
    if server_pid:
        spent = threads(server_pid) - before
        name = max((k for k in spent if isinstance(k, str)), key=lambda k: spent[k])
        cpu.update(server_thread=name,
                   server_s=spent[name] / os.sysconf("SC_CLK_TCK") / wall)
    return run.stdout, cpu


def pg_capacity(pg, work, seconds):
    """pgbench's single-point KNN queries at 8 connections: queries/s, p50 and p99 (ms)."""
    script = os.path.join(work, "knn.sql")
    with open(script, "w", encoding="ascii") as f:
        f.write("\\set x random(0, 999999)\n\\set y random(0, 999999)\n"
                "SELECT id FROM points ORDER BY geom <-> "
                "ST_MakePoint(:x / 1e6, :y / 1e6) LIMIT 1;\n")
    logs = tempfile.mkdtemp(prefix="pgbench-", dir=work)
    out, cpu = load([f"{pg.bindir}/pgbench", "-h", pg.sock, "-p", str(pg.port), "-U", "gvd",
                     "-n", "-M", "prepared", "-c", "8", "-j", "2", "-T", str(seconds),
                     "-f", script, "-l", "--log-prefix", os.path.join(logs, "log"), "gvd"])
    tps = float(re.search(r"tps = ([\d.]+)", out).group(1))
    lat = [int(line.split()[2]) / 1000 for name in os.listdir(logs)
           for line in open(os.path.join(logs, name), encoding="ascii")]
    return {"per_s": tps, "p50_ms": statistics.median(lat), "p99_ms": percentile(lat, 0.99),
            **cpu}


def grpc_capacity(work, server_pid, grpc_port, seconds):
    """h2load's single-point FindNearest calls over gRPC at 8 connections (one body)."""
    body = pb.FindNearestRequest(scene_id="points", points=[pb.Point(x=0.37, y=0.61)])
    data = body.SerializeToString()
    req = os.path.join(work, "req.bin")
    with open(req, "wb") as f:
        f.write(b"\x00" + len(data).to_bytes(4, "big") + data)
    log = os.path.join(work, "h2load.log")
    out, cpu = load(["h2load", "-c", "8", "-t", "2", "-m", "1", "-D", str(seconds),
                     "--warm-up-time", "1", "-d", req, "--log-file", log,
                     "-H", "content-type: application/grpc", "-H", "te: trailers",
                     f"http://127.0.0.1:{grpc_port}/gvd.v1.VoronoiService/FindNearest"],
                    server_pid)
    lat = [int(line.split("\t")[2]) / 1000 for line in open(log, encoding="ascii")]
    if "0 5xx" not in out or "0 4xx" not in out:
        raise SystemExit("h2load: failed calls\n" + out)
    return {"per_s": float(re.search(r"finished in [\d.]+\w+, ([\d.]+) req/s", out).group(1)),
            "p50_ms": statistics.median(lat), "p99_ms": percentile(lat, 0.99), **cpu}


def http_capacity(work, server_pid, http_port, seconds):
    """wrk's single-point FindNearest calls over HTTP/JSON at 8 connections, random points."""
    lua = os.path.join(work, "find.lua")
    with open(lua, "w", encoding="ascii") as f:
        f.write('wrk.method = "POST"\nwrk.headers["Content-Type"] = "application/json"\n'
                "request = function()\n"
                '  local body = string.format(\'{"sceneId":"points","points":[{"x":%.6f,"y":%.6f}]}\','
                " math.random(), math.random())\n"
                "  return wrk.format(nil, nil, nil, body)\nend\n")
    url = f"http://127.0.0.1:{http_port}/gvd.v1.VoronoiService/FindNearest"
    out, cpu = load(["wrk", "-t", "2", "-c", "8", "-d", f"{seconds}s", "--latency", "-s", lua, url],
                    server_pid)
    if "Non-2xx" in out:
        raise SystemExit("wrk: failed calls\n" + out)

    def ms(text):
        value, unit = re.fullmatch(r"([\d.]+)(us|ms|s)", text).groups()
        return float(value) * {"us": 1e-3, "ms": 1.0, "s": 1e3}[unit]
    return {"per_s": float(re.search(r"Requests/sec:\s+([\d.]+)", out).group(1)),
            "p50_ms": ms(re.search(r"^\s*50%\s+(\S+)", out, re.M).group(1)),
            "p99_ms": ms(re.search(r"^\s*99%\s+(\S+)", out, re.M).group(1)), **cpu}


def capacity(pg, work, server_pid, grpc_port, http_port, seconds, rounds):
    """Single-point queries per second at 8 connections, p50 and p99 (ms), on "points":
    `rounds` rounds of PostGIS, gvd over gRPC and gvd over HTTP, `seconds` each, so that a
    slow spell of this shared machine falls on one round rather than on one side. Each side's
    figures are the medians of its rounds ("runs" lists them), and gvd's "vs_postgis" the
    median of its rounds' ratios to PostGIS's queries/s in the same round."""
    runs = {"postgis": [], "gvd_grpc": [], "gvd_http": []}
    for _ in range(rounds):
        runs["postgis"].append(pg_capacity(pg, work, seconds))
        runs["gvd_grpc"].append(grpc_capacity(work, server_pid, grpc_port, seconds))
        runs["gvd_http"].append(http_capacity(work, server_pid, http_port, seconds))
        for side in runs.values():  # a query's CPU (µs), each round's own
            r = side[-1]
            for fraction, per_query in (("generator_s", "generator_us"), ("server_s", "server_us")):
                if fraction in r:
                    r[per_query] = 1e6 * r[fraction] / r["per_s"]
    out = {}
    for side, rs in runs.items():
        out[side] = {key: statistics.median(r[key] for r in rs)
                     for key, value in rs[0].items() if not isinstance(value, str)}
        out[side]["runs"] = rs
        if side != "postgis":
            out[side]["vs_postgis"] = statistics.median(
                r["per_s"] / pg_r["per_s"] for r, pg_r in zip(rs, runs["postgis"]))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("server")
    ap.add_argument("--moves", type=int, default=600)
    ap.add_argument("--seconds", type=int, default=10)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--batch", type=int, default=100_000)
    ap.add_argument("--json")
    args = ap.parse_args()
    if args.rounds < 1 or args.seconds < 1:
        ap.error("--rounds and --seconds are at least 1")
    work = tempfile.mkdtemp(prefix="gvd-postgis-")
    os.chmod(work, 0o755)
    server, pg = None, None
    try:
        pg = Postgres(work)
        conn = psycopg2.connect(host=pg.sock, port=pg.port, user="gvd", dbname="gvd")
        conn.autocommit = True
        with conn.cursor() as cur:
            cur.execute("CREATE EXTENSION postgis")
        ports = os.path.join(work, "ports")
        with open(os.path.join(work, "gvd.log"), "w", encoding="ascii") as log:
            server, http_port = start_server(args.server, os.path.join(work, "gvd"), ports, log,
                                             "--log-level", "warn")
        grpc_port = read_ports(ports)[0]
        client = gvd.Client(f"127.0.0.1:{grpc_port}", timeout=600)
        http_client = gvd.Client(f"http://127.0.0.1:{http_port}", timeout=600)
        bare = GrpcioAlone(f"127.0.0.1:{grpc_port}")
        figures = {}
        for k, (name, make) in enumerate((("points", scene_points), ("segments", scene_segments),
                                          ("curves", scene_curves))):
            rng = np.random.default_rng(7)
            sites = make(rng)
            row = {"sites": len(sites),
                   "load_gvd_ms": 1000 * gvd_load(client, name, sites),
                   "load_postgis_ms": 1000 * pg_load(conn, name, sites)}
            row["move"] = moves({"grpc": client, "http": http_client, "grpcio": bare}, conn,
                                name, sites, args.moves, rng, first=k)
            row["batch"] = batch(client, conn, name, rng.random((args.batch, 2)))
            figures[name] = row
            print(name, json.dumps(row), flush=True)
        figures["floor"] = floor(bare, conn, args.moves)
        print("floor", json.dumps(figures["floor"]), flush=True)
        figures["capacity"] = capacity(pg, work, server.pid, grpc_port, http_port,
                                         args.seconds, args.rounds)
        print("capacity", json.dumps(figures["capacity"]), flush=True)
        print_table(figures, args.batch)
        if args.json:
            with open(args.json, "w", encoding="ascii") as f:
                json.dump(figures, f, indent=1)
    finally:
        if server:
            server.send_signal(signal.SIGTERM)
            server.wait()
        if pg:
            pg.stop()
        shutil.rmtree(work, ignore_errors=True)


def print_table(f, batch_size):
    print(f"\n| scene | load until queryable, gvd / PostGIS | one-site move until a read sees it, "
          f"p50 (p99), gvd over gRPC / gvd over HTTP / grpcio alone / PostGIS | "
          f"{batch_size:,}-query batch, "
          f"gvd / PostGIS |")
    print("|---|---|---|---|")
    for name in ("points", "segments", "curves"):
        r = f[name]
        m, b = r["move"], r["batch"]
        print(f"| {name} ({r['sites']:,}) | {r['load_gvd_ms']:.0f} / {r['load_postgis_ms']:.0f} ms "
              f"({r['load_postgis_ms'] / r['load_gvd_ms']:.2f}x) | "
              f"{m['gvd_grpc_p50_ms']:.2f} ({m['gvd_grpc_p99_ms']:.2f}) / "
              f"{m['gvd_http_p50_ms']:.2f} ({m['gvd_http_p99_ms']:.2f}) / "
              f"{m['gvd_grpcio_p50_ms']:.2f} ({m['gvd_grpcio_p99_ms']:.2f}) / "
              f"{m['postgis_p50_ms']:.2f} ({m['postgis_p99_ms']:.2f}) ms | "
              f"{b['gvd_ms']:.0f} / {b['postgis_ms']:.0f} ms "
              f"({b['postgis_ms'] / b['gvd_ms']:.0f}x faster; first run "
              f"{b['gvd_first_ms']:.0f} / {b['postgis_first_ms']:.0f} ms) |")
    fl = f["floor"]
    print(f"\nA call that does nothing, p50 (p99): grpcio (gRPC's health Check) "
          f"{fl['grpcio_p50_ms']:.3f} ({fl['grpcio_p99_ms']:.3f}) ms, psycopg2 (SELECT 1) "
          f"{fl['psycopg2_p50_ms']:.3f} ({fl['psycopg2_p99_ms']:.3f}) ms; each after 1 ms "
          f"idle: grpcio {fl['grpcio_paced_p50_ms']:.3f} ({fl['grpcio_paced_p99_ms']:.3f}) ms, "
          f"psycopg2 {fl['psycopg2_paced_p50_ms']:.3f} ({fl['psycopg2_paced_p99_ms']:.3f}) ms")
    c = f["capacity"]
    print(f"\n| single-point FindNearest, 8 connections, the median of {len(c['postgis']['runs'])} "
          f"rounds | queries/s (each round's) | p50 | p99 | vs PostGIS, the rounds' median | "
          f"CPU a query: the server's busiest threads by name; the load generator |")
    print("|---|---:|---:|---:|---:|---:|")
    for key, label in (("postgis", "PostGIS (pgbench)"), ("gvd_grpc", "gvd over gRPC (h2load)"),
                       ("gvd_http", "gvd over HTTP/JSON (wrk)")):
        r = c[key]
        each = ", ".join(f"{x['per_s']:,.0f}" for x in r["runs"])
        ratio = f"{r['vs_postgis']:.2f}x" if "vs_postgis" in r else ""
        server = (f"{r['server_us']:.1f} µs "
                  f"({r['runs'][0]['server_thread']}, busy {r['server_s']:.0%}); "
                  if "server_s" in r else "")
        print(f"| {label} | {r['per_s']:,.0f} ({each}) | {r['p50_ms']:.3f} ms | "
              f"{r['p99_ms']:.3f} ms | {ratio} | {server}"
              f"{r['generator_us']:.1f} µs |")


if __name__ == "__main__":
    main()
