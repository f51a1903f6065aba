"""gvd.Client: gvd-server's calls with NumPy arrays in and out."""
from __future__ import annotations

import functools
import operator
import struct
from dataclasses import dataclass
from itertools import chain, count, filterfalse
from typing import (Any, Callable, Dict, Iterable, Iterator, List, Mapping, Optional, Sequence,
                    Tuple, Union)

import numpy as np
from google.protobuf import json_format

from gvd.v1 import voronoi_pb2 as pb  # generated when the package is built
from . import _packed
from ._packed import PackedAnswers
from ._transport import GrpcTransport, GvdError, HttpTransport, _parse

ArrayLike = Union[np.ndarray, Sequence[Sequence[float]]]
Progress = Callable[[int, int], None]

# The server's defaults (--max-points-per-query, --max-sites-per-request): a larger batch is
# sent in several calls.
MAX_POINTS_PER_CALL = 1_000_000
MAX_SITES_PER_CALL = 100_000
# Answers per FindNearestStream chunk, each a progress step (find_nearest's `progress`).
CHUNK_POINTS = 65_536
# Calls of at most this many sites are written a site at a time (_array_sites).
FEW_SITES = 32


@dataclass
class NearestResult:
    """Answers to m query points, each a NumPy array of shape (m,) (closest and gradient: (m,
    2) or (m, 3)). An empty answer (no site is a candidate) has site_id None, site_index -1
    and distance +inf."""
    version: int
    site_ids: np.ndarray        # object: str, or None for an empty answer
    site_indices: np.ndarray    # int64 into `ids`, -1 for an empty answer
    ids: List[str]              # the distinct sites named, in the order site_indices count
    distances: np.ndarray       # float64, scene units
    error_bounds: np.ndarray    # float64, scene units: the distance's possible error (0 if exact)
    exact: np.ndarray           # bool: certified exact
    feature_indices: np.ndarray  # uint32: the part of the site nearest to the point
    feature_kinds: np.ndarray   # int32: gvd.v1.FeatureKind values
    closest: Optional[np.ndarray] = None   # with closest=True: each site's nearest point
    gradient: Optional[np.ndarray] = None  # with closest=True: the distance's unit gradient

    def __len__(self) -> int:
        return len(self.distances)


class Client:
    """A connection to a gvd-server.

    target: "HOST:PORT" (or any gRPC target) speaks gRPC; "http://HOST:PORT" or
    "https://HOST:PORT" speaks HTTP with the Connect protocol. token: a bearer token
    (--tokens on the server). root_certificates, private_key, certificate_chain: PEM bytes
    for TLS (tls=True with none of them uses the system's roots). timeout: seconds for each
    call (None: no deadline; a call with min_version waits at most this long).

    Every call of the service is a method; arguments after the scene id are keyword
    arguments named after the request's fields. A failed call raises GvdError, whose `code` is
    the status (grpc.StatusCode) and `message` the server's.
    """

    def __init__(self, target: str, *, token: Optional[str] = None,
                 root_certificates: Optional[bytes] = None, private_key: Optional[bytes] = None,
                 certificate_chain: Optional[bytes] = None, tls: bool = False,
                 timeout: Optional[float] = 60.0, max_message_bytes: int = 256 << 20):
        kind = HttpTransport if target.startswith(("http://", "https://")) else GrpcTransport
        self._transport = kind(target, token=token, root_certificates=root_certificates,
                               private_key=private_key, certificate_chain=certificate_chain,
                               tls=tls, max_message_bytes=max_message_bytes)
        self.timeout = timeout

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def close(self) -> None:
        self._transport.close()

    # ---- any call ----

    def call(self, method: str, request: Any) -> Any:
        """Any unary call of gvd.v1.VoronoiService by name, with its request message; the
        response message."""
        response = _RESPONSES[method]
        return self._transport.unary(method, request, response, self.timeout)

    # ---- scenes ----

    def create_scene(self, scene_id: str, *, window: Sequence[float], size: Sequence[int],
                     **fields: Any) -> pb.Scene:
        """A new scene. window: (min_x, min_y, max_x, max_y), or (min_x, min_y, min_z, max_x,
        max_y, max_z) for a 3D scene; size: (width_px, height_px), or with depth_px. Other
        fields of CreateSceneRequest by name (max_error, render_mode, diagram)."""
        request = pb.CreateSceneRequest(scene_id=scene_id, window=_window(window), **fields)
        request.width_px, request.height_px = int(size[0]), int(size[1])
        if len(size) == 3:
            request.depth_px = int(size[2])
        return self._transport.unary("CreateScene", request, pb.CreateSceneResponse,
                                     self.timeout).scene

    def get_scene(self, scene_id: str) -> pb.Scene:
        return self._transport.unary("GetScene", pb.GetSceneRequest(scene_id=scene_id),
                                     pb.GetSceneResponse, self.timeout).scene

    def list_scenes(self) -> List[pb.Scene]:
        """Every scene, in id order, read page by page."""
        scenes: List[pb.Scene] = []
        token = ""
        while True:
            page = self._transport.unary("ListScenes", pb.ListScenesRequest(page_token=token),
                                         pb.ListScenesResponse, self.timeout)
            scenes += page.scenes
            token = page.next_page_token
            if not token:
                return scenes

    def delete_scene(self, scene_id: str) -> None:
        self._transport.unary("DeleteScene", pb.DeleteSceneRequest(scene_id=scene_id),
                              pb.DeleteSceneResponse, self.timeout)

    def watch(self, scene_id: str, *, after_version: int = 0,
              timeout: Optional[float] = None) -> Iterator[pb.WatchSceneResponse]:
        """The scene's events, one per published frame, until the scene is deleted or reloaded
        from a store that went back in time (its last event says `deleted` or `reloaded`) or
        the iterator is closed. No deadline unless `timeout`."""
        request = pb.WatchSceneRequest(scene_id=scene_id, after_version=after_version)
        return self._transport.stream("WatchScene", request, pb.WatchSceneResponse, timeout)

    # ---- sites ----

    def upsert_points(self, scene_id: str, ids: Sequence[str], xy: ArrayLike, *,
                      progress: Optional[Progress] = None, durability: str = "sync") -> int:
        """Puts point sites: ids[i] at xy[i] (an (n, 2) array, or (n, 3) in a 3D scene),
        replacing sites of those ids. Returns the scene's version that includes them. More
        than 100,000 go in several calls, each its own version (progress(done, n) after
        each). durability="relaxed" is answered once the change is written, before it is
        synced (gvd.v1.Durability: for interactive edits such as drags)."""
        xy = _points(xy, "xy")
        return self._upsert_arrays(scene_id, ids, "point", xy[:, None, :], progress, durability)

    def upsert_segments(self, scene_id: str, ids: Sequence[str], ab: ArrayLike, *,
                        progress: Optional[Progress] = None, durability: str = "sync") -> int:
        """Puts segment sites: ids[i] from ab[i, 0] to ab[i, 1] (an (n, 2, 2) array, or
        (n, 2, 3) in a 3D scene), as upsert_points puts points."""
        ends = np.ascontiguousarray(ab, dtype="<f8")
        if ends.ndim != 3 or ends.shape[1] != 2 or ends.shape[2] not in (2, 3):
            raise ValueError("ab must be an (n, 2, 2) or (n, 2, 3) array, "
                             f"not of shape {ends.shape}")
        return self._upsert_arrays(scene_id, ids, "segment", ends, progress, durability)

    def _upsert_arrays(self, scene_id: str, ids: Sequence[str], kind: str, ends: np.ndarray,
                       progress: Optional[Progress], durability: str) -> int:
        """upsert_points' and upsert_segments': sites of `kind` whose points are ends[i]."""
        if len(ids) != len(ends):
            raise ValueError(f"{len(ids)} ids for {len(ends)} {kind}s")
        level = _durability(durability)
        version = 0
        for start in range(0, len(ends), MAX_SITES_PER_CALL):
            chunk = ends[start:start + MAX_SITES_PER_CALL]
            chunk_ids = [str(sid) for sid in ids[start:start + len(chunk)]]
            body = _array_sites(_upsert_fields(scene_id, level), chunk_ids, kind, chunk)
            request = None
            if body is None:  # an id too long for the arrays' encoding
                request = pb.UpsertSitesRequest(scene_id=scene_id, durability=level)
                for sid, points in zip(chunk_ids, chunk.tolist()):
                    geometry = getattr(request.sites.add(id=sid), kind)
                    for message, p in zip([geometry] if kind == "point" else
                                          [geometry.a, geometry.b], points):
                        message.x, message.y = p[0], p[1]
                        if len(p) == 3:
                            message.z = p[2]
            version = self._transport.unary("UpsertSites", request, pb.UpsertSitesResponse,
                                            self.timeout, body=body).version
            if progress:
                progress(start + len(chunk), len(ends))
        return version

    def upsert_sites(self, scene_id: str, sites: Iterable[Union[Mapping[str, Any], pb.Site]], *,
                     progress: Optional[Progress] = None, durability: str = "sync") -> int:
        """Puts sites of any kind, each a gvd.v1.Site or a dict in the API's JSON form
        ({"id": "a", "segment": {"a": {"x": 0, "y": 0}, "b": {"x": 1, "y": 1}}}) or
        GeoJSON-like ({"id": "a", "type": "LineString", "coordinates": [[0, 0], [1, 1]]}).
        Returns the version that includes them (several calls past 100,000 sites).
        durability as in upsert_points."""
        messages = [s if isinstance(s, pb.Site) else site_from_dict(s) for s in sites]
        fields = _upsert_fields(scene_id, _durability(durability))
        version = 0
        for start in range(0, len(messages), MAX_SITES_PER_CALL):
            # Each site's bytes after the call's fields, as the request's field `sites` (2):
            # one site in 2.4 µs against 4.5 µs copied into a request message, 100,000
            # segments in 0.38 s against 0.44 s.
            body = [fields]
            for message in messages[start:start + MAX_SITES_PER_CALL]:
                data = message.SerializeToString()
                body += [bytes((_SITES_TAG,)), _varint(len(data)), data]
            version = self._transport.unary("UpsertSites", None, pb.UpsertSitesResponse,
                                            self.timeout, body=b"".join(body)).version
            if progress:
                progress(min(start + MAX_SITES_PER_CALL, len(messages)), len(messages))
        return version

    def delete_sites(self, scene_id: str, ids: Sequence[str], *, durability: str = "sync") -> int:
        """Removes sites by id (NOT_FOUND if one is not there, and then none is removed).
        Returns the version without them. durability as in upsert_points."""
        request = pb.DeleteSitesRequest(scene_id=scene_id, ids=[str(i) for i in ids],
                                        durability=_durability(durability))
        return self._transport.unary("DeleteSites", request, pb.DeleteSitesResponse,
                                     self.timeout).version

    def list_sites(self, scene_id: str, *, page_size: int = 10_000) -> List[Dict[str, Any]]:
        """Every site, as dicts in the API's JSON form, read page by page; a write between
        pages restarts the listing, so the list is one version's."""
        while True:
            sites: List[Dict[str, Any]] = []
            token, version = "", None
            while True:
                page = self._transport.unary(
                    "ListSites", pb.ListSitesRequest(scene_id=scene_id, page_size=page_size,
                                                     page_token=token),
                    pb.ListSitesResponse, self.timeout)
                if version is not None and page.version != version:
                    break
                version = page.version
                sites += [json_format.MessageToDict(s) for s in page.sites]
                token = page.next_page_token
                if not token:
                    return sites

    # ---- queries ----

    def find_nearest(self, scene_id: str, points: ArrayLike, *, min_version: int = 0,
                     exact: bool = False, closest: bool = False, skip_refinement: bool = False,
                     progress: Optional[Progress] = None) -> NearestResult:
        """The nearest site to each of m query points (an (m, 2) array, or (m, 3) in a 3D
        scene), sent packed. min_version: answer from at least this version (waiting for
        its frame, unless the server answers from the index: see the API's
        FindNearestRequest.min_version). exact: certify every answer. closest: also each answer's closest point and
        the distance's gradient. progress(done, m) follows the answers as they come."""
        q = _points(points, "points")
        m = len(q)
        parts: List[_Packed] = []
        # Each call's answers come in one message, unless the caller follows a batch larger
        # than a chunk: then they stream in chunks, each a progress step. A stream costs more
        # (a message's reading and the joining of the messages' site ids): a 100,000-point
        # batch took 1.2-1.6 times as long streamed, a million-point one 1.7 times.
        stream = progress is not None and m > CHUNK_POINTS
        fields = (_query_fields(scene_id, exact, skip_refinement, closest, stream)
                  + _version_field(min_version))
        for start in range(0, m, MAX_POINTS_PER_CALL):
            part = q[start:start + MAX_POINTS_PER_CALL]
            # The points go packed, written straight from the array: field xy (5) or xyz.
            body = fields + _packed_doubles(5 if part.shape[1] == 2 else _XYZ_FIELD, part)
            if not stream:
                data = self._transport.unary("FindNearest", None, _Bytes, self.timeout,
                                             body=body)
                if m == len(part):  # the only call
                    if progress:
                        progress(m, m)
                    return _answer(data, m, q.shape[1], closest)
                parts.append(_Packed(_parse("FindNearest", PackedAnswers, data), start))
                continue
            for chunk in self._transport.stream("FindNearestStream", None,
                                                PackedAnswers, self.timeout, body=body):
                parts.append(_Packed(chunk, start))
                if progress:
                    progress(start + chunk.offset + chunk.count, m)
        return _join(parts, m, q.shape[1], closest)

    def pick(self, scene_id: str, x: float, y: float, z: Optional[float] = None, *,
             max_distance: float = 0.0) -> pb.PickResponse:
        """The site under a cursor: the exact nearest site to (x, y) within max_distance (0: any
        distance), with its closest point and the whole site."""
        point = pb.Point(x=x, y=y, z=z or 0.0)
        request = pb.PickRequest(scene_id=scene_id, point=point, max_distance=max_distance)
        return self._transport.unary("Pick", request, pb.PickResponse, self.timeout)


    # ---- rasters, analysis and planning ----

    def render_window(self, scene_id: str, *, window: Optional[Sequence[float]] = None,
                      size: Optional[Sequence[int]] = None, min_version: int = 0) -> "Raster":
        """The diagram over any window at any resolution (the service's adaptive zoom): per
        pixel the nearest site and its distance, as (H, W) arrays with row 0 at the window's
        bottom (min y). No window and size: the scene's own latest frame as it is."""
        request = pb.RenderWindowRequest(scene_id=scene_id, min_version=min_version)
        if window is not None:
            request.window.CopyFrom(_window(window))
        if size is not None:
            request.width_px, request.height_px = int(size[0]), int(size[1])
        r = self._transport.unary("RenderWindow", request, pb.RenderWindowResponse, self.timeout)
        h, w = r.height_px, r.width_px
        ids = np.array(r.ids, dtype=np.int64).reshape(h, w) - 1  # -1: no site
        return Raster(version=r.version, window=(r.window.min_x, r.window.min_y,
                                                 r.window.max_x, r.window.max_y),
                      site_indices=ids, ids=list(r.site_ids),
                      distances=np.array(r.distances, dtype=np.float32).reshape(h, w),
                      max_error=r.max_error)

    def render_image(self, scene_id: str, *, layer: str = "distance", **fields: Any) -> Any:
        """layer "distance": the (H, W) float32 distances of the scene's latest frame (row 0
        at the top, as images go); "ids": (H, W) site indices (-1: none) and the ids they
        name. Any other layer ("features", "site_index" and the rest of RenderImageRequest's
        fields, such as format="FORMAT_PNG") returns the encoded image's RenderImageResponse."""
        if layer in ("distance", "ids") and not fields:
            raster = self.render_window(scene_id)
            if layer == "distance":
                return raster.distances[::-1]
            return raster.site_indices[::-1], raster.ids
        request = pb.RenderImageRequest(scene_id=scene_id,
                                        layer=pb.RenderImageRequest.Layer.Value(
                                            "LAYER_" + layer.upper()),
                                        **fields)
        return self._transport.unary("RenderImage", request, pb.RenderImageResponse, self.timeout)

    def render_mosaic(self, image: bytes, *, tiles: int = 1000, adaptive: bool = False,
                      seed: int = 0, mean: bool = False,
                      format: str = "") -> pb.RenderMosaicResponse:
        """A Voronoi mosaic of an image file's bytes (PNG, JPEG, WebP, GIF, BMP or PNM), made by
        the server: the encoded mosaic (format "png", "jpeg", "webp" or "pnm"; "" the image's
        own) and its tiles' sites in pixel coordinates, y down from the top edge."""
        request = pb.RenderMosaicRequest(
            image=image, tiles=tiles, adaptive=adaptive, seed=seed, mean=mean,
            format=pb.RenderMosaicRequest.Format.Value("FORMAT_" + (format.upper() or "UNSPECIFIED")))
        return self._transport.unary("RenderMosaic", request, pb.RenderMosaicResponse, self.timeout)

    def get_boundaries(self, scene_id: str, **fields: Any) -> pb.GetBoundariesResponse:
        """The diagram's boundaries, as polylines between pairs of sites (GetBoundariesRequest's
        fields by name: window, method, site_id, min_version, coarse)."""
        if "window" in fields:
            fields["window"] = _window(fields["window"])
        return self._transport.unary("GetBoundaries",
                                     pb.GetBoundariesRequest(scene_id=scene_id, **fields),
                                     pb.GetBoundariesResponse, self.timeout)

    def get_neighbors(self, scene_id: str, **fields: Any) -> pb.GetNeighborsResponse:
        """The pairs of sites whose regions touch (and the hidden sites found)."""
        return self._transport.unary("GetNeighbors",
                                     pb.GetNeighborsRequest(scene_id=scene_id, **fields),
                                     pb.GetNeighborsResponse, self.timeout)

    def get_delaunay(self, scene_id: str, **fields: Any) -> pb.GetDelaunayResponse:
        """The Delaunay triangulation of a scene of points: edges and triangles by site id."""
        return self._transport.unary("GetDelaunay",
                                     pb.GetDelaunayRequest(scene_id=scene_id, **fields),
                                     pb.GetDelaunayResponse, self.timeout)

    def get_clearance_field(self, scene_id: str, *, window: Optional[Sequence[float]] = None,
                            size: Optional[Sequence[int]] = None,
                            **fields: Any) -> pb.GetClearanceFieldResponse:
        """Clearance (distance to the nearest site) sampled over a window; the response's
        `clearance` is a flat list (np.asarray(...).reshape(height_px, width_px))."""
        request = pb.GetClearanceFieldRequest(scene_id=scene_id, **fields)
        if window is not None:
            request.window.CopyFrom(_window(window))
        if size is not None:
            request.width_px, request.height_px = int(size[0]), int(size[1])
            if len(size) == 3:
                request.depth_px = int(size[2])
        return self._transport.unary("GetClearanceField", request, pb.GetClearanceFieldResponse,
                                     self.timeout)

    def plan_path(self, scene_id: str, start: Sequence[float], goal: Sequence[float], *,
                  robot_radius: float = 0.0, **fields: Any) -> "Path":
        """A path for a disc of robot_radius from start to goal along the diagram's
        boundaries: its points as an (k, 2) array and its proven minimum clearance."""
        request = pb.PlanPathRequest(scene_id=scene_id, start=pb.Point(x=start[0], y=start[1]),
                                     goal=pb.Point(x=goal[0], y=goal[1]),
                                     robot_radius=robot_radius, **fields)
        r = self._transport.unary("PlanPath", request, pb.PlanPathResponse, self.timeout)
        return Path(points=np.array([(p.x, p.y) for p in r.path]).reshape(-1, 2),
                    min_clearance=r.min_clearance, response=r)


@dataclass
class Raster:
    """A window of the diagram: per pixel (row 0 at the bottom) the nearest site's index into
    `ids` (-1: none) and its distance (+inf: none), with the meshes' error bound."""
    version: int
    window: tuple
    site_indices: np.ndarray
    ids: List[str]
    distances: np.ndarray
    max_error: float


@dataclass
class Path:
    points: np.ndarray
    min_clearance: float
    response: Any


# ---- helpers ----

_RESPONSES = {m.name: getattr(pb, m.output_type.name)
              for m in pb.DESCRIPTOR.services_by_name["VoronoiService"].methods}
_XYZ_FIELD = next((f.number for f in pb.FindNearestStreamRequest.DESCRIPTOR.fields
                   if f.name == "xyz"), None)


def _window(w: Sequence[float]) -> pb.Window:
    if len(w) == 4:
        return pb.Window(min_x=w[0], min_y=w[1], max_x=w[2], max_y=w[3])
    if len(w) == 6:
        return pb.Window(min_x=w[0], min_y=w[1], min_z=w[2], max_x=w[3], max_y=w[4], max_z=w[5])
    raise ValueError(f"a window is (min_x, min_y, max_x, max_y) or its 3D form, not {tuple(w)}")


def _durability(name: str) -> int:
    if name not in ("sync", "relaxed"):
        raise ValueError(f'durability must be "sync" or "relaxed", not {name!r}')
    return pb.DURABILITY_SYNC if name == "sync" else pb.DURABILITY_RELAXED


def _points(a: ArrayLike, name: str) -> np.ndarray:
    arr = np.ascontiguousarray(a, dtype="<f8")
    if arr.ndim != 2 or arr.shape[1] not in (2, 3):
        raise ValueError(f"{name} must be an (n, 2) or (n, 3) array, not of shape {arr.shape}")
    return arr


def _varint(n: int) -> bytes:
    out = bytearray()
    while True:
        b = n & 0x7F
        n >>= 7
        if n:
            out.append(b | 0x80)
        else:
            out.append(b)
            return bytes(out)


def _packed_doubles(field: Optional[int], a: np.ndarray) -> bytes:
    if field is None:
        raise GvdError(_grpc_code("UNIMPLEMENTED"), "this server's API has no 3D query points")
    data = a.astype("<f8", copy=False).tobytes()
    return _varint(field << 3 | 2) + _varint(len(data)) + data


# A call's fields but its sites, or but its version and points, written by protobuf once for
# each kind of call and kept; the rest follows as bytes (protobuf reads a field written twice
# as the last one, and a repeated field's records as one list). With each call's message made
# and written, and a few sites as protobuf's messages, a one-point move (an upsert and a read
# at its version) took 197,000 instructions of the client's own; 162,000 this way.
@functools.lru_cache(maxsize=256)
def _upsert_fields(scene_id: str, durability: int) -> bytes:
    return pb.UpsertSitesRequest(scene_id=scene_id, durability=durability).SerializeToString()


@functools.lru_cache(maxsize=256)
def _query_fields(scene_id: str, exact: bool, skip_refinement: bool, closest: bool,
                  stream: bool) -> bytes:
    request = (pb.FindNearestStreamRequest(chunk_size=CHUNK_POINTS) if stream
               else pb.FindNearestRequest())
    request.scene_id = scene_id
    request.exact = exact
    request.skip_refinement = skip_refinement
    if closest:
        request.fields.extend([pb.NEAREST_FIELD_SITE, pb.NEAREST_FIELD_DISTANCE,
                               pb.NEAREST_FIELD_ERROR_BOUND, pb.NEAREST_FIELD_EXACT,
                               pb.NEAREST_FIELD_FEATURE, pb.NEAREST_FIELD_CLOSEST,
                               pb.NEAREST_FIELD_GRADIENT])
    return request.SerializeToString()


# FindNearestRequest.min_version's tag (FindNearestStreamRequest's is the same).
_MIN_VERSION_TAG = _varint(
    pb.FindNearestRequest.DESCRIPTOR.fields_by_name["min_version"].number << 3)


def _version_field(min_version: int) -> bytes:
    """min_version as its field's bytes (none for 0, as protobuf writes it)."""
    v = operator.index(min_version)
    if not 0 <= v < 1 << 64:
        raise ValueError(f"min_version must be 0 to 2^64 - 1, not {v}")
    return _MIN_VERSION_TAG + _varint(v) if v else b""


# The bytes of a site after its id, for _array_sites, by kind and dimensions: a point
# (Site.point, field 2) or a segment (Site.segment, field 3, its ends a and b, fields 1 and 2),
# each point's x, y and z (fields 1-3) as doubles; packed, without alignment, in wire order.
_SITE_FIELDS = {"point": (2, 1), "segment": (3, 2)}  # the geometry's field, its points


def _tail(points: int, dims: int) -> np.dtype:
    fields = [("tag", "u1"), ("length", "u1")]
    for e in range(points):
        if points > 1:  # a message of points: each point's tag and length first
            fields += [(f"tag{e}", "u1"), (f"length{e}", "u1")]
        for k in range(dims):
            fields += [(f"tag{e}_{k}", "u1"), (f"value{e}_{k}", "<f8")]
    return np.dtype(fields)


def _tail_bytes(kind: str, tail: np.dtype, dims: int) -> Dict[str, int]:
    """The constant fields of `kind`'s tail (every one but the values): tags and lengths."""
    field, points = _SITE_FIELDS[kind]
    out = {"tag": field << 3 | 2, "length": tail.itemsize - 2}
    for e in range(points):
        if points > 1:
            out[f"tag{e}"], out[f"length{e}"] = (e + 1) << 3 | 2, 9 * dims
        for k in range(dims):
            out[f"tag{e}_{k}"] = (k + 1) << 3 | 1
    return out


def _tail_struct(tail: np.dtype, constants: Dict[str, int]) -> Tuple[struct.Struct, List[bytes]]:
    """The tail as struct writes it, a site at a time: each value a double after the run of
    constant bytes before it (a bytes field); and those runs."""
    form, runs, run = "<", [], bytearray()
    for name in tail.names:
        if name in constants:
            run.append(constants[name])
        else:
            form += f"{len(run)}sd"
            runs.append(bytes(run))
            run = bytearray()
    return struct.Struct(form), runs


def _tail_forms(kind: str, dims: int) -> tuple:
    """`kind`'s tail in `dims` dimensions: its dtype, its constant fields, its struct form."""
    tail = _tail(_SITE_FIELDS[kind][1], dims)
    constants = _tail_bytes(kind, tail, dims)
    return tail, constants, _tail_struct(tail, constants)


_TAILS = {(kind, dims): _tail_forms(kind, dims) for kind in _SITE_FIELDS for dims in (2, 3)}
# UpsertSitesRequest.sites' tag (field 2, bytes), before each site.
_SITES_TAG = 0x12


def _array_sites(fields: bytes, ids: List[str], kind: str, ends: np.ndarray) -> Optional[bytes]:
    """The bytes of an UpsertSitesRequest whose other fields' bytes are `fields`, with sites
    ids[i] of `kind` ("point" or "segment") through the points ends[i] (an (n, 1 or 2, dims)
    array) as its sites. Made and serialized as protobuf's Python messages (Debian's protobuf
    3.21, its C++ implementation), 100,000 points took 0.24-0.37 s, longer than the server's
    whole commit of them, against 0.03-0.06 s written here with a few NumPy steps; 20,000
    segments 0.10-0.11 s against 9-12 ms. Those steps cost a fixed 25-30 µs a call, so up to
    FEW_SITES sites are written one at a time through struct (one point in 1.5 µs against
    29 µs, 16 in 14 against 34, 32 in 30 against 39; 32 segments in 46 against 48). Each
    site is Site{id, point{x, y[, z]}} or Site{id, segment{a{...}, b{...}}}, every coordinate
    written (a zero too, which protobuf would omit: the same message to any reader). None
    where a site does not fit one-byte lengths (an id of more than 105 bytes for a point, 83
    for a segment; 96 and 65 in 3D): the caller then builds the message with protobuf."""
    n, count, dims = ends.shape
    tail, constants, (writer, runs) = _TAILS[(kind, dims)]
    encoded = [sid.encode() for sid in ids]
    if n <= FEW_SITES:
        out = [fields]
        for sid, points in zip(encoded, ends.tolist()):
            site_bytes = 2 + len(sid) + tail.itemsize
            if site_bytes > 127:
                return None
            # A Site's tag and length, its id's tag, length and bytes, then the tail.
            out += [bytes((_SITES_TAG, site_bytes, 0x0a, len(sid))), sid,
                    writer.pack(*chain.from_iterable(zip(runs, chain.from_iterable(points))))]
        return b"".join(out)
    id_bytes = np.fromiter(map(len, encoded), dtype=np.int64, count=n)
    # A Site: 0x0a (id) length id, then the tail (the geometry's tag, length and points).
    site_bytes = 2 + id_bytes + tail.itemsize
    if site_bytes.max() > 127:
        return None
    record = 2 + site_bytes  # _SITES_TAG and the Site's length first
    starts = np.cumsum(record) - record
    out = np.empty(int(record.sum()), dtype=np.uint8)
    out[starts] = _SITES_TAG
    out[starts + 1] = site_bytes
    out[starts + 2] = 0x0a
    out[starts + 3] = id_bytes
    id_starts = np.cumsum(id_bytes) - id_bytes
    out[np.repeat(starts + 4 - id_starts, id_bytes) + np.arange(int(id_bytes.sum()))] = \
        np.frombuffer(b"".join(encoded), dtype=np.uint8)
    sites = np.empty(n, dtype=tail)
    for name, value in constants.items():
        sites[name] = value
    for e in range(count):
        for k in range(dims):
            sites[f"value{e}_{k}"] = ends[:, e, k]
    out[(starts + 4 + id_bytes)[:, None] + np.arange(tail.itemsize)] = \
        sites.view(np.uint8).reshape(n, tail.itemsize)
    return fields + out.tobytes()


def _grpc_code(name: str):
    import grpc  # pylint: disable=import-outside-toplevel
    return getattr(grpc.StatusCode, name)


@dataclass
class _Packed:
    answers: PackedAnswers
    start: int


# The optional columns of an answer: PackedNearest's field number and name, NearestResult's
# name, the type. Where a message omits one, its value is zero (0.0, False).
_COLUMNS = ((_packed.ERROR_BOUND, "error_bound", "error_bounds", np.float64),
            (_packed.EXACT, "exact", "exact", bool),
            (_packed.FEATURE_INDEX, "feature_index", "feature_indices", np.uint32),
            (_packed.FEATURE_KIND, "feature_kind", "feature_kinds", np.int32))


class _Bytes:
    """A response type whose bytes are kept as they came, for the caller to read."""

    @staticmethod
    def FromString(data: bytes) -> bytes:  # pylint: disable=invalid-name
        return data


class _Irregular(Exception):
    """A message that _answer leaves to _join, which reads any and refuses what is wrong."""


def _answer(data: bytes, m: int, dims: int, closest: bool) -> NearestResult:
    """A unary FindNearest's answers from its bytes (FindNearestResponse's version and packed
    answers have FindNearestStreamResponse's numbers). A small message that answers the m
    points whole, every column of its m answers or none, with distinct site ids, is read from
    the wire (_packed.read_small) into one buffer that the result's arrays view: the fewest
    steps through NumPy's code, which an interactive call meets out of the caches. _join's
    general path reads every other message, and refuses what is wrong."""
    small = _packed.read_small(data) if len(data) < _packed._SMALL else None  # pylint: disable=protected-access
    if small is not None:
        try:
            return _answer_arrays(*small, m, dims, closest)
        except _Irregular:
            pass
    return _join([_Packed(_parse("FindNearest", PackedAnswers, data), 0)], m, dims, closest)


# The arrays of a small answer (_answer_arrays): their dtypes. Their buffer holds the 8-byte
# columns first, so that each array is aligned.
_SITE_DTYPE, _INDEX_DTYPE, _KIND_DTYPE = np.dtype("<i8"), np.dtype("<u4"), np.dtype("<i4")
_EXACT_DTYPE, _DOUBLE_DTYPE = np.dtype("?"), np.dtype("<f8")


def _answer_arrays(version: int, offset: int, ids: List[str], fields: Dict[int, bytes], m: int,
                   dims: int, closest: bool) -> NearestResult:
    """_answer's result from a small message's fields; _Irregular where they are not every
    column of the m points' answers (or none, for the optional ones) with distinct ids."""
    distances = fields.get(_packed.DISTANCE, b"")
    n = len(distances) // 8
    try:
        site = _packed.uvarints(fields.get(_packed.SITE, b""))
        exact, index, kind = (_packed.uvarints(fields[number]) if number in fields else [0] * n
                              for number in (_packed.EXACT, _packed.FEATURE_INDEX,
                                             _packed.FEATURE_KIND))
    except IndexError:
        raise _Irregular() from None
    bounds = fields.get(_packed.ERROR_BOUND, bytes(8 * n))
    doubles = [distances, bounds]
    if closest:
        doubles += [fields.get(_packed.CLOSEST, b""), fields.get(_packed.GRADIENT, b"")]
    if (offset or n != m or len(distances) % 8 or len(site) != n or len(exact) != n
            or len(index) != n or len(kind) != n or len(set(ids)) != len(ids)
            or (n and max(site) > len(ids)) or len(bounds) != 8 * n
            or any(len(d) != 8 * n * dims for d in doubles[2:])):
        raise _Irregular()
    buffer = bytearray(b"".join(doubles))
    try:
        buffer += struct.pack(f"<{n}q{n}I{n}i{n}?", *(s - 1 for s in site), *index, *kind,
                              *exact)
    except struct.error:  # an index or a kind out of its type's range (a negative kind)
        raise _Irregular() from None
    arrays, at = [], 0
    for d in doubles:
        arrays.append(np.frombuffer(buffer, _DOUBLE_DTYPE, len(d) // 8, at))
        at += len(d)
    for dtype in (_SITE_DTYPE, _INDEX_DTYPE, _KIND_DTYPE, _EXACT_DTYPE):
        arrays.append(np.frombuffer(buffer, dtype, n, at))
        at += n * dtype.itemsize
    distances_, bounds_ = arrays[:2]
    near, grad = ((arrays[2].reshape(n, dims), arrays[3].reshape(n, dims)) if closest
                  else (None, None))
    site_indices, feature_indices, feature_kinds, exact_ = arrays[-4:]
    return NearestResult(version=version,
                         site_ids=np.array(ids + [None], dtype=object)[site_indices],
                         site_indices=site_indices, ids=ids, distances=distances_,
                         error_bounds=bounds_, exact=exact_, feature_indices=feature_indices,
                         feature_kinds=feature_kinds, closest=near, gradient=grad)


def _join(parts: List[_Packed], m: int, dims: int, closest: bool) -> NearestResult:
    """The answers of one call's messages, checked to cover its m points once, in order, as
    one result (an empty message anywhere). Each column is its messages' arrays joined (a lone message's are used as they
    are: an interactive call's answer costs a few microseconds here)."""
    ids: List[str] = []  # the call's distinct sites, in the order of their indices
    index: Dict[str, int] = {}  # ids' indices, made once a second message needs them
    sites: List[np.ndarray] = []
    distances: List[np.ndarray] = []
    columns: Dict[int, List[np.ndarray]] = {number: [] for number, _, _, _ in _COLUMNS}
    near: List[np.ndarray] = []
    grad: List[np.ndarray] = []
    version = 0
    covered = 0
    for part in sorted(parts, key=lambda p: (p.start + p.answers.offset, p.answers.count)):
        a = part.answers
        version = max(version, a.version)
        lo = part.start + a.offset
        n = a.count
        if lo != covered or lo + n > m:
            raise GvdError(_grpc_code("INTERNAL"),
                           f"answers {lo} to {lo + n} after {covered} of {m} points")
        covered += n
        for number, _, _, dtype in _COLUMNS:
            values = a.arrays.get(number)
            if values is not None and len(values) != n:
                raise GvdError(_grpc_code("INTERNAL"),
                               f"field {number} holds {len(values)} of {n} answers")
            columns[number].append(np.zeros(n, dtype=dtype) if values is None
                                   else values.astype(dtype, copy=False))
        if closest:
            for number, out in ((_packed.CLOSEST, near), (_packed.GRADIENT, grad)):
                values = a.get(number, "<f8")
                if len(values) != n * dims:
                    raise GvdError(_grpc_code("INTERNAL"), "closest points missing from the answers")
                out.append(values.reshape(n, dims))
        idx = a.get(_packed.SITE, "u8")
        if len(idx) != n:
            raise GvdError(_grpc_code("INTERNAL"), f"{len(idx)} sites for {n} distances")
        named = a.site_ids
        if n and int(idx.max()) > len(named):
            raise GvdError(_grpc_code("INTERNAL"), "a site index past the message's site_ids")
        # The message's sites, 1 + an index into its own site_ids (0: none), to the call's
        # (-1: none). The first message's ids, distinct as the API has them, are the call's
        # as they are; later ones are numbered on in C loops over a dict (a Python step per
        # id took most of the joining of a 100,000-point batch).
        if not ids and len(set(named)) == len(named):
            ids = list(named)
            sites.append(idx.astype(np.int64) - 1)
        else:
            if len(index) < len(ids):
                index = dict(zip(ids, count()))
            fresh = dict.fromkeys(filterfalse(index.__contains__, named))
            index.update(zip(fresh, count(len(ids))))
            ids.extend(fresh)
            local = np.fromiter(chain(map(index.__getitem__, named), (-1,)), dtype=np.int64,
                                count=len(named) + 1)
            sites.append(local[idx.astype(np.int64) - 1])
        distances.append(a.get(_packed.DISTANCE, "<f8"))
    if covered != m:
        raise GvdError(_grpc_code("INTERNAL"), f"{covered} answers for {m} points")

    def joined(arrays: List[np.ndarray], dtype: Any, shape: tuple = ()) -> np.ndarray:
        if len(arrays) == 1:  # the caller's to change: a copy of a view of the bytes read
            return arrays[0] if arrays[0].flags.writeable else arrays[0].copy()
        return np.concatenate(arrays) if arrays else np.zeros((0,) + shape, dtype=dtype)

    site = joined(sites, np.int64)
    return NearestResult(
        version=version, site_ids=np.array(ids + [None], dtype=object)[site],
        site_indices=site, ids=ids, distances=joined(distances, np.float64),
        closest=joined(near, np.float64, (dims,)) if closest else None,
        gradient=joined(grad, np.float64, (dims,)) if closest else None,
        **{name: joined(columns[number], dtype) for number, _, name, dtype in _COLUMNS})


def site_from_dict(d: Mapping[str, Any]) -> pb.Site:
    """A gvd.v1.Site from the API's JSON form, or from a GeoJSON-like geometry with an "id":
    Point, LineString (a polyline; two points: a segment), Polygon (one ring: a polygon; with
    holes: a path of its rings, even-odd) or MultiPolygon (a path of all its rings)."""
    if "type" in d and "coordinates" in d:
        kind, c = d["type"], d["coordinates"]
        rest = {k: v for k, v in d.items() if k not in ("type", "coordinates")}
        site = json_format.ParseDict(rest, pb.Site())
        if kind == "Point":
            site.point.x, site.point.y = c[0], c[1]
            if len(c) > 2:
                site.point.z = c[2]
        elif kind == "LineString" and len(c) == 2:
            site.segment.a.x, site.segment.a.y = c[0][0], c[0][1]
            site.segment.b.x, site.segment.b.y = c[1][0], c[1][1]
        elif kind == "LineString":
            site.polyline.points.extend(pb.Point(x=p[0], y=p[1]) for p in c)
        elif kind in ("Polygon", "MultiPolygon"):
            rings = [r[:-1] if len(r) > 1 and list(r[0]) == list(r[-1]) else r
                     for r in (c if kind == "Polygon" else [r for p in c for r in p])]
            if len(rings) == 1:
                site.polygon.vertices.extend(pb.Point(x=p[0], y=p[1]) for p in rings[0])
            else:
                for r in rings:
                    sub = site.path.subpaths.add(closed=True)
                    sub.points.extend(pb.Point(x=p[0], y=p[1]) for p in r)
                site.path.fill_rule = pb.Path.FILL_RULE_EVEN_ODD
        else:
            raise ValueError(f"site {d.get('id')!r}: GeoJSON type {kind!r} is not a site "
                             "(Point, LineString, Polygon or MultiPolygon)")
        return site
    return json_format.ParseDict(dict(d), pb.Site())


class AsyncClient:
    """gvd.Client's methods for asyncio: each call runs on a thread of the default executor
    (the transports are thread-safe), so many may be in flight at once; watch() is an async
    iterator."""

    def __init__(self, target: str, **options: Any):
        self._client = Client(target, **options)

    async def __aenter__(self) -> "AsyncClient":
        return self

    async def __aexit__(self, *exc: Any) -> None:
        self.close()

    def close(self) -> None:
        self._client.close()

    def __getattr__(self, name: str) -> Any:
        import asyncio  # pylint: disable=import-outside-toplevel
        method = getattr(self._client, name)
        if not callable(method) or name.startswith("_"):
            return method

        async def call(*args: Any, **kwargs: Any) -> Any:
            return await asyncio.to_thread(method, *args, **kwargs)
        call.__doc__ = method.__doc__
        return call

    async def watch(self, scene_id: str, **kwargs: Any):  # type: ignore[override]
        import asyncio  # pylint: disable=import-outside-toplevel
        events = self._client.watch(scene_id, **kwargs)
        done = object()
        try:
            while True:
                event = await asyncio.to_thread(next, events, done)
                if event is done:
                    return
                yield event
        finally:
            events.close()
