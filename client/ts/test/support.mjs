// What the tests share: a real gvd-server (GVD_SERVER; default the test build's) on loopback
// ports of its choosing, with a data directory of its own (start in before(), stop in
// after()), and a seeded generator.
import { spawn } from "node:child_process";
import { existsSync, mkdtempSync, readFileSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
import { join, resolve } from "node:path";

const serverPath = resolve(process.env.GVD_SERVER ?? "../../build/test/server/gvd-server");

export async function startServer(...flags) {
  const dir = mkdtempSync(join(tmpdir(), "gvd-ts-"));
  const portFile = join(dir, "port");
  const server = spawn(serverPath, ["--listen", "127.0.0.1:0", "--http-listen", "127.0.0.1:0",
    "--port-file", portFile, "--data", join(dir, "data"), ...flags],
  { stdio: ["ignore", "ignore", "inherit"] });
  for (let i = 0; i < 600 && !existsSync(portFile); ++i) await new Promise((r) => setTimeout(r, 50));
  const [, http] = readFileSync(portFile, "utf8").trim().split(/\s+/);
  return {
    baseUrl: `http://127.0.0.1:${http}`,
    stop() {
      server.kill("SIGTERM");
      rmSync(dir, { recursive: true, force: true });
    },
  };
}

// A small seeded generator of numbers in [0, 1).
export function random(seed) {
  let s = seed >>> 0;
  return () => ((s = (Math.imul(s, 1664525) + 1013904223) >>> 0) / 2 ** 32);
}
