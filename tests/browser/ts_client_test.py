#!/usr/bin/python3
"""The TypeScript client (@gvd/client, client/ts) in a real browser: Debian's Chromium, driven
by Selenium, loads a page from another origin that imports the client's browser bundle, and
calls a real gvd-server on loopback across origins (--http-cors-origins), in binary and in
JSON. Answers are judged by a NumPy brute-force oracle here, not by the server.

Usage: ts_client_test.py --server PATH/gvd-server --bundle PATH/gvd-client.bundle.js
The bundle is what `npm run build` in client/ts writes (ctest's ts_client runs it first).
"""

import argparse
import functools
import http.server
import os
import shutil
import sys
import tempfile
import threading
import unittest

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gvdtest  # noqa: E402
from selection_test import browser, close  # noqa: E402  (Chromium, as the app's tests run it)

ARGS = None

PAGE = """<!doctype html>
<meta charset="utf-8">
<title>@gvd/client</title>
<script type="module">
import * as gvd from "./gvd-client.js";
window.gvd = gvd;
window.ready = true;
</script>
"""

# Runs in the page: arguments[0] is the server's URL, [1] whether to speak binary, then the
# test's own; the last is Selenium's callback. Values cross as JSON: 64-bit integers as strings.
CALL = """
const [url, binary, name, arg] = arguments;
const done = arguments[arguments.length - 1];
const c = window.gvd.createGvdClient(url, {useBinaryFormat: binary});
const steps = {
  async nearest({scene, sites, xy}) {
    await c.rpc.createScene({sceneId: scene, window: {maxX: 1, maxY: 1}, widthPx: 256, heightPx: 256});
    const {version} = await c.rpc.upsertSites({sceneId: scene, sites: sites.map(([id, x, y]) =>
        ({id, geometry: {case: "point", value: {x, y}}}))});
    const progress = [];
    const r = await c.findNearest(scene, new Float64Array(xy), {minVersion: version, exact: true,
        onProgress: (d, m) => progress.push([d, m])});
    return {version: String(r.version), ids: r.siteIds, site: Array.from(r.site),
            distance: Array.from(r.distance), exact: Array.from(r.exact), progress};
  },
  async missing() {
    try {
      await c.rpc.getScene({sceneId: "no-such-scene"});
      return {code: "none"};
    } catch (e) {
      return {code: e.code, name: e.name, message: e.rawMessage};
    }
  },
  async watch({scene}) {
    // Once the watch has answered, the page writes three sites and deletes the scene.
    const events = [], versions = [];
    let writes;
    for await (const e of c.watch(scene)) {
      events.push({version: String(e.version), deleted: e.deleted});
      if (!writes) {
        writes = (async () => {
          for (let k = 0; k < 3; ++k) {
            const r = await c.rpc.upsertSites({sceneId: scene, sites: [
                {id: `s${k}`, geometry: {case: "point", value: {x: 0.1 * (k + 1), y: 0.5}}}]});
            versions.push(String(r.version));
            await new Promise((resolve) => setTimeout(resolve, 300));
          }
          await c.rpc.deleteScene({sceneId: scene});
        })();
      }
      if (e.deleted) break;
    }
    await writes;
    return {events, versions};
  },
};
steps[name](arg).then(done, (e) => done({error: String(e), stack: e.stack}));
"""


class TsClientInChromium(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.site_dir = tempfile.mkdtemp(prefix="gvd-ts-page-")
        with open(os.path.join(cls.site_dir, "index.html"), "w", encoding="utf-8") as f:
            f.write(PAGE)
        shutil.copy(ARGS.bundle, os.path.join(cls.site_dir, "gvd-client.js"))
        handler = functools.partial(QuietHandler, directory=cls.site_dir)
        cls.pages = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
        threading.Thread(target=cls.pages.serve_forever, daemon=True).start()
        origin = f"http://127.0.0.1:{cls.pages.server_address[1]}"
        cls.server = gvdtest.Server(ARGS.server, "--http-cors-origins", origin)
        cls.driver = browser()
        cls.driver.set_script_timeout(120)
        cls.driver.get(f"{origin}/index.html")
        for _ in range(100):
            if cls.driver.execute_script("return window.ready === true"):
                break
            threading.Event().wait(0.1)
        else:
            raise AssertionError(f"the page did not load the bundle: {cls.driver.get_log('browser')}")

    @classmethod
    def tearDownClass(cls):
        close(cls.driver)
        cls.server.stop()
        cls.pages.shutdown()
        shutil.rmtree(cls.site_dir, ignore_errors=True)

    def call(self, binary, name, arg=None):
        out = self.driver.execute_async_script(CALL, self.server.url, binary, name, arg or {})
        self.assertNotIn("error", out if isinstance(out, dict) else {}, out)
        return out

    def test_nearest_sites_equal_the_oracle(self):
        for binary in (True, False):
            with self.subTest(binary=binary):
                rng = np.random.default_rng(7 if binary else 8)
                sites = rng.random((150, 2))
                q = rng.random((20_000, 2))
                ids = [f"p{k}" for k in range(len(sites))]
                scene = f"browser-{'binary' if binary else 'json'}"
                r = self.call(binary, "nearest", {
                    "scene": scene, "sites": [[i, x, y] for i, (x, y) in zip(ids, sites.tolist())],
                    "xy": q.ravel().tolist()})
                d = np.sqrt(((q[:, None, :] - sites[None, :, :]) ** 2).sum(axis=2))
                best = d.min(axis=1)
                got = np.array(r["distance"])
                # Bitwise: the exact answers are the double-precision distances.
                self.assertTrue(np.array_equal(got, best), np.abs(got - best).max())
                named = np.array(r["ids"], dtype=object)[np.array(r["site"])]
                want = np.array(ids, dtype=object)[d.argmin(axis=1)]
                self.assertTrue((named == want).all())
                self.assertTrue(all(r["exact"]))
                self.assertEqual(r["progress"][-1], [len(q), len(q)])
                self.assertEqual(int(r["version"]), 2)

    def test_an_error_carries_the_servers_code_and_message(self):
        for binary in (True, False):
            r = self.call(binary, "missing")
            self.assertEqual(r["code"], 5, r)  # Code.NotFound
            self.assertEqual(r["name"], "ConnectError", r)
            self.assertIn("no-such-scene", r["message"])

    def test_a_watch_follows_writes_to_the_deletion(self):
        for binary in (True, False):
            scene = f"watched-{'binary' if binary else 'json'}"
            self.server.ok("CreateScene", {"sceneId": scene, "widthPx": 64, "heightPx": 64,
                                           "window": {"maxX": 1, "maxY": 1}})
            r = self.call(binary, "watch", {"scene": scene})
            events, versions = r["events"], [int(v) for v in r["versions"]]
            self.assertEqual(versions, [2, 3, 4], r)
            self.assertTrue(events[-1]["deleted"], events)
            self.assertFalse(any(e["deleted"] for e in events[:-1]), events)
            seen = [int(e["version"]) for e in events[:-1]]
            self.assertEqual(seen, sorted(set(seen)), events)
            # The frame that started the writes, then any published between them (how many is
            # the render's pace), none past the last write, then the deletion.
            self.assertTrue(seen and seen[0] >= 1 and seen[-1] <= versions[-1], r)


class QuietHandler(http.server.SimpleHTTPRequestHandler):
    extensions_map = {**http.server.SimpleHTTPRequestHandler.extensions_map,
                      ".js": "text/javascript"}

    def log_message(self, *args):  # pylint: disable=arguments-differ
        pass


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--server", required=True)
    parser.add_argument("--bundle", required=True)
    ARGS, rest = parser.parse_known_args()
    if not os.path.exists(ARGS.bundle):
        sys.exit(f"no bundle at {ARGS.bundle}: npm run build in client/ts writes it")
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)
