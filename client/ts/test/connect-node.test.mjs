// The server's Connect transport as Connect-ES's own Node transport (@connectrpc/connect-node)
// speaks it, with nothing of @gvd/client but the generated service: gzip-compressed requests
// both unary and streaming, a body past --max-message-bytes (unary and streaming) seen by the
// client as resource_exhausted with the server's message, and an unknown service as
// unimplemented. Answers are checked against a brute-force double-precision oracle.
import { after, before, test } from "node:test";
import assert from "node:assert/strict";

import { Code, ConnectError, createClient } from "@connectrpc/connect";
import { compressionGzip, createConnectTransport } from "@connectrpc/connect-node";

import { VoronoiService } from "../dist/index.js";
import { random, startServer } from "./support.mjs";

const maxMessageBytes = 1 << 20;
let server, baseUrl;

before(async () => {
  server = await startServer("--max-message-bytes", String(maxMessageBytes));
  baseUrl = server.baseUrl;
});

after(() => server?.stop());

function client(binary, gzip) {
  return createClient(VoronoiService, createConnectTransport({
    baseUrl,
    httpVersion: "1.1",
    useBinaryFormat: binary,
    sendCompression: gzip ? compressionGzip : null,
    compressMinBytes: 0,
  }));
}


for (const binary of [true, false]) {
  const kind = binary ? "binary" : "json";

  test(`gzip-compressed requests, unary and streaming (${kind})`, async () => {
    const c = client(binary, true);
    const scene = `gzip-${kind}`;
    await c.createScene({ sceneId: scene, window: { maxX: 1, maxY: 1 }, widthPx: 64, heightPx: 64 });
    const rnd = random(11);
    const sites = Array.from({ length: 50 }, (_, i) => ({ id: `s${i}`, x: rnd(), y: rnd() }));
    const { version } = await c.upsertSites({
      sceneId: scene,
      sites: sites.map((s) => ({ id: s.id, geometry: { case: "point", value: { x: s.x, y: s.y } } })),
    });
    const xy = Array.from({ length: 2000 }, () => rnd());
    const nearest = (x, y) => {
      let best = { id: "", d: Infinity };
      for (const s of sites) {
        const d = Math.sqrt((x - s.x) * (x - s.x) + (y - s.y) * (y - s.y));
        if (d < best.d) best = { id: s.id, d };
      }
      return best;
    };
    // Unary: the points one by one as messages.
    const points = [];
    for (let k = 0; k < xy.length; k += 2) points.push({ x: xy[k], y: xy[k + 1] });
    const unary = await c.findNearest({ sceneId: scene, points, minVersion: version, exact: true });
    assert.equal(unary.results.length, points.length);
    unary.results.forEach((r, k) => {
      const want = nearest(points[k].x, points[k].y);
      assert.equal(r.distance, want.d, `point ${k}`);
    });
    // Streaming: one compressed request envelope, packed answers.
    let answered = 0;
    for await (const chunk of c.findNearestStream({ sceneId: scene, xy, minVersion: version, exact: true })) {
      const p = chunk.packed;
      p.distance.forEach((d, j) => {
        const k = Number(chunk.offset) + j;
        assert.equal(d, nearest(xy[2 * k], xy[2 * k + 1]).d, `point ${k}`);
      });
      answered += p.distance.length;
    }
    assert.equal(answered, points.length);
  });

  test(`a body past --max-message-bytes is resource_exhausted, unary and streaming (${kind})`, async () => {
    const c = client(binary, false);
    const scene = `big-${kind}`;
    await c.createScene({ sceneId: scene, window: { maxX: 1, maxY: 1 }, widthPx: 64, heightPx: 64 });
    const xy = Array.from({ length: 2 * maxMessageBytes / 8 }, (_, i) => (i % 97) / 97);
    const refused = (e) => {
      assert.ok(e instanceof ConnectError, String(e));
      assert.equal(e.code, Code.ResourceExhausted, e.message);
      assert.match(e.rawMessage, /--max-message-bytes/);
      return true;
    };
    await assert.rejects(c.findNearest({ sceneId: scene, points: xy.map((x) => ({ x, y: x })) }), refused);
    await assert.rejects(async () => {
      for await (const _ of c.findNearestStream({ sceneId: scene, xy })) { /* none comes */ }
    }, refused);
    // The connection still serves.
    assert.equal((await c.getScene({ sceneId: scene })).scene.sceneId, scene);
  });
}

test("an unknown service is unimplemented", async () => {
  const other = { ...VoronoiService, typeName: "gvd.v2.VoronoiService" };
  other.methods = VoronoiService.methods.map((m) => ({ ...m, parent: other }));
  const c = createClient(other, createConnectTransport({ baseUrl, httpVersion: "1.1" }));
  await assert.rejects(c.listScenes({}), (e) => {
    assert.equal(e.code, Code.Unimplemented, e.message);
    return true;
  });
});
