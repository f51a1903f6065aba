// @gvd/client in Node against a real gvd-server (GVD_SERVER; default the test build's), over
// the Connect protocol in binary and in JSON: answers checked against a brute-force
// double-precision oracle, errors with the server's code and message, a watch to the
// deletion.
import { after, before, test } from "node:test";
import assert from "node:assert/strict";
import { mkdtempSync, rmSync, writeFileSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";

import { Code, ConnectError, FeatureKind, createGvdClient } from "../dist/index.js";
import { random, startServer } from "./support.mjs";

let server, baseUrl;

before(async () => {
  server = await startServer();
  baseUrl = server.baseUrl;
});

after(() => server?.stop());


for (const binary of [true, false]) {
  const kind = binary ? "binary" : "json";

  test(`points in, nearest out (${kind})`, async () => {
    const c = createGvdClient(baseUrl, { useBinaryFormat: binary });
    const scene = `points-${kind}`;
    await c.rpc.createScene({ sceneId: scene, window: { maxX: 1, maxY: 1 }, widthPx: 128, heightPx: 128 });
    const rnd = random(3);
    const sites = Array.from({ length: 300 }, (_, i) => ({ id: `p${i}`, x: rnd(), y: rnd() }));
    const { version } = await c.rpc.upsertSites({
      sceneId: scene,
      sites: sites.map((s) => ({ id: s.id, geometry: { case: "point", value: { x: s.x, y: s.y } } })),
    });
    const m = 100_000;
    const xy = new Float64Array(2 * m).map(() => rnd());
    const steps = [];
    const r = await c.findNearest(scene, xy, { minVersion: version, exact: true, onProgress: (d) => steps.push(d) });
    assert.ok(r.version >= version);
    assert.equal(steps.at(-1), m);
    for (let k = 0; k < m; ++k) {
      let best = Infinity;
      for (const s of sites) {
        const dx = xy[2 * k] - s.x, dy = xy[2 * k + 1] - s.y;
        best = Math.min(best, Math.sqrt(dx * dx + dy * dy));
      }
      assert.equal(r.distance[k], best, `point ${k}`);  // exact: bitwise
      const s = sites[Number(r.siteIds[r.site[k]].slice(1))];
      const dx = xy[2 * k] - s.x, dy = xy[2 * k + 1] - s.y;
      assert.equal(Math.sqrt(dx * dx + dy * dy), best);
      assert.equal(r.exact[k], 1);
    }
  });

  test(`3D points, closest points and gradients, as the Python client answers (${kind})`, async () => {
    const c = createGvdClient(baseUrl, { useBinaryFormat: binary });
    const scene = `space-${kind}`;
    await c.rpc.createScene({ sceneId: scene, window: { maxX: 1, maxY: 1, maxZ: 1 },
      widthPx: 16, heightPx: 16, depthPx: 16 });
    const rnd = random(11);
    const sites = Array.from({ length: 50 }, (_, i) => ({ id: `s${i}`, p: [rnd(), rnd(), rnd()] }));
    const { version } = await c.rpc.upsertSites({ sceneId: scene, sites: sites.map((s) => (
      { id: s.id, geometry: { case: "point", value: { x: s.p[0], y: s.p[1], z: s.p[2] } } })) });
    const m = 500;
    const xyz = new Float64Array(3 * m).map(() => rnd());
    const r = await c.findNearest(scene, xyz, { minVersion: version, exact: true, closest: true, dims: 3 });
    assert.equal(r.closest.length, 3 * m);
    for (let k = 0; k < m; ++k) {
      const q = xyz.subarray(3 * k, 3 * k + 3);
      let best = Infinity, nearest;
      for (const s of sites) {
        const d = Math.hypot(q[0] - s.p[0], q[1] - s.p[1], q[2] - s.p[2]);
        if (d < best) [best, nearest] = [d, s];
      }
      assert.equal(r.siteIds[r.site[k]], nearest.id, `point ${k}`);
      assert.equal(r.exact[k], 1);
      assert.equal(r.featureKind[k], FeatureKind.VERTEX);
      for (let i = 0; i < 3; ++i) {
        assert.equal(r.closest[3 * k + i], nearest.p[i]);
        assert.ok(Math.abs(r.gradient[3 * k + i] - (q[i] - nearest.p[i]) / best) < 1e-12);
      }
    }
    // Without closest, none is asked for; skipRefinement answers from the frame, within its bound.
    const plain = await c.findNearest(scene, xyz.subarray(0, 30), { dims: 3, skipRefinement: true });
    assert.equal(plain.closest, undefined);
    assert.equal(plain.distance.length, 10);
    for (let k = 0; k < 10; ++k) {
      assert.ok(Math.abs(plain.distance[k] - r.distance[k]) <= plain.errorBound[k], `point ${k}`);
    }
    await assert.rejects(c.findNearest(scene, [1, 2, 3, 4], { dims: 3 }), RangeError);
  });

  test(`errors carry the server's code and message (${kind})`, async () => {
    const c = createGvdClient(baseUrl, { useBinaryFormat: binary });
    await assert.rejects(c.rpc.getScene({ sceneId: "missing" }), (e) => {
      assert.ok(e instanceof ConnectError);
      assert.equal(e.code, Code.NotFound);
      assert.match(e.rawMessage, /missing/);
      return true;
    });
    await assert.rejects(c.rpc.createScene({ sceneId: "has spaces", widthPx: 8, heightPx: 8 }), (e) => {
      assert.equal(e.code, Code.InvalidArgument);
      return true;
    });
  });

  test(`a watch sees the write and ends at the deletion (${kind})`, async () => {
    const c = createGvdClient(baseUrl, { useBinaryFormat: binary });
    const scene = `watched-${kind}`;
    await c.rpc.createScene({ sceneId: scene, window: { maxX: 1, maxY: 1 }, widthPx: 16, heightPx: 16 });
    const { version } = await c.rpc.upsertSites({
      sceneId: scene, sites: [{ id: "a", geometry: { case: "point", value: { x: 0.5, y: 0.5 } } }],
    });
    const events = [];
    let deleted = false;
    for await (const e of c.watch(scene)) {
      events.push(e);
      if (!deleted && e.version >= version) {
        deleted = true;
        await c.rpc.deleteScene({ sceneId: scene });
      }
    }
    assert.ok(events.some((e) => e.version >= version));
    assert.ok(events.at(-1).deleted);
  });
}

test("tokens refused by code and message", async (t) => {
  const dir = mkdtempSync(join(tmpdir(), "gvd-ts-tokens-"));
  const write = "w".repeat(20) + "-writer", read = "r".repeat(20) + "-reader";
  writeFileSync(join(dir, "tokens"), `${write} write\n${read} read\n`);
  const guarded = await startServer("--tokens", join(dir, "tokens"));
  t.after(() => {
    guarded.stop();
    rmSync(dir, { recursive: true, force: true });
  });
  await createGvdClient(guarded.baseUrl, { token: write }).rpc.createScene(
    { sceneId: "guarded", window: { maxX: 1, maxY: 1 }, widthPx: 16, heightPx: 16 });
  const upsert = { sceneId: "guarded", sites: [{ id: "a", geometry: { case: "point", value: { x: 0.5, y: 0.5 } } }] };
  for (const [token, code, named] of [[undefined, Code.Unauthenticated, /bearer token/],
    ["x".repeat(20), Code.Unauthenticated, /unknown/], [read, Code.PermissionDenied, /may read/]]) {
    await assert.rejects(createGvdClient(guarded.baseUrl, { token }).rpc.upsertSites(upsert), (e) => {
      assert.equal(e.code, code, e.message);
      assert.match(e.rawMessage, named);
      return true;
    });
  }
  const { scene } = await createGvdClient(guarded.baseUrl, { token: read }).rpc.getScene({ sceneId: "guarded" });
  assert.equal(scene.version, 1n);
});
