// The selection app: a scene's diagram, the object nearest to the cursor highlighted (paper
// sec. 7.2), sites moved, added and deleted, every page kept live by WatchScene.
//
// Hover answers come from Pick, one call in flight at a time (the newest cursor position
// waits for it), never from downloading the sites. The region under the cursor is tinted from
// a LAYER_SITE_INDEX image of the same frame, which names each pixel's site. window.gvd exposes the
// page's state to scripts and tests.
import { Code, ConnectError, VoronoiService, createGvdClient, fromJson, toJson } from './gvd-client.js';

const $ = (id) => document.getElementById(id);
const base = $('base');
const overlay = $('overlay');
const stage = $('stage');

// ---- calls ----------------------------------------------------------------------------------

// The API's calls through the TypeScript client's browser bundle (client/ts, built into
// gvd-client.js), in binary Connect. Requests and answers are held here in proto3's JSON
// mapping: lowerCamelCase fields, enums by name, 64-bit integers and bytes as strings, fields at
// their default left out.
class Calls {
  constructor(token) {
    this.token = token;
    this.rpc = createGvdClient(location.origin, { token }).rpc;
  }

  // A unary call by its name in the API ('FindNearest').
  async call(name, request, { signal } = {}) {
    const method = methodNamed(name);
    const answer = await this.rpc[method.localName](fromJson(method.input, request), { signal });
    return toJson(method.output, answer);
  }

  // A server-streaming call: onMessage(message) for each; resolves when the server ends the
  // stream, rejects with its error or when `signal` aborts.
  async stream(name, request, onMessage, { signal } = {}) {
    const method = methodNamed(name);
    for await (const message of this.rpc[method.localName](fromJson(method.input, request), { signal })) {
      onMessage(toJson(method.output, message));
    }
  }
}

function methodNamed(name) {
  const method = VoronoiService.methods.find((m) => m.name === name);
  if (!method) throw new Error(`gvd.v1.VoronoiService has no method ${name}`);
  return method;
}

// A refusal's Connect code as the protocol spells it ('permission_denied').
function codeName(e) {
  return (Code[e.code] ?? 'unknown').replace(/[A-Z]/g, (c, at) => (at ? '_' : '') + c.toLowerCase());
}

// The bytes of a protobuf `bytes` field, which JSON carries in base64.
function bytesOf(base64) {
  const text = atob(base64 ?? '');
  const out = new Uint8Array(text.length);
  for (let i = 0; i < text.length; ++i) out[i] = text.charCodeAt(i);
  return out;
}

const params = new URLSearchParams(location.search);
if (params.has('token')) localStorage.setItem('gvd.token', params.get('token'));
let client = new Calls(localStorage.getItem('gvd.token') ?? '');
$('token').value = client.token;

const kHistory = 1000;  // hover round trips kept for the figures
const state = {
  sceneId: '',
  scene: null,          // GetScene's answer
  view: null,           // the scene window the canvas shows: {minX, minY, maxX, maxY}
  image: null,          // the layer shown: {bitmap, window, version}
  index: null,          // SITE_INDEX: {ids, width, height, window, siteIds, slotOf, boxes, version}
  hover: null,          // the last Pick answered: {x, y, found, siteId, distance, feature, site, closest}
  selected: null,       // {siteId, site}
  tool: 'select',
  draft: [],            // the points of a site being added
  press: null,          // a pointer held down: {x, y, view, moved, drag}
  frameVersion: 0,
  lastWriteVersion: 0,
  watch: null,          // AbortController of the WatchScene stream
  slice: -1,            // a 3D scene's slice shown and picked in (its voxels' z: sliceZ()); -1 in 2D
};
const gvd = (window.gvd = {
  ready: false,         // the first frame of a scene is drawn
  error: '',
  sceneId: '',
  hover: null,
  hoverSeq: 0,
  latencies: [],        // hover round trips, ms: pointer event to highlight drawn
  parts: [],            // each round trip's parts, ms: [input queue, waiting, Pick, drawing]
  frameVersion: 0,
  lastWriteVersion: 0,
  refreshes: 0,
  view: null,
  toCanvas: (x, y) => toCanvas(x, y),
  toScene: (cx, cy) => toScene(cx, cy),
  indexAt: (x, y) => indexAt(x, y),
  // The picture's pixels: their number and the window they cover.
  indexShape: () => state.index && { width: state.index.width, height: state.index.height, window: state.index.window },
});

// ---- errors -------------------------------------------------------------------------------

// The banner shows the last error until a call of the same kind (`source`: 'scenes',
// 'render', 'watch', 'pick', 'write') succeeds, or it is clicked away: a refused edit stays
// in view while the picture goes on refreshing.
let errorSource = '';

function showError(e, source) {
  const text = e instanceof ConnectError ? `${codeName(e)}: ${e.rawMessage}` : String(e?.message ?? e);
  gvd.error = text;
  errorSource = source;
  $('error').textContent = text;
  $('error').hidden = false;
}

function clearError(source) {
  if (source !== undefined && source !== errorSource) return;
  gvd.error = '';
  $('error').hidden = true;
}

// ---- the view: scene units to canvas pixels ------------------------------------------------

function scale() {
  return base.width / (state.view.maxX - state.view.minX);
}

function toCanvas(x, y) {
  const s = scale();
  return [(x - state.view.minX) * s, (state.view.maxY - y) * s];
}

function toScene(cx, cy) {
  const s = scale();
  return [state.view.minX + cx / s, state.view.maxY - cy / s];
}

// A view of `w` that fits the canvas, centred, with the canvas's aspect ratio.
function fit(w) {
  const width = w.maxX - w.minX, height = w.maxY - w.minY;
  const s = Math.min(base.width / width, base.height / height) * 0.98;
  return around((w.minX + w.maxX) / 2, (w.minY + w.maxY) / 2, s);
}

function around(cx, cy, s) {
  const hw = base.width / s / 2, hh = base.height / s / 2;
  return { minX: cx - hw, maxX: cx + hw, minY: cy - hh, maxY: cy + hh };
}

function setView(view) {
  state.view = view;
  gvd.view = { ...view };
}

function resize() {
  const { clientWidth: w, clientHeight: h } = stage;
  if (w === base.width && h === base.height) return;
  const s = state.view ? scale() : 1;
  const c = state.view ? [(state.view.minX + state.view.maxX) / 2, (state.view.minY + state.view.maxY) / 2] : [0, 0];
  for (const canvas of [base, overlay]) {
    canvas.width = w;
    canvas.height = h;
  }
  if (state.view) {
    setView(around(c[0], c[1], s));
    drawBase();
    drawOverlay();
    scheduleRefresh();
  }
}

// ---- scenes -------------------------------------------------------------------------------

async function loadScenes(preferred) {
  let scenes;
  try {
    scenes = [];
    for (let token = '', first = true; first || token; first = false) {
      const page = await client.call('ListScenes', { pageToken: token });
      scenes.push(...(page.scenes ?? []));
      token = page.nextPageToken ?? '';
    }
  } catch (e) {
    showError(e, 'scenes');
    return;
  }
  clearError();
  const select = $('scene');
  select.replaceChildren(...scenes.map((s) => new Option(
    `${s.sceneId} (${s.siteCount ?? 0} sites${s.unavailable ? ', not loaded' : ''})`, s.sceneId)));
  const ids = scenes.map((s) => s.sceneId);
  const want = [preferred, state.sceneId, params.get('scene'), 'demo-mixed', ids[0]].find((id) => id && ids.includes(id));
  $('empty').hidden = ids.length > 0;
  if (want) {
    select.value = want;
    if (want !== state.sceneId) await openScene(want);
  } else {
    closeScene();
  }
}

function closeScene() {
  state.watch?.abort();
  Object.assign(state, { sceneId: '', scene: null, image: null, index: null, hover: null, selected: null, slice: -1 });
  gvd.sceneId = '';
  gvd.ready = false;
  drawBase();
  drawOverlay();
  showPanel();
}

async function openScene(id) {
  closeScene();
  state.sceneId = gvd.sceneId = id;
  const url = new URL(location.href);
  url.searchParams.set('scene', id);
  url.searchParams.delete('token');
  history.replaceState(null, '', url);
  try {
    state.scene = (await client.call('GetScene', { sceneId: id })).scene ?? {};
  } catch (e) {
    showError(e, 'scenes');
    return;
  }
  const w = state.scene.window ?? {};
  // A 3D scene shows one slice at a time, the middle one first; its sites are edited through
  // the API, not drawn here.
  const depth = state.scene.depthPx ?? 0;
  state.slice = depth > 0 ? Math.floor(depth / 2) : -1;
  $('z-control').hidden = depth === 0;
  $('z').max = String(Math.max(0, depth - 1));
  $('z').value = String(Math.max(0, state.slice));
  $('z-value').textContent = depth > 0 ? sliceZ().toPrecision(4) : '';
  for (const radio of document.querySelectorAll('input[name=tool]')) {
    radio.disabled = depth > 0 && radio.value !== 'select';
    if (depth > 0 && radio.value === 'select') radio.click();
  }
  gvd.slice = state.slice;
  setView(fit({ minX: w.minX ?? 0, minY: w.minY ?? 0, maxX: w.maxX ?? 0, maxY: w.maxY ?? 0 }));
  await refresh(0);
  watch(id);
}

// A scene of every kind, to try the app on: 1024x1024 pixels over [0, 100]^2.
async function createDemo() {
  const taken = new Set([...$('scene').options].map((o) => o.value));
  let id = 'demo-mixed';
  for (let k = 2; taken.has(id); ++k) id = `demo-mixed-${k}`;
  try {
    await client.call('CreateScene', {
      sceneId: id, window: { minX: 0, minY: 0, maxX: 100, maxY: 100 }, widthPx: 1024, heightPx: 1024,
    });
    const r = await client.call('UpsertSites', { sceneId: id, sites: demoSites() });
    noteWrite(r.version);
  } catch (e) {
    showError(e, 'scenes');
    return;
  }
  await loadScenes(id);
}

function demoSites() {
  let seed = 1999;
  const random = () => {  // mulberry32
    seed = (seed + 0x6d2b79f5) | 0;
    let t = Math.imul(seed ^ (seed >>> 15), 1 | seed);
    t = (t + Math.imul(t ^ (t >>> 7), 61 | t)) ^ t;
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
  const u = (lo, hi) => lo + (hi - lo) * random();
  const p = (cx = u(5, 95), cy = u(5, 95), r = 0) => ({ x: cx + u(-r, r), y: cy + u(-r, r) });
  const sites = [];
  for (let i = 0; i < 60; ++i) sites.push({ id: `point-${i}`, point: p() });
  for (let i = 0; i < 10; ++i) {
    const a = p();
    sites.push({ id: `segment-${i}`, segment: { a, b: p(a.x, a.y, 12) } });
  }
  for (let i = 0; i < 6; ++i) {
    const a = p();
    const points = [a];
    for (let k = 0; k < 4; ++k) points.push(p(points[k].x + 5, points[k].y, 4));
    sites.push({ id: `polyline-${i}`, polyline: { points } });
  }
  for (let i = 0; i < 6; ++i) {
    const c = p(), r = u(3, 7), n = 3 + (i % 4);
    const vertices = [];
    for (let k = 0; k < n; ++k) {
      const t = (2 * Math.PI * k) / n;
      vertices.push({ x: c.x + r * Math.cos(t), y: c.y + r * Math.sin(t) });
    }
    sites.push({ id: `polygon-${i}`, polygon: { vertices } });
  }
  for (let i = 0; i < 6; ++i) {
    const a = p();
    sites.push({ id: `bezier-${i}`, bezier: { controlPoints: [a, p(a.x, a.y, 10), p(a.x, a.y, 10), p(a.x, a.y, 12)], tolerance: 0.02 } });
  }
  // Paths: rounded rectangles (lines and quarter circles as cubics) with a rounded hole, one
  // site each, every other one restricted to its outside.
  const k = 0.5523;  // a quarter circle's cubic handles, in radii
  for (let i = 0; i < 4; ++i) {
    const c = p(), w = u(4, 8), h = u(4, 8), r = Math.min(w, h) / 3;
    const x0 = c.x - w / 2, x1 = c.x + w / 2, y0 = c.y - h / 2, y1 = c.y + h / 2;
    const at = (x, y) => ({ x, y });
    const outer = {
      points: [at(x0 + r, y0), at(x1 - r, y0), at(x1 - r + k * r, y0), at(x1, y0 + r - k * r), at(x1, y0 + r),
        at(x1, y1 - r), at(x1, y1 - r + k * r), at(x1 - r + k * r, y1), at(x1 - r, y1),
        at(x0 + r, y1), at(x0 + r - k * r, y1), at(x0, y1 - r + k * r), at(x0, y1 - r),
        at(x0, y0 + r), at(x0, y0 + r - k * r), at(x0 + r - k * r, y0), at(x0 + r, y0)],
      degrees: [1, 3, 1, 3, 1, 3, 1, 3],
      closed: true,
    };
    // A rounded hole of four quadratics, clockwise (so a hole by either fill rule).
    const q = r / 2, hole = { points: [at(c.x + q, c.y)], degrees: [2, 2, 2, 2], closed: true };
    for (const [cx, cy, ex, ey] of [[q, -q, 0, -q], [-q, -q, -q, 0], [-q, q, 0, q], [q, q, q, 0]]) {
      hole.points.push(at(c.x + cx, c.y + cy), at(c.x + ex, c.y + ey));
    }
    sites.push({ id: `path-${i}`, path: { subpaths: [outer, hole], side: i % 2 ? 'SIDE_OUTSIDE' : undefined } });
  }
  return sites;
}

// ---- frames: the shown layer and the SITE_INDEX image ---------------------------------------

let rendering = false;
let wanted = -1;  // a refresh asked for while one runs: its min_version
let refreshTimer = 0;

function scheduleRefresh() {
  clearTimeout(refreshTimer);
  refreshTimer = setTimeout(() => refresh(0), 120);
}

function clip(view, w) {
  const out = {
    minX: Math.max(view.minX, w.minX ?? 0), minY: Math.max(view.minY, w.minY ?? 0),
    maxX: Math.min(view.maxX, w.maxX ?? 0), maxY: Math.min(view.maxY, w.maxY ?? 0),
  };
  return out.minX < out.maxX && out.minY < out.maxY ? out : null;
}

// Zoomed in past the scene's raster (a scene pixel wider than a canvas pixel): the window
// rendered anew at the canvas's resolution (the service's zoom windows), not the frame's
// pixels stretched into squares. Nothing where the frame's own pixels are fine enough.
const kMaxZoomSide = 4096;
function zoomSize(window) {
  const w = state.scene.window ?? {}, columns = Number(state.scene.widthPx ?? 0);
  if (!columns) return {};
  const s = scale();
  if (s * ((w.maxX ?? 0) - (w.minX ?? 0)) / columns <= 1) return {};
  const side = (extent) => Math.min(kMaxZoomSide, Math.max(1, Math.round(extent * s)));
  return { widthPx: side(window.maxX - window.minX), heightPx: side(window.maxY - window.minY) };
}

async function decode(bytes, width, height) {
  const bitmap = await createImageBitmap(new Blob([bytes], { type: 'image/png' }),
                                         { colorSpaceConversion: 'none', premultiplyAlpha: 'none' });
  if (width === undefined) return bitmap;
  const canvas = new OffscreenCanvas(width, height);
  const context = canvas.getContext('2d', { willReadFrequently: true });
  context.drawImage(bitmap, 0, 0);
  return context.getImageData(0, 0, width, height).data;
}

// Each pixel's site (1 + an index into siteIds, 0 for none) and each site's pixel box.
async function decodeIndex(r) {
  const width = r.widthPx ?? 0, height = r.heightPx ?? 0;
  const rgba = await decode(bytesOf(r.image), width, height);
  const siteIds = r.siteIds ?? [];
  const ids = new Uint32Array(width * height);
  const boxes = new Int32Array(4 * (siteIds.length + 1));
  for (let k = 0; k <= siteIds.length; ++k) boxes.set([width, height, -1, -1], 4 * k);
  for (let row = 0, at = 0; row < height; ++row) {
    for (let col = 0; col < width; ++col, ++at) {
      const k = (rgba[4 * at] << 16) | (rgba[4 * at + 1] << 8) | rgba[4 * at + 2];
      ids[at] = k;
      const b = 4 * k;
      if (col < boxes[b]) boxes[b] = col;
      if (row < boxes[b + 1]) boxes[b + 1] = row;
      if (col > boxes[b + 2]) boxes[b + 2] = col;
      if (row > boxes[b + 3]) boxes[b + 3] = row;
    }
  }
  const slotOf = new Map(siteIds.map((id, k) => [id, k + 1]));
  return { ids, width, height, window: windowOf(r.window), siteIds, slotOf, boxes, version: Number(r.version ?? 0), tints: new Map() };
}

// A 3D scene's slice: the z of its voxels' centres; the point picked at (x, y) of the slice.
function sliceZ() {
  const w = state.scene?.window ?? {}, depth = state.scene?.depthPx ?? 0;
  return (w.minZ ?? 0) + ((state.slice + 0.5) * ((w.maxZ ?? 0) - (w.minZ ?? 0))) / depth;
}
function pointAt(x, y) {
  return state.slice >= 0 ? { x, y, z: sliceZ() } : { x, y };
}

function windowOf(w = {}) {
  return { minX: w.minX ?? 0, minY: w.minY ?? 0, maxX: w.maxX ?? 0, maxY: w.maxY ?? 0 };
}

async function refresh(minVersion) {
  if (!state.scene) return;
  if (rendering) {
    wanted = Math.max(wanted, minVersion);
    return;
  }
  rendering = true;
  const sceneId = state.sceneId;
  try {
    const window = clip(state.view, state.scene.window ?? {});
    if (!window) {
      state.image = state.index = null;
    } else {
      const common = { sceneId, window, minVersion: String(Math.max(minVersion, state.lastWriteVersion)) };
      const space = state.slice >= 0;  // a 3D scene: its slice, with no sites drawn over it
      if (space) common.slice = state.slice;
      else Object.assign(common, zoomSize(window));
      const [shown, index] = await Promise.all([
        client.call('RenderImage', { ...common, layer: $('layer').value === 'distance' ? 'LAYER_DISTANCE' : 'LAYER_IDS', drawSites: !space && $('draw-sites').checked }),
        client.call('RenderImage', { ...common, layer: 'LAYER_SITE_INDEX' }),
      ]);
      if (sceneId !== state.sceneId) return;
      const [bitmap, decoded] = await Promise.all([decode(bytesOf(shown.image)), decodeIndex(index)]);
      if (sceneId !== state.sceneId) return;
      state.image = { bitmap, window: windowOf(shown.window), version: Number(shown.version ?? 0) };
      state.index = decoded;
      state.frameVersion = Math.min(state.image.version, decoded.version);
      gvd.imageSlice = space ? Number(shown.slice ?? 0) : -1;
      gvd.frameVersion = state.frameVersion;
    }
    clearError('render');
    drawBase();
    drawOverlay();
    showPanel();
    gvd.refreshes += 1;
    gvd.ready = true;
  } catch (e) {
    showError(e, 'render');
  } finally {
    rendering = false;
    if (wanted >= 0 && sceneId === state.sceneId) {
      const v = wanted;
      wanted = -1;
      refresh(v);
    }
  }
}

// Live: each frame published (by anyone) refreshes the picture; a broken stream is opened
// again after a second.
async function watch(sceneId) {
  const controller = new AbortController();
  state.watch = controller;
  while (!controller.signal.aborted) {
    try {
      await client.stream('WatchScene', { sceneId, afterVersion: String(state.frameVersion) }, (event) => {
        if (event.deleted) {
          showError(new ConnectError(`scene ${sceneId} was deleted`, Code.NotFound), 'scenes');
          controller.abort();
          loadScenes();
          return;
        }
        if (event.reloaded) {
          // The store went back in time: versions from here on are a new history. The stream
          // ends; the next one starts from the latest frame.
          state.frameVersion = 0;
          return;
        }
        const version = Number(event.version ?? 0);
        if (state.scene) state.scene.siteCount = event.siteCount ?? '0';
        if (version > state.frameVersion) refresh(version);
      }, { signal: controller.signal });
    } catch (e) {
      if (controller.signal.aborted) return;
      showError(e, 'watch');
      if ([Code.Unauthenticated, Code.PermissionDenied, Code.NotFound].includes(e.code)) return;
    }
    await new Promise((resolve) => setTimeout(resolve, 1000));
  }
}

// ---- drawing --------------------------------------------------------------------------------

// Draws `source` as part of an image of cols x rows pixels covering the scene window w, its
// top-left pixel at (c0, r0) of that image.
function drawImageOver(context, source, w, cols, rows, c0 = 0, r0 = 0) {
  const [x0, y0] = toCanvas(w.minX, w.maxY);
  const [x1, y1] = toCanvas(w.maxX, w.minY);
  const px = (x1 - x0) / cols, py = (y1 - y0) / rows;
  context.drawImage(source, x0 + c0 * px, y0 + r0 * py, source.width * px, source.height * py);
}

function drawBase() {
  const context = base.getContext('2d');
  context.fillStyle = '#202024';
  context.fillRect(0, 0, base.width, base.height);
  if (!state.image || !state.view) return;
  const { bitmap, window } = state.image;
  // Pixels larger than the image's are shown as squares; smaller ones averaged, so that the
  // thin lines of the drawn sites stay whole.
  const [x0] = toCanvas(window.minX, 0), [x1] = toCanvas(window.maxX, 0);
  context.imageSmoothingEnabled = x1 - x0 < bitmap.width;
  drawImageOver(context, bitmap, window, bitmap.width, bitmap.height);
}

// The hovered site's pixels, white and half transparent, on a canvas the size of its box.
function tintOf(siteId) {
  const index = state.index;
  if (!index) return null;
  const k = index.slotOf.get(siteId);
  if (!k) return null;
  if (index.tints.has(k)) return index.tints.get(k);
  const [c0, r0, c1, r1] = index.boxes.subarray(4 * k, 4 * k + 4);
  if (c1 < c0) return null;
  const w = c1 - c0 + 1, h = r1 - r0 + 1;
  const canvas = new OffscreenCanvas(w, h);
  const context = canvas.getContext('2d');
  const pixels = context.createImageData(w, h);
  for (let row = 0; row < h; ++row) {
    for (let col = 0; col < w; ++col) {
      if (index.ids[(r0 + row) * index.width + c0 + col] !== k) continue;
      const at = 4 * (row * w + col);
      pixels.data.set([255, 255, 255, 140], at);
    }
  }
  context.putImageData(pixels, 0, 0);
  const tint = { canvas, c0, r0 };
  if (index.tints.size > 256) index.tints.clear();
  index.tints.set(k, tint);
  return tint;
}

function tracePath(context, site, closeRing = true) {
  const pts = (list) => (list ?? []).map((p) => toCanvas(p.x ?? 0, p.y ?? 0));
  context.beginPath();
  if (site.point) {
    const [x, y] = toCanvas(site.point.x ?? 0, site.point.y ?? 0);
    context.arc(x, y, 6, 0, 2 * Math.PI);
  } else if (site.segment) {
    const [a, b] = pts([site.segment.a ?? {}, site.segment.b ?? {}]);
    context.moveTo(...a);
    context.lineTo(...b);
  } else if (site.polyline || site.polygon) {
    const v = pts(site.polyline ? site.polyline.points : site.polygon.vertices);
    v.forEach((p, i) => (i ? context.lineTo(...p) : context.moveTo(...p)));
    if (site.polygon && closeRing) context.closePath();
  } else if (site.path) {
    for (const sub of site.path.subpaths ?? []) {
      const v = pts(sub.points);
      if (v.length === 0) continue;
      context.moveTo(...v[0]);
      const degrees = sub.degrees?.length ? sub.degrees : v.slice(1).map(() => 1);
      let k = 1;
      for (const d of degrees) {
        if (d === 1 && k < v.length) context.lineTo(...v[k]);
        if (d === 2 && k + 1 < v.length) context.quadraticCurveTo(...v[k], ...v[k + 1]);
        if (d === 3 && k + 2 < v.length) context.bezierCurveTo(...v[k], ...v[k + 1], ...v[k + 2]);
        k += d;
      }
      if (sub.closed && closeRing) context.closePath();
    }
  } else if (site.bezier) {
    const c = pts(site.bezier.controlPoints);
    if (c.length > 0) context.moveTo(...c[0]);
    if (c.length === 3) context.quadraticCurveTo(...c[1], ...c[2]);
    if (c.length === 4) context.bezierCurveTo(...c[1], ...c[2], ...c[3]);
    if (c.length === 2) context.lineTo(...c[1]);
  }
}

function outline(context, site, colour) {
  tracePath(context, site);
  context.lineJoin = 'round';
  context.strokeStyle = 'rgba(0, 0, 0, 0.85)';
  context.lineWidth = 5;
  context.stroke();
  context.strokeStyle = colour;
  context.lineWidth = 2.5;
  context.stroke();
}

function draftSite() {
  const points = state.draft.map(([x, y]) => ({ x, y }));
  switch (state.tool) {
    case 'segment': return points.length === 2 ? { segment: { a: points[0], b: points[1] } } : { polyline: { points } };
    case 'polygon': return { polygon: { vertices: points } };
    case 'bezier': return points.length >= 3 ? { bezier: { controlPoints: points } } : { polyline: { points } };
    default: return { polyline: { points } };
  }
}

function drawOverlay() {
  const context = overlay.getContext('2d');
  context.clearRect(0, 0, overlay.width, overlay.height);
  if (!state.view) return;
  const hover = state.hover;
  if (hover?.found && !state.press?.drag) {
    const tint = tintOf(hover.siteId);
    if (tint && state.index) {
      context.imageSmoothingEnabled = false;
      const { window, width, height } = state.index;
      drawImageOver(context, tint.canvas, window, width, height, tint.c0, tint.r0);
    }
    if (hover.site) outline(context, hover.site, '#ffd21f');
    if (hover.closest) {
      // The site's point nearest to the cursor, and the line to it: the distance shown.
      const [ax, ay] = toCanvas(hover.x, hover.y);
      const [bx, by] = toCanvas(hover.closest[0], hover.closest[1]);
      context.strokeStyle = '#ffd21f';
      context.lineWidth = 1;
      context.setLineDash([3, 3]);
      context.beginPath();
      context.moveTo(ax, ay);
      context.lineTo(bx, by);
      context.stroke();
      context.setLineDash([]);
      context.fillStyle = '#ffd21f';
      context.beginPath();
      context.arc(bx, by, 3, 0, 2 * Math.PI);
      context.fill();
    }
  }
  if (state.selected?.site) outline(context, state.selected.site, '#3ee0ff');
  const drag = state.press?.drag;
  if (drag?.to) outline(context, { point: { x: drag.to[0], y: drag.to[1] } }, '#ffd21f');
  if (state.draft.length > 0) {
    context.setLineDash([6, 4]);
    outline(context, draftSite(), '#ff7af2');
    context.setLineDash([]);
    for (const [x, y] of state.draft) {
      const [cx, cy] = toCanvas(x, y);
      context.fillStyle = '#ff7af2';
      context.fillRect(cx - 3, cy - 3, 6, 6);
    }
  }
}

// ---- the panel ------------------------------------------------------------------------------

const format = (v) => (Number.isFinite(v) ? v.toPrecision(6) : '–');

function featureName(kind, index) {
  return kind ? `${kind.replace('FEATURE_KIND_', '').toLowerCase()} ${index ?? 0}` : '–';
}

function kindOf(site) {
  return ['point', 'segment', 'polyline', 'polygon', 'bezier', 'path', 'triangle', 'mesh'].find((k) => site?.[k]) ?? '–';
}

function percentile(sorted, p) {
  return sorted.length ? sorted[Math.min(sorted.length - 1, Math.floor(p * sorted.length))] : NaN;
}

function showPanel() {
  const h = state.hover;
  $('hover-id').textContent = h ? (h.found ? h.siteId : `none within ${format(Number($('max-distance').value))}`) : '–';
  $('hover-feature').textContent = h?.found ? featureName(h.feature, h.featureIndex) : '–';
  $('hover-distance').textContent = h?.found ? String(h.distance) : '–';
  $('hover-at').textContent = h ? `${format(h.x)}, ${format(h.y)}` : '–';
  $('selected-id').textContent = state.selected?.siteId ?? '–';
  $('selected-kind').textContent = kindOf(state.selected?.site);
  $('delete').disabled = !state.selected;
  $('scene-version').textContent = state.frameVersion ? String(state.frameVersion) : '–';
  $('scene-sites').textContent = state.scene ? String(state.scene.siteCount ?? 0) : '–';
  const sorted = gvd.latencies.slice(-kHistory).sort((a, b) => a - b);
  $('latency').textContent = sorted.length
    ? `p50 ${percentile(sorted, 0.5).toFixed(1)} ms, p99 ${percentile(sorted, 0.99).toFixed(1)} ms (${sorted.length})`
    : '–';
}

// ---- hover: Pick, one call in flight --------------------------------------------------------

let picking = false;
let nextPick = null;

async function pick(at) {
  if (picking) {
    nextPick = at;
    return;
  }
  picking = true;
  const sent = performance.now();
  try {
    const maxDistance = Math.max(0, Number($('max-distance').value) || 0);
    const r = await client.call('Pick', { sceneId: state.sceneId, point: pointAt(at.x, at.y), maxDistance });
    state.hover = {
      x: at.x, y: at.y, found: !!r.found, siteId: r.siteId ?? '', distance: r.distance ?? 0,
      feature: r.featureKind ?? '', featureIndex: r.featureIndex ?? 0, site: r.site ?? null,
      closest: r.closest ? [r.closest.x ?? 0, r.closest.y ?? 0] : null,
    };
    const answered = performance.now();
    drawOverlay();
    const drawn = performance.now();
    gvd.latencies.push(drawn - at.t0);
    // Where the time went: event to handler (the browser's own input queue), handler to call,
    // the call, the drawing.
    gvd.parts.push([at.handled - at.t0, sent - at.handled, answered - sent, drawn - answered]);
    if (gvd.parts.length > 4 * kHistory) gvd.parts.splice(0, gvd.parts.length - kHistory);
    if (gvd.latencies.length > 4 * kHistory) gvd.latencies.splice(0, gvd.latencies.length - kHistory);
    gvd.hover = { ...state.hover, site: undefined, at: at.cx !== undefined ? [at.cx, at.cy] : null };
    gvd.hoverSeq += 1;
    clearError('pick');
    showPanel();
  } catch (e) {
    showError(e, 'pick');
  } finally {
    picking = false;
    if (nextPick) {
      const next = nextPick;
      nextPick = null;
      pick(next);
    }
  }
}

// A click selects what is nearest to where it was, asked anew: the last hover answer may be
// for another position.
async function select([x, y]) {
  try {
    const maxDistance = Math.max(0, Number($('max-distance').value) || 0);
    const r = await client.call('Pick', { sceneId: state.sceneId, point: pointAt(x, y), maxDistance });
    state.selected = r.found ? { siteId: r.siteId, site: r.site ?? null } : null;
    clearError('pick');
  } catch (e) {
    showError(e, 'pick');
  }
  showPanel();
  drawOverlay();
}

// The SITE_INDEX pixel at scene point (x, y): the site it names ('' for none) and its centre.
function indexAt(x, y) {
  const index = state.index;
  if (!index) return null;
  const w = index.window;
  const col = Math.floor(((x - w.minX) / (w.maxX - w.minX)) * index.width);
  const row = Math.floor(((w.maxY - y) / (w.maxY - w.minY)) * index.height);
  if (col < 0 || row < 0 || col >= index.width || row >= index.height) return null;
  const k = index.ids[row * index.width + col];
  return {
    id: k ? index.siteIds[k - 1] : '',
    x: w.minX + ((col + 0.5) / index.width) * (w.maxX - w.minX),
    y: w.maxY - ((row + 0.5) / index.height) * (w.maxY - w.minY),
  };
}

// ---- writes ---------------------------------------------------------------------------------

function noteWrite(version) {
  state.lastWriteVersion = Math.max(state.lastWriteVersion, Number(version ?? 0));
  gvd.lastWriteVersion = state.lastWriteVersion;
}

async function write(method, request) {
  try {
    const r = await client.call(method, { sceneId: state.sceneId, ...request });
    noteWrite(r.version);
    clearError('write');
    refresh(state.lastWriteVersion);
    return r;
  } catch (e) {
    showError(e, 'write');
    return null;
  }
}

// A dragged point is sent as it moves, one upsert in flight (the newest position waits):
// DURABILITY_RELAXED while it moves (answered once written, without waiting for the disk;
// synced within the server's --relaxed-sync-ms), DURABILITY_SYNC where it is dropped, the
// position that stays.
let moving = false;
let nextMove = null;

async function move(id, site, to, durability = 'DURABILITY_RELAXED') {
  if (moving) {
    nextMove = [id, site, to, durability];
    return;
  }
  moving = true;
  await write('UpsertSites', {
    sites: [{ ...site, id, point: { x: to[0], y: to[1] } }],
    durability,
  });
  moving = false;
  if (nextMove) {
    const args = nextMove;
    nextMove = null;
    await move(...args);
  }
}

function newId(kind) {
  return `${kind}-${Date.now().toString(36)}${Math.floor(Math.random() * 1296).toString(36)}`;
}

const kNeeds = { point: 1, segment: 2, bezier: 4 };  // points that complete a site

async function finishDraft() {
  const tool = state.tool;
  const points = state.draft.map(([x, y]) => ({ x, y }));
  const enough = { point: 1, segment: 2, polyline: 2, polygon: 3, bezier: 3 }[tool];
  if (points.length < enough) return;
  state.draft = [];
  let site;
  switch (tool) {
    case 'point': site = { point: points[0] }; break;
    case 'segment': site = { segment: { a: points[0], b: points[1] } }; break;
    case 'polyline': site = { polyline: { points } }; break;
    case 'polygon': site = { polygon: { vertices: points } }; break;
    default: site = { bezier: { controlPoints: points } };
  }
  const id = newId(tool);
  drawOverlay();
  if (await write('UpsertSites', { sites: [{ id, ...site }] })) {
    state.selected = { siteId: id, site };
    showPanel();
    drawOverlay();
  }
}

async function deleteSelected() {
  if (!state.selected) return;
  const id = state.selected.siteId;
  state.selected = null;
  if (state.hover?.siteId === id) state.hover = null;
  showPanel();
  drawOverlay();
  await write('DeleteSites', { ids: [id] });
}

// ---- pointer, wheel and keys ----------------------------------------------------------------

function canvasPoint(e) {
  const r = overlay.getBoundingClientRect();
  return [e.clientX - r.left, e.clientY - r.top];
}

overlay.addEventListener('pointerdown', (e) => {
  if (e.button !== 0 || !state.view) return;
  const [cx, cy] = canvasPoint(e);
  overlay.setPointerCapture(e.pointerId);
  state.press = { x: cx, y: cy, view: { ...state.view }, moved: false, drag: null };
  const site = state.hover?.found ? state.hover.site : null;
  if (state.tool === 'select' && site?.point && state.slice < 0) {  // no drags in a 3D slice
    const [px, py] = toCanvas(site.point.x ?? 0, site.point.y ?? 0);
    if (Math.hypot(px - cx, py - cy) <= 10) state.press.drag = { id: state.hover.siteId, site, to: null };
  }
});

overlay.addEventListener('pointermove', (e) => {
  if (!state.view || !state.sceneId) return;
  const [cx, cy] = canvasPoint(e);
  const press = state.press;
  if (press) {
    if (Math.hypot(cx - press.x, cy - press.y) > 3) press.moved = true;
    if (press.drag && press.moved) {
      press.drag.to = toScene(cx, cy);
      drawOverlay();
      move(press.drag.id, press.drag.site, press.drag.to);
      return;
    }
    if (!press.drag && press.moved) {  // pan
      const s = scale();
      const dx = (cx - press.x) / s, dy = (cy - press.y) / s;
      setView({ minX: press.view.minX - dx, maxX: press.view.maxX - dx, minY: press.view.minY + dy, maxY: press.view.maxY + dy });
      drawBase();
      drawOverlay();
      return;
    }
  }
  if (!kRawUpdates) hover(e);
});

// Hover. Browsers hand pointermove to the page once per animation frame; pointerrawupdate
// (Chromium, secure contexts: HTTPS or loopback) as the pointer moves, up to a frame sooner.
const kRawUpdates = 'onpointerrawupdate' in window;

function hover(e) {
  if (!state.view || !state.sceneId || state.press) return;
  const [cx, cy] = canvasPoint(e);
  const [x, y] = toScene(cx, cy);
  pick({ x, y, cx, cy, t0: e.timeStamp, handled: performance.now() });
}

if (kRawUpdates) overlay.addEventListener('pointerrawupdate', hover);

overlay.addEventListener('pointerup', async (e) => {
  const press = state.press;
  state.press = null;
  if (!press || e.button !== 0) return;
  const [cx, cy] = canvasPoint(e);
  if (press.drag && press.moved) {
    const to = toScene(cx, cy);
    drawOverlay();
    await move(press.drag.id, press.drag.site, to, 'DURABILITY_SYNC');
    state.hover = null;
    return;
  }
  if (press.moved) {
    refresh(0);
    return;
  }
  // A click.
  if (state.tool === 'select') {
    select(toScene(cx, cy));
    return;
  }
  const p = toScene(cx, cy);
  const last = state.draft[state.draft.length - 1];
  if (last) {
    const [lx, ly] = toCanvas(...last);
    if (Math.hypot(lx - cx, ly - cy) <= 4) {  // the last point again: done
      finishDraft();
      return;
    }
  }
  state.draft.push(p);
  drawOverlay();
  if (state.draft.length === kNeeds[state.tool]) finishDraft();
});

overlay.addEventListener('pointerleave', () => {
  if (state.press) return;
  nextPick = null;
});

overlay.addEventListener('wheel', (e) => {
  if (!state.view) return;
  e.preventDefault();
  const [cx, cy] = canvasPoint(e);
  const [x, y] = toScene(cx, cy);
  const f = Math.exp(e.deltaY * 0.0015);
  const v = state.view;
  setView({ minX: x + (v.minX - x) * f, maxX: x + (v.maxX - x) * f, minY: y + (v.minY - y) * f, maxY: y + (v.maxY - y) * f });
  drawBase();
  drawOverlay();
  scheduleRefresh();
}, { passive: false });

document.addEventListener('keydown', (e) => {
  if (e.target instanceof HTMLInputElement || e.target instanceof HTMLSelectElement) return;
  if (e.key === 'Escape') {
    state.draft = [];
    state.selected = null;
    showPanel();
    drawOverlay();
  } else if (e.key === 'Enter') {
    finishDraft();
  } else if (e.key === 'Delete' || e.key === 'Backspace') {
    deleteSelected();
  }
});

// ---- controls -------------------------------------------------------------------------------

const kHints = {
  select: 'Hover to find the nearest object; click to select it; drag a point to move it; drag elsewhere to pan; wheel to zoom.',
  point: 'Click to add a point.',
  segment: 'Click its two ends.',
  polyline: 'Click its points; click the last one again (or press Enter) to finish.',
  polygon: 'Click its vertices; click the last one again (or press Enter) to close it.',
  bezier: 'Click four control points (or three, then Enter, for a quadratic curve).',
};

for (const radio of document.querySelectorAll('input[name=tool]')) {
  radio.addEventListener('change', () => {
    state.tool = radio.value;
    state.draft = [];
    $('hint').textContent = kHints[state.tool];
    drawOverlay();
  });
}
$('hint').textContent = kHints.select;
$('error').addEventListener('click', () => clearError());
$('scene').addEventListener('change', () => openScene($('scene').value));
$('demo').addEventListener('click', createDemo);
$('delete').addEventListener('click', deleteSelected);
$('fit').addEventListener('click', () => {
  if (!state.scene) return;
  setView(fit(windowOf(state.scene.window)));
  drawBase();
  drawOverlay();
  refresh(0);
});
$('layer').addEventListener('change', () => refresh(0));
$('draw-sites').addEventListener('change', () => refresh(0));
$('z').addEventListener('input', () => {
  state.slice = gvd.slice = Number($('z').value);
  $('z-value').textContent = sliceZ().toPrecision(4);
  state.hover = null;
  showPanel();
  drawOverlay();
  refresh(0);
});
$('max-distance').addEventListener('change', () => {
  state.hover = null;
  showPanel();
  drawOverlay();
});
$('token').addEventListener('change', () => {
  client = new Calls($('token').value.trim());
  localStorage.setItem('gvd.token', client.token);
  state.sceneId = '';
  loadScenes();
});

new ResizeObserver(resize).observe(stage);
resize();
loadScenes();
