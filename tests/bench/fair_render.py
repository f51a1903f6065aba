#!/usr/bin/python3
"""A small scene's updates while a huge render runs in another scene, with one render thread
and with the default two.

Usage: fair_render.py GVD_SERVER [--polylines N] [--points N] [--size PX]

For each --render-threads value (1, then 2) it starts GVD_SERVER on loopback (store in memory),
creates "big" (PX x PX) and "small" (256 x 256, 100 points), then upserts N random polylines of
M points each into "big" (the case a user met: 20 polylines of 5,000 points). Until that
version of "big" is published, it moves one site of "small" and polls GetScene over HTTP/JSON
until that version is published, one move after another, and reports how long each took
(update to published frame) and how long the big render took.
"""
import argparse
import json
import os
import random
import tempfile
import threading
import time
import http.client
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from gvdtest import percentile, start_server  # noqa: E402


def call(port, method, body):
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=600)
    conn.request("POST", "/gvd.v1.VoronoiService/" + method, json.dumps(body).encode(),
                 {"Content-Type": "application/json"})
    response = conn.getresponse()
    payload = response.read()
    conn.close()
    if response.status != 200:
        raise RuntimeError(f"{method}: {payload[:300]!r}")
    return json.loads(payload)


def rendered(port, scene, version, pause):
    """Returns once the scene's published frame is at `version` or later (a FindNearest at a
    version would not wait for it: the index answers while the frame is drawn)."""
    while True:
        got = call(port, "GetScene", {"sceneId": scene})["scene"].get("renderedVersion", 0)
        if int(got) >= int(version):
            return
        time.sleep(pause)


def run(server, threads, args):
    work = tempfile.mkdtemp(prefix="gvd-fair-")
    proc, port = start_server(server, ":memory:", os.path.join(work, "port"),
                              open(os.path.join(work, "log"), "w"), "--log-level", "warn",
                              "--render-threads", str(threads))
    try:
        window = {"minX": 0, "minY": 0, "maxX": 1, "maxY": 1}
        call(port, "CreateScene", {"sceneId": "big", "widthPx": args.size, "heightPx": args.size,
                                   "window": window})
        call(port, "CreateScene", {"sceneId": "small", "widthPx": 256, "heightPx": 256,
                                   "window": window})
        rng = random.Random(1)
        small = call(port, "UpsertSites", {"sceneId": "small", "sites": [
            {"id": f"p{i}", "point": {"x": rng.random(), "y": rng.random()}} for i in range(100)]})
        call(port, "FindNearest", {"sceneId": "small", "points": [{"x": 0.5, "y": 0.5}],
                                   "minVersion": small["version"]})
        sites = [{"id": f"l{i}", "polyline": {"points": [
            {"x": rng.random(), "y": rng.random()} for _ in range(args.points)]}}
            for i in range(args.polylines)]
        big = call(port, "UpsertSites", {"sceneId": "big", "sites": sites})
        start = time.perf_counter()
        done = threading.Event()
        render = {}

        def wait_big():
            rendered(port, "big", big["version"], 0.005)
            render["seconds"] = time.perf_counter() - start
            done.set()
        threading.Thread(target=wait_big, daemon=True).start()
        rounds = []
        while not done.is_set():
            t0 = time.perf_counter()
            v = call(port, "UpsertSites", {"sceneId": "small", "sites": [
                {"id": "p0", "point": {"x": rng.random(), "y": rng.random()}}]})
            rendered(port, "small", v["version"], 0)
            rounds.append(time.perf_counter() - t0)
        done.wait()
        return render["seconds"], rounds
    finally:
        proc.terminate()
        proc.wait()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("server")
    ap.add_argument("--polylines", type=int, default=20)
    ap.add_argument("--points", type=int, default=5000)
    ap.add_argument("--size", type=int, default=2048)
    args = ap.parse_args()
    print(f"big: {args.polylines} random polylines of {args.points} points, "
          f"{args.size}x{args.size}; small: 256x256, one-point moves")
    print("| render threads | big render | small updates published meanwhile | p50 | p99 | max |")
    print("|---|---|---|---|---|---|")
    for threads in (1, 2):
        seconds, rounds = run(args.server, threads, args)
        ms = [1e3 * r for r in rounds]
        print(f"| {threads} | {seconds:.1f} s | {len(ms)} | {percentile(ms, 0.5):.1f} ms | "
              f"{percentile(ms, 0.99):.1f} ms | {max(ms):.1f} ms |", flush=True)


if __name__ == "__main__":
    main()
