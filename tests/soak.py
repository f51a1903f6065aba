#!/usr/bin/python3
"""Mixed load on a real gvd-server for a set time, with restarts, every answer checked.

Usage: soak.py --server GVD_SERVER --seconds N [--out DIR] [--restarts K] [--seed S]
              [--replicas N]

Starts GVD_SERVER on loopback with a store on disk and drives it over HTTP/JSON (the Connect
protocol, Python's standard library only):
  - one writer per long-lived scene: upserts (new sites, moves, degenerate segments, sites
    outside the window, duplicates) and deletes. As the only writer it knows the scene's
    sites at every version, so every answer below is checked against the version it names;
  - readers: FindNearest, raster and exact, with and without min_version, checked against
    an exact double-precision oracle (distance of the named site, the error bound's
    promise, min_version honoured);
  - analysis calls: Pick (exact nearest by the oracle), GetNeighbors and GetDelaunay (pairs and
    triangles name sites of their version), GetBoundaries;
  - scene churn: scenes created, filled, queried and deleted (then NOT_FOUND);
  - K restarts in the first half, alternately SIGTERM (must exit 0) and SIGKILL. A write in
    flight across a restart is resolved by the scene's version afterwards (the next version
    or not at all), and every scene's sites are compared with the writer's after each
    restart: nothing acknowledged may be lost. The second half runs without restarts, and
    resident memory is sampled throughout: its slope over the second half after a warm-up is
    reported.
At the end the scenes are compared once more, the server must stop cleanly on SIGTERM, and the
script exits 1 on any unexpected error or wrong answer. Errors are expected only while a
restart is under way (refused connections, UNAVAILABLE from a draining server). It prints
p50/p99 of each call and writes the figures to DIR/soak.json.

With --replicas N (2 or more) the same load runs on N gvd-servers sharing one PostgreSQL of
the soak's own (Debian's postgresql package). Each scene's writer goes through one replica;
readers, analysts and churn pick a replica per call, so a min_version acknowledged by one
replica is asked of another. The faults, in turn: SIGKILL of one replica, the database
stopped (fast) and started, SIGTERM of another replica, the database crashed (immediate)
and started. While the database is down, writes may fail with UNAVAILABLE (their effect is
resolved as across a restart, once every replica has caught up again) and reads go on, each
checked at its version. At the end every replica must hold every scene's acknowledged state.
"""
import argparse
import atexit
import http.client
import json
import os
import random
import shutil
import signal
import sys
import tempfile
import threading
import time

from gvdtest import Postgres, distance, percentile, start_server, value

SCENES = 4
WINDOW = (0.0, 0.0, 100.0, 100.0)
TOL = 1e-9


class RestartError(Exception):
    """The call met a restart or a database outage: no answer, no verdict."""


class CallError(Exception):
    def __init__(self, code, message):
        super().__init__(f"{code}: {message}")
        self.code = code


def normalized(site):
    """A site's JSON as it must come back from ListSites: numbers as floats, default (zero,
    empty) fields left out, as protobuf's JSON leaves them out."""
    if isinstance(site, dict):
        out = {k: normalized(v) for k, v in site.items()}
        return {k: v for k, v in out.items() if v not in (0, "", [], {}, False)}
    if isinstance(site, list):
        return [normalized(v) for v in site]
    return float(site) if isinstance(site, (int, float)) and not isinstance(site, bool) else site


class Server:
    """gvd-server on loopback, restarted in place on the same store (a directory, or the
    URL of a database that replicas share)."""

    def __init__(self, binary, workdir, store, name="server"):
        self.binary = binary
        self.store = store
        self.name = name
        self.port_file = os.path.join(workdir, name + ".port")
        self.lock = threading.Condition()
        self.generation = 0
        self.restarting = False
        self.degraded = False  # its database is down, or it has not caught up since
        self.database_down = False
        self.restarts = 0  # counts each restart's start and end
        self.outages = 0  # counts each database outage's start and end
        self.http_port = None
        self.proc = None
        self.log = open(os.path.join(workdir, name + ".log"), "ab")

    def start(self):
        self.proc, port = start_server(self.binary, self.store, self.port_file, self.log,
                                       "--log-level", "warn", timeout=300)
        with self.lock:
            self.http_port = port
            self.generation += 1
            self.restarts += 1
            self.restarting = False
            self.lock.notify_all()

    def degrade(self, degraded):
        """Marks the server's database down (True), or up with the server caught up (False)."""
        with self.lock:
            self.degraded = degraded
            self.outages += 1
            self.lock.notify_all()

    def restart(self, sig):
        """Stops the server with sig and starts it again; SIGTERM must end in exit 0."""
        with self.lock:
            self.restarting = True
            self.restarts += 1
        self.proc.send_signal(sig)
        code = self.proc.wait(timeout=120)
        if sig == signal.SIGTERM and code != 0:
            raise SystemExit(f"soak: SIGTERM ended {self.name} with {code}, not 0")
        self.start()

    def stop(self):
        with self.lock:
            self.restarting = True
        self.proc.send_signal(signal.SIGTERM)
        return self.proc.wait(timeout=120)

    def rss_kib(self):
        try:
            with open(f"/proc/{self.proc.pid}/status") as f:
                for line in f:
                    if line.startswith("VmRSS:"):
                        return int(line.split()[1])
        except OSError:
            pass
        return None

    def wait_serving(self):
        """Blocks while a restart or a database outage is under way."""
        with self.lock:
            while self.restarting or self.degraded:
                self.lock.wait(1)


# The calls that write to the store: while the database is down they may fail with
# UNAVAILABLE. Every other call must be answered, from the state the server holds.
WRITES = {"CreateScene", "DeleteScene", "UpsertSites", "DeleteSites"}


class Client:
    """One keep-alive HTTP connection, Connect unary calls in JSON."""

    def __init__(self, server, stats):
        self.server = server
        self.stats = stats
        self.conn = None
        self.port = None

    def call(self, method, body, timeout=120):
        with self.server.lock:
            seen = (self.server.restarts, self.server.outages)
            port, outage = self.server.http_port, self.server.database_down
            if self.server.restarting:
                raise RestartError(method)
        if self.conn is None or self.port != port:
            if self.conn:
                self.conn.close()
            self.conn = http.client.HTTPConnection("127.0.0.1", port, timeout=timeout)
            self.port = port
        data = json.dumps(body).encode()
        start = time.perf_counter()
        try:
            self.conn.request("POST", "/gvd.v1.VoronoiService/" + method, data,
                              {"Content-Type": "application/json"})
            response = self.conn.getresponse()
            payload = response.read()
        except (OSError, http.client.HTTPException) as e:
            self.conn.close()
            self.conn = None
            # A call that hung until the client's timeout is a failure, whatever happened.
            if not isinstance(e, TimeoutError) and self.during_restart(seen):
                raise RestartError(method) from e
            raise CallError("transport", f"{method}: {e!r}") from e
        elapsed = time.perf_counter() - start
        if response.status != 200:
            try:
                err = json.loads(payload)
            except ValueError:
                err = {"code": f"http {response.status}", "message": payload[:200].decode(errors="replace")}
            code = err.get("code", "?")
            if code == "unavailable" and (self.during_restart(seen) or
                                          (method in WRITES and self.during_outage(seen))):
                raise RestartError(method)
            raise CallError(code, f"{method}: {err.get('message', '')}")
        self.stats.latency(method, elapsed)
        if outage and method not in WRITES:
            self.stats.count("reads answered while the database was down")
        return json.loads(payload)

    def close(self):
        if self.conn:
            self.conn.close()
            self.conn = None

    def during_restart(self, seen):
        """Whether a restart of the server was under way, began or ended since `seen`."""
        with self.server.lock:
            return self.server.restarting or self.server.restarts != seen[0]

    def during_outage(self, seen):
        """Whether a database outage was under way, began or ended since `seen`."""
        with self.server.lock:
            return self.server.degraded or self.server.outages != seen[1]


class Stats:
    def __init__(self):
        self.lock = threading.Lock()
        self.latencies = {}
        self.counts = {}
        self.failures = []

    def latency(self, method, seconds):
        with self.lock:
            self.latencies.setdefault(method, []).append(seconds)

    def count(self, what, n=1):
        with self.lock:
            self.counts[what] = self.counts.get(what, 0) + n

    def fail(self, message):
        with self.lock:
            if len(self.failures) < 50:
                self.failures.append(message)
            print("soak: FAIL " + message, file=sys.stderr, flush=True)


class SceneModel:
    """What the single writer of a scene knows: its sites at each recent version."""

    def __init__(self, scene_id, points_only):
        self.scene_id = scene_id
        self.points_only = points_only  # GetDelaunay takes point sites only
        self.lock = threading.Lock()
        self.history = {}  # version -> {id: site}
        self.acked = 0
        self.pending = None

    def at(self, version):
        with self.lock:
            return self.history.get(version)

    def latest(self):
        with self.lock:
            return self.acked, self.history[self.acked]


def random_site(rng, sid, points_only):
    """Sites of every sort a user sends: mostly inside, some outside the window, degenerate
    (zero-length) segments, short polylines, additive weights small and huge; the writer adds
    duplicates of existing sites. The points-only scenes are the ones GetDelaunay is asked
    about, which takes unweighted points only."""
    lo, hi = (-20.0, 120.0) if rng.random() < 0.1 else (0.0, 100.0)
    x, y = rng.uniform(lo, hi), rng.uniform(lo, hi)
    r = rng.random()
    if points_only or r < 0.6:
        site = {"id": sid, "point": {"x": x, "y": y}}
    elif r < 0.65:
        site = {"id": sid, "segment": {"a": {"x": x, "y": y}, "b": {"x": x, "y": y}}}
    elif r < 0.9:
        site = {"id": sid, "segment": {"a": {"x": x, "y": y},
                                       "b": {"x": x + rng.uniform(-15, 15), "y": y + rng.uniform(-15, 15)}}}
    else:
        site = {"id": sid, "polyline": {"points": [
            {"x": x + rng.uniform(-10, 10), "y": y + rng.uniform(-10, 10)} for _ in range(rng.randint(2, 6))]}}
    if not points_only and rng.random() < 0.05:
        site["additiveWeight"] = rng.choice([rng.uniform(0, 5), 1e9])
    return site


def writer(server, stats, model, rng, stop):
    client = Client(server, stats)
    next_id = 0
    while not stop.is_set():
        version, sites = model.latest()
        new = dict(sites)
        if len(sites) > 40 and rng.random() < 0.25:
            ids = rng.sample(sorted(sites), rng.randint(1, 5))
            for i in ids:
                del new[i]
            method, body = "DeleteSites", {"sceneId": model.scene_id, "ids": ids}
        else:
            batch = {}
            for _ in range(rng.randint(1, 30)):
                if sites and rng.random() < 0.4:
                    sid = rng.choice(sorted(sites))
                elif sites and rng.random() < 0.05:  # a second site exactly on another's spot
                    sid = f"w{next_id}"
                    next_id += 1
                    batch[sid] = dict(sites[rng.choice(sorted(sites))], id=sid)
                    continue
                else:
                    sid = f"w{next_id}"
                    next_id += 1
                batch[sid] = random_site(rng, sid, model.points_only)
            if len(new) + len(batch) > 400:
                continue
            new.update(batch)
            method = "UpsertSites"
            body = {"sceneId": model.scene_id, "sites": list(batch.values())}
        with model.lock:
            model.history[version + 1] = new
            model.pending = version + 1
        try:
            answer = client.call(method, body)
        except RestartError:
            resolve(server, stats, model, client)
            continue
        except CallError as e:
            stats.fail(f"{model.scene_id} {method} at version {version}: {e}")
            with model.lock:
                del model.history[version + 1]
                model.pending = None
            continue
        got = int(answer.get("version", 0))
        if got != version + 1:
            stats.fail(f"{model.scene_id} {method} acknowledged version {got}, expected {version + 1}")
        with model.lock:
            model.acked = version + 1
            model.pending = None
            for old in [v for v in model.history if v < model.acked - 300]:
                del model.history[old]
        stats.count("writes acknowledged")
        time.sleep(rng.uniform(0, 0.02))


def list_sites(client, scene_id):
    sites, token, version = {}, "", None
    while True:
        page = client.call("ListSites", {"sceneId": scene_id, "pageSize": 1000, "pageToken": token})
        if version is not None and int(page.get("version", 0)) != version:
            return None, None  # a write came between pages: read again
        version = int(page.get("version", 0))
        for s in page.get("sites", []):
            sites[s["id"]] = s
        token = page.get("nextPageToken", "")
        if not token:
            return version, sites


def same_sites(a, b):
    return a.keys() == b.keys() and all(normalized(a[k]) == normalized(b[k]) for k in a)


def resolve(server, stats, model, client):
    """After a restart or an outage: the write in flight took effect entirely or not at all,
    and every acknowledged one is there."""
    while True:
        server.wait_serving()
        try:
            version, stored = list_sites(client, model.scene_id)
        except RestartError:
            continue
        except CallError as e:
            stats.fail(f"{model.scene_id} ListSites after a restart: {e}")
            return
        if version is not None:
            break
    with model.lock:
        pending, acked = model.pending, model.acked
        if pending is not None and version == pending:
            model.acked = pending
            stats.count("writes in flight at a restart, applied")
        elif pending is not None and version == acked:
            del model.history[pending]
            stats.count("writes in flight at a restart, not applied")
        elif version != acked:
            stats.fail(f"{model.scene_id} is at version {version} after a restart; "
                       f"acknowledged {acked}, in flight {pending}")
        model.pending = None
        expected = model.history.get(version)
    if expected is not None and not same_sites(stored, expected):
        stats.fail(f"{model.scene_id} at version {version} after a restart holds "
                   f"{len(stored)} sites, not the {len(expected)} acknowledged")
    stats.count("scenes compared after restarts")


def check_nearest(stats, where, sites, x, y, r, measure=value):
    """The contract of an answer (NearestSite, or Pick's with measure=distance): `distance` is
    the named site's exact value at the point, and no site's value is below it by more than
    the error bound (zero when exact)."""
    if not sites:
        if not r.get("empty"):
            stats.fail(f"{where}: an empty scene answered {r}")
        return
    best = min(measure((x, y), s) for s in sites.values())
    sid = r.get("siteId", "")
    if sid not in sites:
        stats.fail(f"{where}: ({x}, {y}) answered {sid!r}, not a site of that version")
        return
    d = r.get("distance", 0.0)
    own = measure((x, y), sites[sid])
    if abs(own - d) > TOL * (1 + own):
        stats.fail(f"{where}: ({x}, {y}) {sid} at distance {d}, the oracle says {own}")
    bound = 0.0 if r.get("exact") else r.get("errorBound", 0.0)
    if best < d - bound - TOL * (1 + d):
        stats.fail(f"{where}: ({x}, {y}) {sid} at {d} +- {bound}, but the nearest is at {best}")


def versioned_call(server, stats, client, model, method, body, min_version):
    """Calls `method` on the model's scene: the answer, its version and the scene's sites at
    that version; None when the call met a restart, failed (a failure is recorded) or
    answered at a version the writer no longer keeps."""
    try:
        answer = client.call(method, body)
    except RestartError:
        server.wait_serving()
        return None
    except CallError as e:
        stats.fail(f"{model.scene_id} {method}: {e}")
        return None
    version = int(answer.get("version", 0))
    if min_version is not None and version < min_version:
        stats.fail(f"{model.scene_id} {method} min_version {min_version} answered at {version}")
    sites = model.at(version)
    if sites is None:
        stats.count("answers at a version no longer kept")
        return None
    return answer, version, sites


def reader(servers, stats, models, rng, stop):
    clients = [Client(server, stats) for server in servers]
    while not stop.is_set():
        k = rng.randrange(len(servers))
        server, client = servers[k], clients[k]
        model = rng.choice(models)
        acked, _ = model.latest()
        exact = rng.random() < 0.5
        body = {"sceneId": model.scene_id, "exact": exact,
                "points": [{"x": rng.uniform(-10, 110), "y": rng.uniform(-10, 110)}
                           for _ in range(rng.randint(1, 64))]}
        if rng.random() < 0.5:
            body["minVersion"] = str(acked)
        got = versioned_call(server, stats, client, model, "FindNearest", body,
                             acked if "minVersion" in body else None)
        if got is None:
            continue
        answer, version, sites = got
        for p, r in zip(body["points"], answer.get("results", [])):
            check_nearest(stats, f"{model.scene_id} v{version}", sites, p["x"], p["y"], r)
        if len(answer.get("results", [])) != len(body["points"]):
            stats.fail(f"{model.scene_id} FindNearest: {len(body['points'])} points, "
                       f"{len(answer.get('results', []))} answers")
        stats.count("nearest answers checked", len(body["points"]))


def analyst(servers, stats, models, rng, stop):
    clients = [Client(server, stats) for server in servers]
    while not stop.is_set():
        k = rng.randrange(len(servers))
        server, client = servers[k], clients[k]
        model = rng.choice(models)
        acked, _ = model.latest()
        method = rng.choice(["Pick", "Pick", "GetNeighbors", "GetBoundaries"] +
                            (["GetDelaunay"] if model.points_only else []))
        x, y = rng.uniform(0, 100), rng.uniform(0, 100)
        if method == "Pick":
            body = {"sceneId": model.scene_id, "point": {"x": x, "y": y}}
        else:
            body = {"sceneId": model.scene_id, "minVersion": str(acked)}
        got = versioned_call(server, stats, client, model, method, body,
                             None if method == "Pick" else acked)
        if got is None:
            continue
        answer, version, sites = got
        if method == "Pick":
            if answer.get("found"):
                answer["exact"] = True
                check_nearest(stats, f"{model.scene_id} Pick v{version}", sites, x, y, answer,
                              measure=distance)
            elif sites:
                stats.fail(f"{model.scene_id} Pick found nothing among {len(sites)} sites")
        else:
            names = [p.get("siteA", "") for p in answer.get("pairs", answer.get("edges", []))]
            names += [p.get("siteB", "") for p in answer.get("pairs", answer.get("edges", []))]
            names += [t.get(k, "") for t in answer.get("triangles", []) for k in "abc"]
            names += [b.get(k, "") for b in answer.get("boundaries", []) for k in ("siteA", "siteB")]
            unknown = {n for n in names if n and n not in sites}
            if unknown:
                stats.fail(f"{model.scene_id} {method} v{version} names {sorted(unknown)[:3]}, "
                           "no sites of that version")
        stats.count(f"{method} answers checked")


def churn(servers, stats, rng, stop):
    clients = [Client(server, stats) for server in servers]
    n = 0
    while not stop.is_set():
        k = rng.randrange(len(servers))
        server, client = servers[k], clients[k]
        n += 1
        scene_id = f"churn-{os.getpid()}-{n}"
        size = rng.choice([64, 128, 256])
        try:
            client.call("CreateScene", {"sceneId": scene_id, "widthPx": size, "heightPx": size,
                                        "window": {"minX": 0, "minY": 0, "maxX": 100, "maxY": 100}})
            sites = {f"c{i}": random_site(rng, f"c{i}", False) for i in range(50)}
            answer = client.call("UpsertSites", {"sceneId": scene_id, "sites": list(sites.values())})
            points = [{"x": rng.uniform(0, 100), "y": rng.uniform(0, 100)} for _ in range(16)]
            near = client.call("FindNearest", {"sceneId": scene_id, "points": points,
                                               "minVersion": answer["version"]})
            for p, r in zip(points, near.get("results", [])):
                check_nearest(stats, scene_id, sites, p["x"], p["y"], r)
            client.call("DeleteScene", {"sceneId": scene_id})
            try:
                client.call("GetScene", {"sceneId": scene_id})
                stats.fail(f"{scene_id} still there after DeleteScene")
            except CallError as e:
                if e.code != "not_found":
                    stats.fail(f"GetScene of deleted {scene_id}: {e}")
            stats.count("scenes created and deleted")
        except RestartError:
            server.wait_serving()
            cleanup(server, stats, client, scene_id)
        except CallError as e:
            stats.fail(f"{scene_id}: {e}")


def cleanup(server, stats, client, scene_id):
    """A churn scene interrupted by a restart: created or not, it goes."""
    while True:
        try:
            client.call("DeleteScene", {"sceneId": scene_id})
            return
        except RestartError:
            server.wait_serving()
        except CallError as e:
            if e.code != "not_found":
                stats.fail(f"DeleteScene {scene_id} after a restart: {e}")
            return


def slope_mib_per_min(samples):
    if len(samples) < 3:
        return float("nan")
    ts = [t for t, _ in samples]
    rs = [r / 1024.0 for _, r in samples]
    mt, mr = sum(ts) / len(ts), sum(rs) / len(rs)
    den = sum((t - mt) ** 2 for t in ts)
    return 60.0 * sum((t - mt) * (r - mr) for t, r in zip(ts, rs)) / den if den else float("nan")


def wait_caught_up(server, stats, models, since):
    """Blocks until the server has read the store's heads after `since` (a time.monotonic()
    when the database was up again) and holds every scene at the version they said."""
    client = Client(server, stats)
    deadline = time.monotonic() + 120
    try:
        for model in models:
            while True:
                try:
                    scene = client.call("GetScene", {"sceneId": model.scene_id}).get("scene", {})
                except CallError as e:
                    # A replica learns of a scene made through another from the log: until
                    # it has read it, the scene is not found there.
                    if e.code != "not_found":
                        stats.fail(f"GetScene {model.scene_id} on {server.name}: {e}")
                        return
                    scene = None
                if scene is not None:
                    age = float(scene.get("storeReadAgeSeconds", 0.0))
                    read_after = time.monotonic() - age > since
                    if read_after and int(scene.get("version", 0)) >= int(scene.get("storeVersion", 0)):
                        break
                if time.monotonic() > deadline:
                    stats.fail(f"{server.name} did not hold {model.scene_id} at its stored "
                               "version within 120 s")
                    return
                time.sleep(0.1)
    finally:
        client.close()


def database_outage(pg, servers, stats, models, mode):
    """Stops the database (mode "fast" or "immediate") for two seconds under the load."""
    def down(flag):
        for server in servers:
            with server.lock:
                server.database_down = flag

    for server in servers:
        server.degrade(True)
    down(True)
    pg.stop(mode)
    time.sleep(2)
    pg.start()
    down(False)
    since = time.monotonic()
    for server in servers:
        wait_caught_up(server, stats, models, since)
        server.degrade(False)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--server", required=True)
    ap.add_argument("--seconds", type=float, default=60)
    ap.add_argument("--restarts", type=int, default=None,
                    help="faults in the first half (default: one per minute of it, at least 2; "
                    "with replicas one per half minute, at least 4)")
    ap.add_argument("--readers", type=int, default=3)
    ap.add_argument("--replicas", type=int, default=0,
                    help="gvd-servers sharing one PostgreSQL (default: one server on SQLite)")
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    if args.replicas == 1:
        ap.error("--replicas needs at least 2")
    seed = args.seed if args.seed is not None else random.randrange(1 << 30)
    if args.restarts is not None:
        restarts = args.restarts
    elif args.replicas:
        restarts = max(4, int(args.seconds / 60))
    else:
        restarts = max(2, int(args.seconds / 120))
    workdir = tempfile.mkdtemp(prefix="gvd-soak-")
    out = args.out or workdir
    os.makedirs(out, exist_ok=True)
    print(f"soak: {args.seconds:.0f} s, {restarts} faults, seed {seed}, "
          f"{f'{args.replicas} replicas on PostgreSQL' if args.replicas else 'one server'}, "
          f"work in {workdir}", flush=True)

    pg = None
    if args.replicas:
        os.chmod(workdir, 0o755)
        pg = Postgres(workdir)
        atexit.register(pg.stop)
        servers = [Server(args.server, workdir, pg.url, f"replica-{k}")
                   for k in range(args.replicas)]
        # In turn: a replica killed, the database stopped, another replica stopped, the
        # database crashed.
        faults = [("replica", 0, signal.SIGKILL), ("database", "fast"),
                  ("replica", 1, signal.SIGTERM), ("database", "immediate")]
    else:
        servers = [Server(args.server, workdir, os.path.join(workdir, "store.db"))]
        faults = [("replica", 0, signal.SIGTERM), ("replica", 0, signal.SIGKILL)]
    atexit.register(lambda: [s.proc.kill() for s in servers if s.proc and s.proc.poll() is None])
    for server in servers:
        server.start()
    stats = Stats()
    setup = Client(servers[0], stats)
    models = []
    for i in range(SCENES):
        model = SceneModel(f"soak-{i}", points_only=i % 2 == 0)
        setup.call("CreateScene", {
            "sceneId": model.scene_id, "widthPx": 512, "heightPx": 512,
            "window": {"minX": WINDOW[0], "minY": WINDOW[1], "maxX": WINDOW[2], "maxY": WINDOW[3]}})
        # A raster read of a scene without sites is refused (FAILED_PRECONDITION): each
        # starts with some.
        rng = random.Random(seed - i)
        first = {f"s{k}": random_site(rng, f"s{k}", model.points_only) for k in range(20)}
        answer = setup.call("UpsertSites", {"sceneId": model.scene_id, "sites": list(first.values())})
        model.acked = int(answer["version"])
        model.history[model.acked] = first
        models.append(model)

    # Every replica holds every scene before the load starts (a replica learns of a scene
    # made through another from the log).
    for server in servers[1:]:
        wait_caught_up(server, stats, models, 0.0)

    stop = threading.Event()
    # Each scene has one writer, through one server.
    threads = [threading.Thread(target=writer, args=(servers[i % len(servers)], stats, m,
                                                     random.Random(seed + i), stop))
               for i, m in enumerate(models)]
    threads += [threading.Thread(target=reader, args=(servers, stats, models,
                                                      random.Random(seed + 100 + i), stop))
                for i in range(args.readers)]
    threads.append(threading.Thread(target=analyst, args=(servers, stats, models,
                                                          random.Random(seed + 200), stop)))
    threads.append(threading.Thread(target=churn, args=(servers, stats, random.Random(seed + 300), stop)))
    for t in threads:
        t.daemon = True
        t.start()

    start = time.time()
    half = args.seconds / 2
    fault_at = [start + half * (k + 1) / (restarts + 1) for k in range(restarts)]
    watched = servers[0]  # whose resident memory is sampled
    rss = []  # (seconds since start, KiB, generation)
    done = 0
    while time.time() - start < args.seconds and not stats.failures:
        if done < len(fault_at) and time.time() >= fault_at[done]:
            fault = faults[done % len(faults)]
            if fault[0] == "replica":
                server = servers[fault[1]]
                print(f"soak: {time.time() - start:5.1f} s  {signal.Signals(fault[2]).name} "
                      f"{server.name}", flush=True)
                server.restart(fault[2])
            else:
                print(f"soak: {time.time() - start:5.1f} s  database stopped ({fault[1]})",
                      flush=True)
                database_outage(pg, servers, stats, models, fault[1])
            done += 1
            continue
        kib = watched.rss_kib()
        if kib:
            rss.append((time.time() - start, kib, watched.generation))
        time.sleep(0.5)
    stop.set()
    for t in threads:
        t.join(timeout=180)

    # Every server holds every scene's acknowledged state (a replica within 60 s).
    for server in servers:
        final = Client(server, stats)
        for model in models:
            deadline = time.monotonic() + 60
            while True:
                version, stored = list_sites(final, model.scene_id)
                with model.lock:
                    expected = model.history.get(version)
                    acked = model.acked
                if version == acked and expected is not None and same_sites(stored, expected):
                    break
                if time.monotonic() > deadline or not args.replicas:
                    stats.fail(f"{model.scene_id} on {server.name} at the end: version {version}, "
                               f"acknowledged {acked}")
                    break
                time.sleep(0.2)
    for server in servers:
        code = server.stop()
        if code != 0:
            stats.fail(f"the final SIGTERM ended {server.name} with {code}")

    last = [(t, k) for t, k, g in rss if g == watched.generation]
    warm = [(t, k) for t, k in last if t >= (last[0][0] + 0.25 * (last[-1][0] - last[0][0]))] if last else []
    report = {
        "seconds": args.seconds, "seed": seed, "restarts": done, "replicas": args.replicas,
        "counts": stats.counts, "failures": stats.failures,
        "rss_mib_after_warmup": warm[0][1] / 1024.0 if warm else None,
        "rss_mib_at_end": warm[-1][1] / 1024.0 if warm else None,
        "rss_slope_mib_per_min": slope_mib_per_min(warm),
        "rss_window_seconds": (warm[-1][0] - warm[0][0]) if warm else 0,
        "calls": {m: {"count": len(v), "p50_ms": 1e3 * percentile(v, 0.5),
                      "p99_ms": 1e3 * percentile(v, 0.99), "max_ms": 1e3 * max(v)}
                  for m, v in sorted(stats.latencies.items())},
    }
    with open(os.path.join(out, "soak.json"), "w") as f:
        json.dump(report, f, indent=1)
    print(f"{'call':<16}{'count':>8}{'p50 ms':>10}{'p99 ms':>10}{'max ms':>10}")
    for m, c in report["calls"].items():
        print(f"{m:<16}{c['count']:>8}{c['p50_ms']:>10.2f}{c['p99_ms']:>10.2f}{c['max_ms']:>10.1f}")
    for k, v in sorted(stats.counts.items()):
        print(f"  {k}: {v}")
    if warm:
        print(f"resident memory over the last {report['rss_window_seconds']:.0f} s after warm-up: "
              f"{report['rss_mib_after_warmup']:.1f} -> {report['rss_mib_at_end']:.1f} MiB, "
              f"slope {report['rss_slope_mib_per_min']:+.2f} MiB/min")
    print(f"figures in {os.path.join(out, 'soak.json')}")
    if stats.failures:
        print(f"soak: {len(stats.failures)} failure(s); server logs in {workdir}", file=sys.stderr)
        return 1
    needed = ["writes acknowledged", "nearest answers checked", "Pick answers checked",
              "scenes created and deleted", "scenes compared after restarts"]
    if args.replicas:
        needed.append("reads answered while the database was down")
    missing = [k for k in needed if not stats.counts.get(k)]
    if missing:
        print(f"soak: nothing was {missing}: the load did not run", file=sys.stderr)
        return 1
    print("soak: no unexpected errors, every answer matched its version, nothing acknowledged lost")
    if pg:
        pg.stop()
        shutil.rmtree(pg.data, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
