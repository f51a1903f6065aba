"""What the Python tests share: gvd-server started on loopback with its HTTP/JSON calls, a
PostgreSQL of their own, and an exact oracle over the API's JSON sites, written for the tests (distances in double precision
from the sites' geometry, Bezier curves sampled and refined on the curve itself), never the
server's own code.
"""
import collections
import glob
import json
import math
import os
import shutil
import signal
import socket
import subprocess
import tempfile
import time
import urllib.error
import urllib.request

import numpy as np


def read_ports(port_file):
    """The gRPC and HTTP ports that gvd-server wrote to its --port-file."""
    with open(port_file, encoding="ascii") as f:
        grpc, http = f.read().split()[:2]
    return int(grpc), int(http)


def threads(pid):
    """CPU ticks and context switches of the process's threads, summed by thread name: a
    Counter of name -> ticks and (name, "switches") -> count. A thread that ends between two
    readings takes its counts with it."""
    out = collections.Counter()
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            with open(f"/proc/{pid}/task/{tid}/stat", encoding="ascii") as f:
                stat = f.read()
            with open(f"/proc/{pid}/task/{tid}/status", encoding="ascii") as f:
                status = f.read().splitlines()
        except OSError:  # the thread ended
            continue
        name = stat[stat.index("(") + 1:stat.rindex(")")]
        fields = stat[stat.rindex(")") + 2:].split()
        out[name] += int(fields[11]) + int(fields[12])  # utime, stime
        for line in status:
            if line.startswith(("voluntary_ctxt_switches", "nonvoluntary_ctxt_switches")):
                out[(name, "switches")] += int(line.split()[1])
    return out


def start_server(binary, data, port_file, log, *flags, timeout=60):
    """Starts gvd-server on loopback ports of its choosing, storing in `data` (a directory,
    or a --store URL such as postgresql://...); returns the process and its HTTP port once
    it serves (read_ports gives the gRPC port too)."""
    if os.path.exists(port_file):
        os.remove(port_file)
    store = ["--store", data] if "://" in data else ["--data", data]
    process = subprocess.Popen(
        [binary, "--listen", "127.0.0.1:0", "--http-listen", "127.0.0.1:0",
         "--port-file", port_file, *store, *flags],
        stdout=subprocess.DEVNULL, stderr=log)
    deadline = time.monotonic() + timeout
    while not os.path.exists(port_file):
        if process.poll() is not None or time.monotonic() > deadline:
            process.kill()
            raise RuntimeError(f"gvd-server did not start (exit {process.poll()}); log: {log.name}")
        time.sleep(0.05)
    return process, read_ports(port_file)[1]


class Postgres:
    """A PostgreSQL cluster of the caller's own, from Debian's postgresql package: made by
    initdb in workdir/pg, listening on a Unix socket in workdir and on no TCP address, run as
    the postgres user when this runs as root (PostgreSQL refuses root). `url` is its
    database "gvd"."""

    def __init__(self, workdir, *settings):
        found = sorted(glob.glob("/usr/lib/postgresql/*/bin/pg_ctl"))
        if not found:
            raise RuntimeError("no PostgreSQL server (install Debian's postgresql package)")
        self.bindir = os.path.dirname(found[-1])
        self.data, self.sock = os.path.join(workdir, "pg"), workdir
        self.as_pg = ["runuser", "-u", "postgres", "--"] if os.getuid() == 0 else []
        if os.getuid() == 0:
            shutil.chown(workdir, "postgres")
        with socket.socket() as s:  # a port number for the socket's name, free on loopback
            s.bind(("127.0.0.1", 0))
            self.port = s.getsockname()[1]
        self.settings = ["-c", "listen_addresses=", "-c", "max_connections=200", *settings]
        subprocess.run(self.as_pg + [f"{self.bindir}/initdb", "-D", self.data, "-A", "trust",
                                     "-U", "gvd", "-E", "UTF8"], check=True,
                       stdout=subprocess.DEVNULL)
        self.start()
        try:
            subprocess.run(self.as_pg + [f"{self.bindir}/createdb", "-h", self.sock, "-p",
                                         str(self.port), "-U", "gvd", "gvd"], check=True)
        except subprocess.CalledProcessError:
            self.stop()
            raise
        self.url = f"postgresql://gvd@/gvd?host={self.sock}&port={self.port}"

    def start(self):
        options = " ".join([f"-k {self.sock}", f"-p {self.port}", *self.settings])
        subprocess.run(self.as_pg + [f"{self.bindir}/pg_ctl", "-D", self.data, "-l",
                                     os.path.join(self.sock, "pg.log"), "-w", "-o", options,
                                     "start"], check=True, stdout=subprocess.DEVNULL)

    def stop(self, mode="fast"):
        """"fast": clients disconnected, a clean shutdown; "immediate": as a crash."""
        if not os.path.isdir(self.data):
            return
        subprocess.run(self.as_pg + [f"{self.bindir}/pg_ctl", "-D", self.data, "-m", mode, "-w",
                                     "stop"], check=False, stdout=subprocess.DEVNULL)


def percentile(values, q):
    """The nearest-rank q-quantile of values (q = 0.99: the p99)."""
    values = sorted(values)
    return values[min(len(values) - 1, max(0, math.ceil(q * len(values)) - 1))]


class Server:
    """gvd-server on loopback ports of its choosing, with its own data directory."""

    def __init__(self, binary, *flags):
        self.dir = tempfile.mkdtemp(prefix="gvd-test-")
        self.log_path = os.path.join(self.dir, "log")
        self.log = open(self.log_path, "w")
        self.process, self.http_port = start_server(
            binary, os.path.join(self.dir, "data"), os.path.join(self.dir, "ports"), self.log, *flags)
        self.url = f"http://127.0.0.1:{self.http_port}"

    def stop(self):
        self.process.send_signal(signal.SIGTERM)
        try:
            self.process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            self.process.kill()
        self.log.close()
        shutil.rmtree(self.dir, ignore_errors=True)

    def call(self, method, request, token=None, body=None, content_type="application/json"):
        """A unary call over HTTP/JSON: (HTTP status, decoded JSON answer)."""
        data = body if body is not None else json.dumps(request).encode()
        headers = {"Content-Type": content_type}
        if token:
            headers["Authorization"] = f"Bearer {token}"
        r = urllib.request.Request(f"{self.url}/gvd.v1.VoronoiService/{method}", data=data, headers=headers)
        try:
            with urllib.request.urlopen(r, timeout=120) as response:
                return response.status, json.loads(response.read() or b"{}")
        except urllib.error.HTTPError as e:
            return e.code, json.loads(e.read() or b"{}")

    def ok(self, method, request, token=None):
        status, answer = self.call(method, request, token)
        if status != 200:
            raise AssertionError(f"{method}: HTTP {status} {answer}")
        return answer


# ---- the exact oracle ----

def to_segment(q, a, b):
    ax, ay = a
    dx, dy = b[0] - ax, b[1] - ay
    length2 = dx * dx + dy * dy
    t = 0.0 if length2 == 0 else max(0.0, min(1.0, ((q[0] - ax) * dx + (q[1] - ay) * dy) / length2))
    return math.hypot(q[0] - (ax + t * dx), q[1] - (ay + t * dy))


def bezier_point(control, t):
    """The curve at t by de Casteljau's construction; t may be a NumPy array of parameters."""
    p = list(control)
    for k in range(len(p) - 1, 0, -1):
        p = [(p[i][0] + t * (p[i + 1][0] - p[i][0]), p[i][1] + t * (p[i + 1][1] - p[i][1])) for i in range(k)]
    return p[0]


def to_bezier(q, control):
    """Distance to the curve itself: the best of 2,049 samples, refined by golden sections."""
    def d(t):
        x, y = bezier_point(control, t)
        return np.hypot(q[0] - x, q[1] - y)
    n = 2048
    best = int(np.argmin(d(np.arange(n + 1) / n)))  # the first of equals, as min() would
    lo, hi = max(0.0, (best - 1) / n), min(1.0, (best + 1) / n)
    g = (math.sqrt(5) - 1) / 2
    for _ in range(60):
        a, b = hi - g * (hi - lo), lo + g * (hi - lo)
        if d(a) < d(b):
            hi = b
        else:
            lo = a
    return float(min(d(0.0), d(1.0), d((lo + hi) / 2), d(best / n)))


def points_of(site, key):
    return [(p.get("x", 0.0), p.get("y", 0.0)) for p in site.get(key, [])]


def path_pieces(site):
    """A path's pieces, subpath after subpath: (control points, closed), a line's its two ends."""
    for sub in site["path"].get("subpaths", []):
        v = points_of(sub, "points")
        degrees = sub.get("degrees") or [1] * (len(v) - 1)
        k = 0
        for d in degrees:
            yield v[k:k + d + 1], sub.get("closed", False)
            k += d
        if sub.get("closed", False) and v[k] != v[0]:
            yield [v[k], v[0]], True


def distance(q, site):
    """Euclidean distance from q to the site's geometry (a polygon's boundary, a path's pieces):
    Pick's measure, weights and sides aside."""
    if "point" in site:
        p = site["point"]
        return math.hypot(q[0] - p.get("x", 0.0), q[1] - p.get("y", 0.0))
    if "segment" in site:
        s = site["segment"]
        a, b = s.get("a", {}), s.get("b", {})
        return to_segment(q, (a.get("x", 0.0), a.get("y", 0.0)), (b.get("x", 0.0), b.get("y", 0.0)))
    if "polyline" in site or "polygon" in site:
        v = points_of(site["polyline"], "points") if "polyline" in site else points_of(site["polygon"], "vertices")
        pairs = list(zip(v, v[1:])) + ([(v[-1], v[0])] if "polygon" in site else [])
        return min(to_segment(q, a, b) for a, b in pairs)
    if "path" in site:
        return min(to_segment(q, *c) if len(c) == 2 else to_bezier(q, c) for c, _ in path_pieces(site))
    return to_bezier(q, points_of(site["bezier"], "controlPoints"))


def inside(q, v):
    """Whether q is inside the polygon with vertices v (even-odd rule)."""
    result = False
    for (ax, ay), (bx, by) in zip(v, v[1:] + v[:1]):
        if (ay > q[1]) != (by > q[1]) and q[0] < ax + (q[1] - ay) * (bx - ax) / (by - ay):
            result = not result
    return result


def inside_path(q, site):
    """Whether q is inside a path of lines (its closed subpaths' winding number by its fill rule);
    the inside of curves is their drawn polylines', which this oracle does not know."""
    winding = 0
    for c, closed in path_pieces(site):
        assert len(c) == 2, "the oracle knows the inside of paths of lines only"
        (ax, ay), (bx, by) = c
        if closed and (ay > q[1]) != (by > q[1]) and q[0] < ax + (q[1] - ay) * (bx - ax) / (by - ay):
            winding += 1 if by > ay else -1
    return winding % 2 == 1 if site["path"].get("fillRule") == "FILL_RULE_EVEN_ODD" else winding != 0


def value(q, site):
    """The site's value in the diagram (a DIAGRAM_NEAREST one): m d + a, or infinity where the site
    does not reach (beyond max_distance, or on the side of a polygon or path it leaves out)."""
    d = distance(q, site)
    if site.get("maxDistance") and d > site["maxDistance"]:
        return math.inf
    side = site.get("polygon", site.get("path", {})).get("side", "SIDE_UNSPECIFIED")
    if side != "SIDE_UNSPECIFIED" and d > 0:
        within = inside(q, points_of(site["polygon"], "vertices")) if "polygon" in site else inside_path(q, site)
        if within != (side == "SIDE_INSIDE"):
            return math.inf
    return site.get("multiplicativeWeight", 1) * d + site.get("additiveWeight", 0)


def slack(site):
    """How far the server's distance may be from the oracle's: a Bezier, or a path's curves, is
    drawn as its flattening, within the tolerance; all else to rounding."""
    for kind in ("bezier", "path"):
        if kind in site:
            return site[kind].get("tolerance", 0.0) + 1e-9
    return 1e-9
