// @gvd/client: gvd-server's API over the Connect protocol, in browsers and Node (fetch), with
// typed arrays for packed batches. The messages and the service are generated from the
// server's proto (src/gen, by protoc-gen-es).
import { create } from "@bufbuild/protobuf";
import { Code, ConnectError, createClient, type Client, type Interceptor } from "@connectrpc/connect";
import { createConnectTransport } from "@connectrpc/connect-web";

import {
  FindNearestStreamRequestSchema,
  VoronoiService,
  type FindNearestStreamResponse,
  type WatchSceneResponse,
} from "./gen/gvd/v1/voronoi_pb.js";

export * from "./gen/gvd/v1/voronoi_pb.js";
export { Code, ConnectError };

export interface GvdOptions {
  /** A bearer token (the server's --tokens). */
  token?: string;
  /** Binary protobuf bodies (the default) or JSON. */
  useBinaryFormat?: boolean;
  /** Each call's deadline in milliseconds (none by default). */
  timeoutMs?: number;
  /** fetch to use (Node 20 and browsers have one). */
  fetch?: typeof globalThis.fetch;
}

/** Every call of gvd.v1.VoronoiService, typed, plus the packed helpers below. */
export type VoronoiClient = Client<typeof VoronoiService>;

/** A client of the server at `baseUrl` (its HTTP port: "http://127.0.0.1:8080"). */
export function createGvdClient(baseUrl: string, options: GvdOptions = {}): GvdClient {
  const interceptors: Interceptor[] = [];
  if (options.token) {
    const token = options.token;
    interceptors.push((next) => async (req) => {
      req.header.set("Authorization", `Bearer ${token}`);
      return next(req);
    });
  }
  const transport = createConnectTransport({
    baseUrl,
    useBinaryFormat: options.useBinaryFormat ?? true,
    interceptors,
    defaultTimeoutMs: options.timeoutMs,
    fetch: options.fetch,
  });
  return new GvdClient(createClient(VoronoiService, transport));
}

/** Answers to m query points, as typed arrays of length m. */
export interface NearestAnswers {
  version: bigint;
  /** The distinct sites named; `site` indexes it (-1: no site is a candidate). */
  siteIds: string[];
  site: Int32Array;
  distance: Float64Array;
  errorBound: Float64Array;
  exact: Uint8Array;
}

export class GvdClient {
  constructor(readonly rpc: VoronoiClient) {}

  /**
   * The nearest site to each point of `xy` (x0, y0, x1, y1, ...), sent packed and read from
   * FindNearestStream's chunks; `onProgress(done, m)` follows them.
   */
  async findNearest(
    sceneId: string,
    xy: Float64Array | number[],
    options: { minVersion?: bigint; exact?: boolean; onProgress?: (done: number, total: number) => void } = {},
  ): Promise<NearestAnswers> {
    const m = Math.floor(xy.length / 2);
    const answers: NearestAnswers = {
      version: 0n,
      siteIds: [],
      site: new Int32Array(m).fill(-1),
      distance: new Float64Array(m).fill(Infinity),
      errorBound: new Float64Array(m),
      exact: new Uint8Array(m),
    };
    const index = new Map<string, number>();
    const request = create(FindNearestStreamRequestSchema, {
      sceneId,
      xy: Array.from(xy),
      minVersion: options.minVersion ?? 0n,
      exact: options.exact ?? false,
    });
    for await (const chunk of this.rpc.findNearestStream(request)) {
      merge(answers, index, chunk);
      options.onProgress?.(Number(chunk.offset) + (chunk.packed?.distance.length ?? 0), m);
    }
    return answers;
  }

  /** The scene's events, one per published frame, until it is deleted or reloaded from a store
   * that went back in time (the last event says `deleted` or `reloaded`). */
  watch(sceneId: string, afterVersion = 0n, signal?: AbortSignal): AsyncIterable<WatchSceneResponse> {
    return this.rpc.watchScene({ sceneId, afterVersion }, { signal });
  }
}

function merge(out: NearestAnswers, index: Map<string, number>, chunk: FindNearestStreamResponse): void {
  const p = chunk.packed;
  if (!p) return;
  if (chunk.version > out.version) out.version = chunk.version;
  const local = p.siteIds.map((id) => {
    let i = index.get(id);
    if (i === undefined) {
      i = out.siteIds.length;
      index.set(id, i);
      out.siteIds.push(id);
    }
    return i;
  });
  const at = Number(chunk.offset);
  for (let k = 0; k < p.distance.length; ++k) {
    const s = p.site[k];  // 1 + an index into the chunk's siteIds; 0: none
    out.site[at + k] = s === 0 ? -1 : local[s - 1];
    out.distance[at + k] = p.distance[k];
    if (p.errorBound.length) out.errorBound[at + k] = p.errorBound[k];
    if (p.exact.length) out.exact[at + k] = p.exact[k] ? 1 : 0;
  }
}
