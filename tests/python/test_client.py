"""The Python client (client/python) against a real gvd-server on loopback, over gRPC and over
HTTP: answers checked against an exact double-precision oracle (NumPy brute force), errors
carrying the server's code and message.

Run: GVD_SERVER=build/test/server/gvd-server python3 -m pytest tests/python (with the
package installed: pip install --no-build-isolation client/python in a venv made with
--system-site-packages). The server and client fixtures are conftest.py's.
"""
import os
import sys

import grpc
import numpy as np
import pytest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import gvd  # noqa: E402
from gvd.v1 import voronoi_pb2  # noqa: E402
from gvdtest import Server  # noqa: E402

from conftest import SERVER  # noqa: E402


def brute_nearest(sites, q):
    """The exact nearest site of each query point: every distance in double precision."""
    dx, dy = q[:, None, 0] - sites[None, :, 0], q[:, None, 1] - sites[None, :, 1]
    d = np.sqrt(dx * dx + dy * dy)
    return d.argmin(axis=1), d.min(axis=1)


def random_scene(client, sid, n, size, seed, prefix):
    """A scene over the unit square of n random points named prefix0, prefix1, ...:
    (the random generator, the points, their ids, the version that holds them)."""
    client.create_scene(sid, window=(0, 0, 1, 1), size=(size, size))
    rng = np.random.default_rng(seed)
    xy = rng.random((n, 2))
    ids = [f"{prefix}{i}" for i in range(n)]
    return rng, xy, ids, client.upsert_points(sid, ids, xy)


def test_points_in_nearest_out(client):
    sid = f"points-{client.kind}"
    rng, xy, ids, v = random_scene(client, sid, 500, 256, 7, "p")
    q = np.vstack([rng.random((20_000, 2)), xy[:50], [[0.5, 1.5], [-3, -3]]])  # on sites, outside
    steps = []
    r = client.find_nearest(sid, q, min_version=v, exact=True,
                            progress=lambda done, n: steps.append((done, n)))
    best, dist = brute_nearest(xy, q)
    assert r.version >= v and len(r) == len(q)
    assert r.exact.all()
    assert np.array_equal(r.distances, dist)  # exact answers: bitwise equal
    # Ties aside, the nearest site is the oracle's; with a tie, one at the same distance.
    named = np.array([ids.index(s) for s in r.site_ids])
    dx, dy = (xy[named] - q).T
    assert np.array_equal(np.sqrt(dx * dx + dy * dy), dist)
    assert steps[-1] == (len(q), len(q)) and all(a[0] < b[0] for a, b in zip(steps, steps[1:]))
    raster = client.find_nearest(sid, q, min_version=v)
    assert (raster.distances - raster.error_bounds <= dist + 1e-12).all()


def test_points_are_stored_as_given_whatever_their_ids(client):
    # upsert_points writes a call of up to FEW_SITES points a site at a time, and more with
    # NumPy's steps; a call with an id too long for either goes as protobuf's messages.
    # Each way the server holds each id at its point.
    sid = f"ids-{client.kind}"
    client.create_scene(sid, window=(-1, -1, 1, 1), size=(64, 64))
    rng = np.random.default_rng(5)
    ids = [f"pt-{i}-é漢" for i in range(300)] + ["L" * 200 + str(i) for i in range(3)]
    xy = rng.random((len(ids), 2)) * 2 - 1
    # Omitted by protobuf's writer, written by the arrays': in each kind of call.
    xy[0, 0] = xy[291, 1] = xy[299, 0] = xy[301, 1] = 0.0
    v = client.upsert_points(sid, ids[:291], xy[:291])
    for few in (slice(291, 292), slice(292, 300), slice(300, 303)):
        assert client.upsert_points(sid, ids[few], xy[few]) > v
    listed = {s["id"]: s["point"] for s in client.list_sites(sid)}
    assert sorted(listed) == sorted(ids)
    got = np.array([[listed[i].get("x", 0.0), listed[i].get("y", 0.0)] for i in ids])
    assert np.array_equal(got, xy)
    client.delete_scene(sid)


def test_segments_are_stored_as_given_whatever_their_ids(client):
    # upsert_segments writes its request from the arrays, as upsert_points does, and an id
    # too long for that goes as protobuf's messages; either way each id holds its segment,
    # and a read at the version finds each segment where it lies.
    sid = f"segs-{client.kind}"
    client.create_scene(sid, window=(-1, -1, 1, 1), size=(64, 64))
    rng = np.random.default_rng(6)
    ids = [f"sg-{i}-é漢" for i in range(200)] + ["L" * 100 + str(i) for i in range(3)]
    ab = rng.random((len(ids), 2, 2)) * 2 - 1
    # Omitted by protobuf's writer, written by the arrays': in each kind of call.
    ab[0, 0, 0] = ab[198, 0, 1] = ab[201, 1, 1] = 0.0
    v = client.upsert_segments(sid, ids[:197], ab[:197])
    v = client.upsert_segments(sid, ids[197:200], ab[197:200])  # a few: protobuf's messages
    v = client.upsert_segments(sid, ids[200:], ab[200:])
    listed = {s["id"]: s["segment"] for s in client.list_sites(sid)}
    assert sorted(listed) == sorted(ids)
    got = np.array([[[listed[i][end].get(c, 0.0) for c in "xy"] for end in "ab"] for i in ids])
    assert np.array_equal(got, ab)
    # The midpoint of each segment is on it: distance 0, within the answer's bound.
    r = client.find_nearest(sid, ab.mean(axis=1), min_version=v, exact=True)
    assert (r.distances <= 1e-12).all()
    with pytest.raises(ValueError, match=r"\(n, 2, 2\)"):
        client.upsert_segments(sid, ids[:1], ab[:1, 0])
    client.delete_scene(sid)


@pytest.mark.parametrize("dims", [2, 3])
def test_calls_of_a_few_points_with_closest_points(client, dims):
    # What a UI sends: one to three points a call, exact, with each answer's closest point
    # and gradient; in a plane and in a volume. A point site's closest point is the site.
    sid = f"few-{dims}-{client.kind}"
    if dims == 2:
        client.create_scene(sid, window=(0, 0, 1, 1), size=(128, 128))
    else:
        client.create_scene(sid, window=(0, 0, 0, 1, 1, 1), size=(32, 32, 32))
    rng = np.random.default_rng(dims)
    sites = rng.random((300, dims))
    ids = [f"f{i}" for i in range(len(sites))]
    v = client.upsert_points(sid, ids, sites)
    for k in range(60):
        q = rng.random((1 + k % 3, dims))
        r = client.find_nearest(sid, q, min_version=v, exact=True, closest=True)
        d = np.sqrt(((q[:, None, :] - sites[None, :, :]) ** 2).sum(axis=2)).min(axis=1)
        assert r.version >= v and r.exact.all() and np.array_equal(r.distances, d)
        named = sites[[ids.index(s) for s in r.site_ids]]
        assert r.closest.shape == (len(q), dims) and np.array_equal(r.closest, named)
        assert np.allclose(r.gradient, (q - named) / d[:, None], rtol=0, atol=1e-12)
        assert [r.ids[i] for i in r.site_indices] == r.site_ids.tolist()
        assert (r.error_bounds == 0).all() and (r.feature_indices == 0).all()
    # A drag: one site moved at a time, each read at its version where it now lies.
    for _ in range(5):
        i, to = int(rng.integers(len(sites))), rng.random((1, dims))
        v = client.upsert_points(sid, [ids[i]], to)
        r = client.find_nearest(sid, to, min_version=v, exact=True)
        assert r.site_ids.tolist() == [ids[i]] and r.distances.tolist() == [0.0]
    client.delete_scene(sid)


def test_a_batch_in_one_call_in_a_stream_and_in_several_calls(client, monkeypatch):
    # 140,000 points: one call's message without progress, FindNearestStream's three chunks
    # with it, three calls when a call takes 50,000. The points go left to right, so that
    # each chunk and call names sites of its own and some of the one before, which the
    # result names once each.
    sid = f"ways-{client.kind}"
    rng, xy, ids, v = random_scene(client, sid, 500, 256, 31, "w")
    q = rng.random((140_000, 2))
    q = q[np.argsort(q[:, 0])]
    best = np.concatenate([brute_nearest(xy, q[lo:lo + 20_000])[1]
                           for lo in range(0, len(q), 20_000)])
    steps = []
    results = [client.find_nearest(sid, q, min_version=v),
               client.find_nearest(sid, q, min_version=v,
                                   progress=lambda done, n: steps.append(done))]
    monkeypatch.setattr(gvd._client, "MAX_POINTS_PER_CALL", 50_000)
    results.append(client.find_nearest(sid, q, min_version=v))
    assert steps == [65_536, 131_072, 140_000]
    for r in results:
        assert len(r) == len(q) and r.version >= v
        assert len(set(r.ids)) == len(r.ids) and (r.site_indices >= 0).all()
        assert r.site_ids.tolist() == [r.ids[i] for i in r.site_indices]
        d, bound = r.distances, r.error_bounds
        assert (d - bound <= best + 1e-12).all() and (best <= d + 1e-12).all()
        # The site named is the one whose distance was reported.
        named = xy[[int(s[1:]) for s in r.site_ids]]
        assert np.allclose(np.hypot(*(named - q).T), d, rtol=0, atol=1e-12)
        assert r.site_ids.tolist() == results[0].site_ids.tolist()
    client.delete_scene(sid)


def test_a_million_points_with_progress(client):
    sid = f"million-{client.kind}"
    rng, xy, _, v = random_scene(client, sid, 60, 512, 23, "m")
    q = rng.random((1_000_000, 2))
    steps = []
    r = client.find_nearest(sid, q, min_version=v, progress=lambda done, n: steps.append((done, n)))
    assert len(r) == len(q) and r.version >= v
    assert len(steps) >= 10 and steps[-1] == (len(q), len(q))
    assert all(a[0] < b[0] for a, b in zip(steps, steps[1:]))
    # Every raster answer within its bound of the exact distance, chunk by chunk.
    for lo in range(0, len(q), 100_000):
        _, dist = brute_nearest(xy, q[lo:lo + 100_000])
        d, bound = r.distances[lo:lo + 100_000], r.error_bounds[lo:lo + 100_000]
        assert (d - bound <= dist + 1e-12).all() and (dist <= d + 1e-12).all()
    client.delete_scene(sid)


def test_errors_carry_the_servers_code_and_message(client):
    with pytest.raises(gvd.GvdError) as e:
        client.get_scene(f"missing-{client.kind}")
    assert e.value.code == grpc.StatusCode.NOT_FOUND
    assert f"missing-{client.kind}" in e.value.message
    with pytest.raises(gvd.GvdError) as e:
        client.create_scene("has spaces", window=(0, 0, 1, 1), size=(16, 16))
    assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT
    with pytest.raises(ValueError):
        client.find_nearest("any", np.zeros((3, 4)))


def test_sites_of_every_kind_and_pick(client):
    sid = f"kinds-{client.kind}"
    client.create_scene(sid, window=(0, 0, 10, 10), size=(128, 128))
    v = client.upsert_sites(sid, [
        {"id": "pt", "type": "Point", "coordinates": [1, 1]},
        {"id": "seg", "type": "LineString", "coordinates": [[5, 0], [5, 4]]},
        {"id": "poly", "type": "Polygon", "coordinates": [[[7, 7], [9, 7], [9, 9], [7, 7]]]},
        {"id": "json", "segment": {"a": {"x": 0, "y": 9}, "b": {"x": 2, "y": 9}}},
        # A polygon with a hole: one path site of two closed rings, even-odd.
        {"id": "holed", "type": "Polygon", "coordinates": [[[1, 4], [4, 4], [4, 7], [1, 7], [1, 4]],
                                                          [[2, 5], [3, 5], [3, 6], [2, 6], [2, 5]]]},
    ])
    listed = {s["id"]: s for s in client.list_sites(sid)}
    assert set(listed) == {"pt", "seg", "poly", "json", "holed"}
    assert listed["seg"]["segment"]["b"] == {"x": 5.0, "y": 4.0}
    holed = listed["holed"]["path"]
    assert holed["fillRule"] == "FILL_RULE_EVEN_ODD"
    assert [len(s["points"]) for s in holed["subpaths"]] == [5, 5]  # each ring and its closing line
    assert all(s["closed"] and s["degrees"] == [1] * 4 for s in holed["subpaths"])
    picked = client.pick(sid, 5.5, 2)
    assert picked.found and picked.site_id == "seg" and picked.distance == 0.5
    # In the hole, 0.25 from its left side: the hole's closing line, piece 7 (pieces 0-3 are
    # the outer ring's).
    picked = client.pick(sid, 2.25, 5.5)
    assert picked.found and picked.site_id == "holed" and picked.distance == 0.25
    assert picked.feature_kind == voronoi_pb2.FEATURE_KIND_EDGE and picked.feature_index == 7
    v2 = client.delete_sites(sid, ["pt"])
    assert v2 == v + 1
    assert {s["id"] for s in client.list_sites(sid)} == {"seg", "poly", "json", "holed"}


def test_relaxed_writes_are_seen_at_once(client):
    """A RELAXED move is answered and queried like a SYNC one (over gRPC and over HTTP/JSON,
    where the enum goes by name); a durability the API does not have is refused here."""
    sid = f"relaxed-{client.kind}"
    rng, xy, ids, v = random_scene(client, sid, 200, 128, 31, "r")
    for k in range(20):
        to = rng.random((1, 2))
        v = client.upsert_points(sid, ["r0"], to, durability="relaxed")
        xy[0] = to[0]
        q = np.vstack([to, rng.random((50, 2))])
        r = client.find_nearest(sid, q, min_version=v, exact=True)
        best, dist = brute_nearest(xy, q)
        assert np.array_equal(r.distances, dist)
        assert r.site_ids[0] == "r0"
    v2 = client.delete_sites(sid, ["r1"], durability="relaxed")
    assert v2 == v + 1
    assert len(client.list_sites(sid)) == 199
    with pytest.raises(ValueError, match="durability"):
        client.upsert_points(sid, ["r0"], xy[:1], durability="fast")
    client.delete_scene(sid)


def test_watch_sees_a_write_and_the_deletion(client):
    sid = f"watched-{client.kind}"
    client.create_scene(sid, window=(0, 0, 1, 1), size=(32, 32))
    v = client.upsert_points(sid, ["a"], [[0.5, 0.5]])
    events = client.watch(sid, timeout=60)
    assert any(e.version >= v for e in events)  # the frames up to the write's
    client.delete_scene(sid)
    last = list(events)[-1]
    assert last.deleted


def test_render_window_is_the_diagram_within_its_error_bound(client):
    sid = f"raster-{client.kind}"
    _, xy, ids, v = random_scene(client, sid, 40, 64, 11, "s")
    r = client.render_window(sid, window=(0.25, 0.25, 0.75, 0.5), size=(50, 25), min_version=v)
    assert r.version >= v and r.site_indices.shape == (25, 50) == r.distances.shape
    # Pixel centres, row 0 at the bottom.
    cx = 0.25 + (np.arange(50) + 0.5) * 0.5 / 50
    cy = 0.25 + (np.arange(25) + 0.5) * 0.25 / 25
    q = np.stack(np.meshgrid(cx, cy), axis=-1).reshape(-1, 2)
    _, dist = brute_nearest(xy, q)
    named = np.array([ids.index(r.ids[i]) for i in r.site_indices.ravel()])
    dx, dy = (xy[named] - q).T
    own = np.sqrt(dx * dx + dy * dy)
    slack = r.max_error + 1e-6 * (1 + dist)  # the meshes' bound, and float32 storage
    assert (own <= dist + 2 * slack).all()  # the pixel names a site within the bound
    assert (np.abs(r.distances.ravel() - dist) <= slack).all()
    image = client.render_image(sid)  # the scene's own frame, row 0 at the top
    whole = client.render_window(sid)
    assert np.array_equal(image, whole.distances[::-1])


def test_async_client_under_100_concurrent_calls(server):
    import asyncio

    async def run(target):
        async with gvd.AsyncClient(target) as c:
            sid = "async-" + ("http" if target.startswith("http") else "grpc")
            await c.create_scene(sid, window=(0, 0, 1, 1), size=(64, 64))
            rng = np.random.default_rng(5)
            xy = rng.random((100, 2))
            v = await c.upsert_points(sid, [f"a{i}" for i in range(100)], xy)
            queries = [rng.random((50, 2)) for _ in range(100)]
            answers = await asyncio.gather(*(c.find_nearest(sid, q, min_version=v, exact=True)
                                             for q in queries))
            for q, r in zip(queries, answers):
                _, dist = brute_nearest(xy, q)
                assert np.array_equal(r.distances, dist)
            events = c.watch(sid, timeout=60)
            first = await events.__anext__()
            assert first.scene_id == sid
            await events.aclose()

    for target in server.targets.values():
        asyncio.run(run(target))


def test_plan_path_keeps_its_clearance(client):
    sid = f"plan-{client.kind}"
    client.create_scene(sid, window=(0, 0, 10, 10), size=(128, 128))
    v = client.upsert_sites(sid, [
        {"id": "wall", "type": "LineString", "coordinates": [[5, 0], [5, 7]]},
        {"id": "post", "type": "Point", "coordinates": [2, 8]},
    ])
    path = client.plan_path(sid, (1, 1), (9, 1), robot_radius=0.5, min_version=v)
    assert path.points.shape[1] == 2 and len(path.points) >= 2
    assert np.allclose(path.points[0], (1, 1)) and np.allclose(path.points[-1], (9, 1))
    assert path.min_clearance >= 0.5
    assert path.points[:, 1].max() > 7  # around the wall's end


def empty_circle_triangles(xy, ids):
    """The Delaunay triangles of points in general position by brute force: every triple
    whose circumcircle holds no other point, with its circumcentre."""
    n = len(xy)
    out = {}
    for i in range(n):
        for j in range(i + 1, n):
            for k in range(j + 1, n):
                (ax, ay), (bx, by), (cx, cy) = xy[i], xy[j], xy[k]
                d = 2 * (ax * (by - cy) + bx * (cy - ay) + cx * (ay - by))
                if abs(d) < 1e-12:
                    continue
                ux = ((ax * ax + ay * ay) * (by - cy) + (bx * bx + by * by) * (cy - ay)
                      + (cx * cx + cy * cy) * (ay - by)) / d
                uy = ((ax * ax + ay * ay) * (cx - bx) + (bx * bx + by * by) * (ax - cx)
                      + (cx * cx + cy * cy) * (bx - ax)) / d
                r2 = (ax - ux) ** 2 + (ay - uy) ** 2
                inside = ((xy[:, 0] - ux) ** 2 + (xy[:, 1] - uy) ** 2) < r2 * (1 - 1e-9)
                inside[[i, j, k]] = False
                if not inside.any():
                    out[frozenset((ids[i], ids[j], ids[k]))] = (ux, uy)
    return out


def test_structure_calls_against_brute_force(client):
    sid = f"structure-{client.kind}"
    _, xy, ids, v = random_scene(client, sid, 30, 256, 17, "d")
    assert sid in [s.scene_id for s in client.list_scenes()]
    truth = empty_circle_triangles(xy, ids)
    px = 1 / 256
    delaunay = client.get_delaunay(sid, min_version=v)
    triangles = {frozenset((t.a, t.b, t.c)) for t in delaunay.triangles}
    # The server's are those whose Voronoi edges cross the window: every triangle whose
    # circumcentre (where its three Voronoi edges meet) is inside it, and no other kind.
    assert triangles <= set(truth)
    assert {t for t, (ux, uy) in truth.items()
            if 2 * px < ux < 1 - 2 * px and 2 * px < uy < 1 - 2 * px} <= triangles
    edges = {frozenset(e) for t in truth for e in
             ((a, b) for a in t for b in t if a < b)}
    assert {frozenset((e.site_a, e.site_b)) for e in delaunay.edges} <= edges
    # Voronoi neighbours within the window are Delaunay edges.
    neighbours = {frozenset((p.site_a, p.site_b)) for p in
                  client.get_neighbors(sid, min_version=v).pairs}
    assert neighbours <= edges and len(neighbours) >= len(edges) * 0.7
    # Boundary points are equidistant from their two sites, and no site is nearer, within
    # two of the scene's pixels.
    where = dict(zip(ids, xy))
    boundaries = client.get_boundaries(sid, min_version=v).boundaries
    assert boundaries
    for b in boundaries:
        pts = np.array(b.xy).reshape(-1, 2)
        da = np.hypot(*(pts - where[b.site_a]).T)
        db = np.hypot(*(pts - where[b.site_b]).T)
        nearest = np.sqrt(((pts[:, None, :] - xy[None, :, :]) ** 2).sum(axis=2)).min(axis=1)
        assert np.abs(da - db).max() <= 2 * px, (b.site_a, b.site_b)
        assert (np.minimum(da, db) - nearest).max() <= 2 * px
    # Clearance samples at the cells' centres: the distance to the nearest site.
    field = client.get_clearance_field(sid, window=(0, 0, 1, 1), size=(40, 30), min_version=v)
    assert (field.width_px, field.height_px) == (40, 30)
    centres = np.stack(np.meshgrid((np.arange(40) + 0.5) / 40, (np.arange(30) + 0.5) / 30),
                       axis=-1).reshape(-1, 2)
    exact = np.sqrt(((centres[:, None, :] - xy[None, :, :]) ** 2).sum(axis=2)).min(axis=1)
    # A proven lower bound, within the meshes' error of the distance (float32 rounding aside):
    # a pixel of the field, as the scene's is one of its own (max_error 1/256 here).
    assert client.get_scene(sid).max_error == px
    clearance = np.array(field.clearance)
    assert (clearance <= exact * (1 + 1e-6)).all()
    assert (exact - clearance).max() <= 1 / 30


def test_mosaic_tiles_are_the_nearest_sites_regions(client):
    """A mosaic of a random-noise PPM: each pixel the input's colour under the site nearest to
    its centre (brute force; near-ties skipped), over both transports."""
    rng = np.random.default_rng(4)
    h, w = 40, 60
    pixels = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    image = b"P6\n%d %d\n255\n" % (w, h) + pixels.tobytes()
    r = client.render_mosaic(image, tiles=30, seed=7, format="pnm")
    assert (r.width_px, r.height_px, r.mime_type) == (w, h, "image/x-portable-anymap")
    header = b"P6\n%d %d\n255\n" % (w, h)
    assert r.image.startswith(header)
    out = np.frombuffer(r.image[len(header):], dtype=np.uint8).reshape(h, w, 3)
    sites = np.array([(p.x, p.y) for p in r.sites])
    assert len(sites) == 30
    jj, ii = np.mgrid[0:h, 0:w]
    centres = np.stack([ii.ravel() + 0.5, jj.ravel() + 0.5], axis=1)
    d = np.hypot(centres[:, None, 0] - sites[None, :, 0], centres[:, None, 1] - sites[None, :, 1])
    order = np.sort(d, axis=1)
    clear = order[:, 1] - order[:, 0] > 1e-6
    nearest = d.argmin(axis=1)
    under = pixels[np.minimum(sites[:, 1].astype(int), h - 1), np.minimum(sites[:, 0].astype(int), w - 1)]
    expected = under[nearest].reshape(h, w, 3)
    assert clear.mean() > 0.99
    assert np.array_equal(out.reshape(-1, 3)[clear], expected.reshape(-1, 3)[clear])
    with pytest.raises(gvd.GvdError) as e:
        client.render_mosaic(b"GIF89a", tiles=3)
    assert e.value.code == grpc.StatusCode.INVALID_ARGUMENT and "image is a damaged gif" in e.value.message


def test_no_points_no_call(client):
    r = client.find_nearest("not-even-there", np.zeros((0, 2)))
    assert len(r) == 0 and r.version == 0


@pytest.mark.parametrize("kind", ["grpc", "http"])
def test_tokens_refused_by_code_and_message(kind, tmp_path):
    write, read = "w" * 20 + "-writer", "r" * 20 + "-reader"
    tokens = tmp_path / "tokens"
    tokens.write_text(f"{write} write\n{read} read\n")
    s = Server(SERVER, "--tokens", str(tokens))
    try:
        with open(os.path.join(s.dir, "ports")) as f:
            target = {"grpc": f"127.0.0.1:{int(f.read().split()[0])}", "http": s.url}[kind]
        with gvd.Client(target, token=write) as c:
            c.create_scene("guarded", window=(0, 0, 1, 1), size=(16, 16))
        for token, code, named in ((None, grpc.StatusCode.UNAUTHENTICATED, "bearer token"),
                                   ("x" * 20, grpc.StatusCode.UNAUTHENTICATED, "unknown"),
                                   (read, grpc.StatusCode.PERMISSION_DENIED, "may read")):
            with gvd.Client(target, token=token) as c:
                with pytest.raises(gvd.GvdError) as e:
                    c.upsert_points("guarded", ["a"], [[0.5, 0.5]])
                assert e.value.code == code, e.value
                assert named in e.value.message
        with gvd.Client(target, token=read) as c:
            assert c.get_scene("guarded").version == 1
    finally:
        s.stop()
