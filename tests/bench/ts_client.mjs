// One-point FindNearest calls through the TypeScript client's transport (Connect-ES over
// fetch, binary bodies, HTTP/1.1 on loopback), unary, as a stream, and through the client's
// findNearest, against a gvd-server of its own: p50 and p99 of 300 calls each.
// Usage (after client/ts/run-tests.sh has built client/ts/dist):
//   GVD_SERVER=build/test/server/gvd-server node tests/bench/ts_client.mjs
import { createGvdClient } from "../../client/ts/dist/index.js";
import { startServer } from "../../client/ts/test/support.mjs";
const server = await startServer();
const c = createGvdClient(server.baseUrl);
await c.rpc.createScene({ sceneId: "b", window: { maxX: 1, maxY: 1 }, widthPx: 256, heightPx: 256 });
const sites = Array.from({ length: 1000 }, (_, i) => ({ id: `s${i}`, geometry: { case: "point", value: { x: Math.random(), y: Math.random() } } }));
await c.rpc.upsertSites({ sceneId: "b", sites });
async function time(name, f) {
  const t = [];
  for (let i = 0; i < 300; ++i) { const t0 = performance.now(); await f(); t.push(performance.now() - t0); }
  t.sort((a, b) => a - b);
  console.log(`${name}: p50 ${t[150].toFixed(3)} ms p99 ${t[297].toFixed(3)} ms`);
}
await time("unary xy", () => c.rpc.findNearest({ sceneId: "b", xy: [Math.random(), Math.random()] }));
await time("stream xy", async () => {
  for await (const m of c.rpc.findNearestStream({ sceneId: "b", xy: [Math.random(), Math.random()] })) void m;
});
await time("client findNearest", () => c.findNearest("b", [Math.random(), Math.random()]));
server.stop();
