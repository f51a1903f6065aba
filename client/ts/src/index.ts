// @gvd/client: gvd-server's API over the Connect protocol, in browsers and Node (fetch), with
// typed arrays for packed batches. The messages and the service are generated from the
// server's proto (src/gen, by protoc-gen-es).
import { create } from "@bufbuild/protobuf";
import { Code, ConnectError, createClient, type Client, type Interceptor } from "@connectrpc/connect";
import { createConnectTransport } from "@connectrpc/connect-web";

import {
  FindNearestStreamRequestSchema,
  NearestField,
  VoronoiService,
  type FindNearestStreamResponse,
  type WatchSceneResponse,
} from "./gen/gvd/v1/voronoi_pb.js";

export * from "./gen/gvd/v1/voronoi_pb.js";
export { Code, ConnectError };
/** Messages from and to proto3's JSON mapping, for callers that hold requests and answers as
 * plain JSON (the browser bundle has no other way to reach them). */
export { create, fromJson, toJson } from "@bufbuild/protobuf";

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
  /** 1 where the answer is certified exact. */
  exact: Uint8Array;
  /** The answering site's part nearest to the point (FeatureKind values and their index). */
  featureKind: Int32Array;
  featureIndex: Uint32Array;
  /** With `closest`: per answer, the site's point nearest to the query point and the unit
   * gradient of the distance, `dims` numbers each (NaN where no site is a candidate). */
  closest?: Float64Array;
  gradient?: Float64Array;
}

export interface NearestOptions {
  /** Answer from at least this version (the API's min_version). */
  minVersion?: bigint;
  /** Certify every answer. */
  exact?: boolean;
  /** Answer from the frame alone, without refining (the API's skip_refinement). */
  skipRefinement?: boolean;
  /** Also each answer's closest point and gradient. */
  closest?: boolean;
  /** 2 (x, y per point; the default) or 3 (x, y, z per point, for a 3D scene). */
  dims?: 2 | 3;
  onProgress?: (done: number, total: number) => void;
}

export class GvdClient {
  constructor(readonly rpc: VoronoiClient) {}

  /**
   * The nearest site to each of m query points, `points` holding x0, y0, x1, y1, ... (or
   * x, y, z each with `dims: 3`), sent packed and read from FindNearestStream's chunks;
   * `onProgress(done, m)` follows them.
   */
  async findNearest(
    sceneId: string,
    points: Float64Array | number[],
    options: NearestOptions = {},
  ): Promise<NearestAnswers> {
    const dims = options.dims ?? 2;
    if (dims !== 2 && dims !== 3) throw new RangeError(`dims is ${dims}; it must be 2 or 3`);
    if (points.length % dims !== 0) {
      throw new RangeError(`points holds ${points.length} numbers, not a multiple of dims (${dims})`);
    }
    const m = points.length / dims;
    const answers: NearestAnswers = {
      version: 0n,
      siteIds: [],
      site: new Int32Array(m).fill(-1),
      distance: new Float64Array(m).fill(Infinity),
      errorBound: new Float64Array(m),
      exact: new Uint8Array(m),
      featureKind: new Int32Array(m),
      featureIndex: new Uint32Array(m),
    };
    if (options.closest) {
      answers.closest = new Float64Array(dims * m).fill(NaN);
      answers.gradient = new Float64Array(dims * m).fill(NaN);
    }
    const index = new Map<string, number>();
    const packed = Array.from(points);
    const request = create(FindNearestStreamRequestSchema, {
      sceneId,
      xy: dims === 2 ? packed : [],
      xyz: dims === 3 ? packed : [],
      minVersion: options.minVersion ?? 0n,
      exact: options.exact ?? false,
      skipRefinement: options.skipRefinement ?? false,
      fields: options.closest
        ? [NearestField.SITE, NearestField.DISTANCE, NearestField.ERROR_BOUND, NearestField.EXACT,
            NearestField.FEATURE, NearestField.CLOSEST, NearestField.GRADIENT]
        : [],
    });
    for await (const chunk of this.rpc.findNearestStream(request)) {
      merge(answers, index, chunk, dims);
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

function merge(out: NearestAnswers, index: Map<string, number>, chunk: FindNearestStreamResponse,
  dims: number): void {
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
    if (p.featureKind.length) out.featureKind[at + k] = p.featureKind[k];
    if (p.featureIndex.length) out.featureIndex[at + k] = p.featureIndex[k];
  }
  if (out.closest && p.closest.length) out.closest.set(p.closest, at * dims);
  if (out.gradient && p.gradient.length) out.gradient.set(p.gradient, at * dims);
}
