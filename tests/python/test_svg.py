"""gvd.sites_from_svg against a real server: SVG shapes in, answers within their bounds of
the true shapes out. The oracles are apart from the reader and the server: circles and
ellipses measured in closed form (and by the oracle's own root finding), the shapes of real
files (Debian's libwacom-common and gdal-data) sampled through svgelements' own evaluation
of each segment, with a proven bound on what the samples miss."""
import math
import os

import grpc
import numpy as np
import pytest
import svgelements as se

import gvd
from gvd.v1 import voronoi_pb2

# Tablet layouts (paths with arcs and curves, circles, rects, transforms) and logos (polygons,
# paths, a viewBox), from Debian packages the tests install.
REAL_FILES = ["/usr/share/libwacom/layouts/ek-remote.svg",
              "/usr/share/libwacom/layouts/mobilestudio-pro-16.svg",
              "/usr/share/gdal/GDALLogoColor.svg"]


def write(tmp_path, name, body, head='width="100" height="100"'):
    path = tmp_path / name
    path.write_text(f'<svg xmlns="http://www.w3.org/2000/svg" '
                    f'xmlns:xlink="http://www.w3.org/1999/xlink" {head}>{body}</svg>')
    return str(path)


def ellipse_distance(q, c, rx, ry, angle):
    """Distance from points q (m, 2) to the ellipse of centre c, radii rx, ry, turned by
    `angle` radians: in its frame, the least of |q - (rx cos t, ry sin t)| over t, from 4096
    samples refined by Newton's method on the derivative, each root kept within its bracket."""
    cos, sin = math.cos(angle), math.sin(angle)
    x = (q[:, 0] - c[0]) * cos + (q[:, 1] - c[1]) * sin
    y = -(q[:, 0] - c[0]) * sin + (q[:, 1] - c[1]) * cos
    t = np.linspace(0, 2 * np.pi, 4097)[:-1]
    d2 = (x[:, None] - rx * np.cos(t)) ** 2 + (y[:, None] - ry * np.sin(t)) ** 2
    best = t[d2.argmin(axis=1)]
    h = 2 * np.pi / 4096
    for _ in range(40):
        f = (rx * rx - ry * ry) * np.sin(best) * np.cos(best) - x * rx * np.sin(best) + y * ry * np.cos(best)
        df = (rx * rx - ry * ry) * np.cos(2 * best) - x * rx * np.cos(best) - y * ry * np.sin(best)
        step = np.where(df != 0, f / np.where(df != 0, df, 1), 0)
        best = best - np.clip(step, -h, h)
    return np.hypot(x - rx * np.cos(best), y - ry * np.sin(best))


def check_within_bounds(client, sid, q, truth, exact):
    r = client.find_nearest(sid, q, exact=exact)
    err = np.abs(r.distances - truth)
    bad = np.flatnonzero(err > r.error_bounds)
    assert bad.size == 0, (f"{bad.size} of {len(q)} answers (exact={exact}) outside their bound, "
                           f"e.g. at {q[bad[0]]}: {r.distances[bad[0]]!r} bound {r.error_bounds[bad[0]]!r}, "
                           f"true {truth[bad[0]]!r}")
    return r


def test_circles_and_ellipses_within_their_bound_of_the_true_curve(client, tmp_path):
    """Arcs become cubics; the answers' bounds must cover how far those are from the true
    circles and ellipses, in exact answers too (which measure the cubics to a few ulps)."""
    rng = np.random.default_rng(5)
    shapes, body = [], ""
    for i in range(6):
        cx, cy = rng.uniform(15, 85, 2)
        if i % 2 == 0:
            r = rng.uniform(3, 14)
            body += f'<circle cx="{cx!r}" cy="{cy!r}" r="{r!r}"/>'
            shapes.append((cx, cy, r, r, 0.0))
        else:
            rx, ry, deg = rng.uniform(3, 14), rng.uniform(1, 6), rng.uniform(0, 180)
            body += (f'<ellipse cx="{cx!r}" cy="{cy!r}" rx="{rx!r}" ry="{ry!r}" '
                     f'transform="rotate({deg!r} {cx!r} {cy!r})"/>')
            shapes.append((cx, cy, rx, ry, math.radians(deg)))
    sites = gvd.sites_from_svg(write(tmp_path, "round.svg", body))
    assert [s["id"] for s in sites] == ["circle-0", "ellipse-0", "circle-1", "ellipse-1",
                                        "circle-2", "ellipse-2"]
    for s in sites:
        assert 0 < s["path"]["approximation_error"] < 1e-4
    q = rng.uniform(0, 100, (3000, 2))
    truth = np.min([ellipse_distance(q, (cx, cy), rx, ry, a) for cx, cy, rx, ry, a in shapes], axis=0)
    for mode in (voronoi_pb2.RENDER_MODE_MESH, voronoi_pb2.RENDER_MODE_EXACT):
        sid = f"round-{mode}-{client.kind}"
        client.create_scene(sid, window=(0, 0, 100, 100), size=(256, 256), render_mode=mode)
        client.upsert_sites(sid, sites)
        check_within_bounds(client, sid, q, truth, exact=False)
        r = check_within_bounds(client, sid, q, truth, exact=True)
        assert r.exact.all()
        # The bound is the cubics' stated distance from the curves, not a loose one.
        assert np.median(r.error_bounds) < 1e-4
        client.delete_scene(sid)


def sampled(element, per_segment=512):
    """Points on each segment of an element (in svgelements' own coordinates), and a bound on
    how far the segment strays from the polyline through them: a curve's distance from a
    chord between parameters t and t + h is at most h^2/8 times its largest second
    derivative, bounded from its control points (an arc: the sweep squared times its
    ellipse's largest radius)."""
    t = np.linspace(0, 1, per_segment + 1)
    polylines, stray = [], 0.0
    for seg in se.Path(element).segments(transformed=True):
        if isinstance(seg, se.Move) or seg.start is None or seg.end is None:
            continue
        if isinstance(seg, (se.Line, se.Close)):
            polylines.append(np.array([[seg.start.x, seg.start.y], [seg.end.x, seg.end.y]]))
            continue
        pts = seg.npoint(t)
        if isinstance(seg, se.Arc):
            # |P''| = sweep^2 |U cos t + V sin t| <= sweep^2 (|U|^2 + |V|^2)^(1/2).
            radius = math.hypot(math.dist(seg.prx, seg.center), math.dist(seg.pry, seg.center))
            second = seg.sweep ** 2 * radius
        else:
            c = np.array([[p.x, p.y] for p in ([seg.start, seg.control, seg.end]
                                                if isinstance(seg, se.QuadraticBezier) else
                                                [seg.start, seg.control1, seg.control2, seg.end])])
            n = len(c) - 1
            second = n * (n - 1) * max(np.hypot(*(c[k + 2] - 2 * c[k + 1] + c[k])) for k in range(n - 1))
        stray = max(stray, second / (8 * per_segment ** 2))
        polylines.append(pts)
    return polylines, stray


def polyline_distance(q, pts):
    a, b = pts[:-1], pts[1:]
    ab = b - a
    length2 = np.maximum((ab ** 2).sum(axis=1), 1e-300)
    t = np.clip(((q[:, None, :] - a[None]) * ab[None]).sum(axis=2) / length2[None], 0, 1)
    nearest = a[None] + t[..., None] * ab[None]
    return np.sqrt(((q[:, None, :] - nearest) ** 2).sum(axis=2)).min(axis=1)


@pytest.mark.parametrize("name", REAL_FILES)
def test_real_files_answer_within_their_bound(client, name):
    """Every drawn element of a real file is a site the server takes; every answer is within
    its bound of the nearest true shape, sampled independently through svgelements."""
    sites = gvd.sites_from_svg(name)
    svg = se.SVG.parse(name)
    elements = [e for e in svg.elements() if isinstance(e, se.Shape)
                and any(not isinstance(s, (se.Move, se.Close)) for s in se.Path(e).segments())]
    assert len(sites) == len(elements) and len({s["id"] for s in sites}) == len(sites)
    # The reader's coordinates are user units; svgelements' the viewport's px.
    user = ~se.Matrix(svg.viewbox.transform(svg)) if svg.viewbox is not None else se.Matrix()
    lo = np.full(2, np.inf)
    hi = -lo
    shapes = []
    for e in elements:
        polylines, stray = sampled(e * user)
        shapes.append((polylines, stray))
        for p in polylines:
            lo, hi = np.minimum(lo, p.min(axis=0)), np.maximum(hi, p.max(axis=0))
    pad = 0.05 * (hi - lo).max()
    window = (lo[0] - pad, lo[1] - pad, hi[0] + pad, hi[1] + pad)
    sid = f"real-{os.path.basename(name)}-{client.kind}"
    client.create_scene(sid, window=window, size=(512, 512))
    client.upsert_sites(sid, sites)
    rng = np.random.default_rng(9)
    q = rng.uniform(window[:2], window[2:], (2000, 2))
    # upper: to the sample points, which are on the shapes; lower: to the polylines, less what
    # they miss. A polyline's box is no farther than any of its points: where that, less its
    # stray, is past a distance to some shape's endpoint, the polyline can lower neither, and
    # its box distance less the stray stands in for its lower bound.
    pieces = [(p, stray) for polylines, stray in shapes for p in polylines]
    ends = np.array([p[k] for p, _ in pieces for k in (0, -1)])
    upper = np.sqrt(((q[:, None, :] - ends[None]) ** 2).sum(axis=2)).min(axis=1)
    lower = np.full(len(q), np.inf)
    for p, stray in pieces:
        box = np.hypot(*np.maximum(np.maximum(p.min(axis=0) - q, q - p.max(axis=0)), 0).T)
        near = box - stray < upper
        lower[~near] = np.minimum(lower[~near], box[~near] - stray)
        qn = q[near]
        lower[near] = np.minimum(lower[near], polyline_distance(qn, p) - stray)
        vertex = np.sqrt(((qn[:, None, :] - p[None]) ** 2).sum(axis=2)).min(axis=1)
        upper[near] = np.minimum(upper[near], vertex)
    for exact in (False, True):
        r = client.find_nearest(sid, q, exact=exact)
        slack = 1e-9 * (hi - lo).max()
        bad = np.flatnonzero((r.distances - r.error_bounds > upper + slack) |
                             (r.distances + r.error_bounds < lower - slack))
        assert bad.size == 0, (f"{name}: {bad.size} answers outside their bound, e.g. at {q[bad[0]]}: "
                               f"{r.distances[bad[0]]} +- {r.error_bounds[bad[0]]}, true in "
                               f"[{lower[bad[0]]}, {upper[bad[0]]}]")
    client.delete_scene(sid)


def test_ids_use_instances_transforms_and_upright(tmp_path):
    name = write(tmp_path, "ids.svg", '''
      <defs><rect id="key" width="2" height="1"/></defs>
      <g transform="translate(10 20) scale(2)">
        <path id="p" d="M0 0 h4 v2 z M 1 0.5 h1"/>
        <path d="M 5 5"/>
        <use xlink:href="#key" x="3"/>
        <use href="#key" y="3"/>
        <line x1="0" y1="0" x2="1" y2="0"/>
      </g>
      <circle id="p" cx="1" cy="1" r="1"/>
      <rect x="0" y="90" width="10" height="10" style="fill-rule: evenodd"/>
      <text x="0" y="0">not a site</text>''', head='width="200mm" height="100mm" viewBox="0 0 100 50"')
    sites = gvd.sites_from_svg(name)
    ids = [s["id"] for s in sites]
    # The path of moves only is no site and takes no index; the second "p" and each "key"
    # instance after the first get a suffix; the instances are drawn rects 0 and 1.
    assert ids == ["p", "key", "key~2", "line-0", "p~2", "rect-2"]
    p = sites[0]["path"]
    # User units (the viewBox's, not the 200 mm viewport's px), transforms applied.
    assert p["subpaths"][0]["points"][:3] == [{"x": 10, "y": 20}, {"x": 18, "y": 20}, {"x": 18, "y": 24}]
    assert [s["closed"] for s in p["subpaths"]] == [True, False]
    assert p["subpaths"][1]["degrees"] == [1] and p["fill_rule"] == "FILL_RULE_NONZERO"
    assert "approximation_error" not in p  # lines only
    assert sites[1]["path"]["subpaths"][0]["points"][0] == {"x": 16, "y": 20}
    assert sites[2]["path"]["subpaths"][0]["points"][0] == {"x": 10, "y": 26}
    assert sites[5]["path"]["fill_rule"] == "FILL_RULE_EVEN_ODD"
    upright = gvd.sites_from_svg(name, upright=True)
    assert upright[0]["path"]["subpaths"][0]["points"][0] == {"x": 10, "y": 30}  # 50 - 20


def test_unreadable_files_are_refused_by_name(tmp_path):
    cases = {
        "broken.svg": ("<svg xmlns='http://www.w3.org/2000/svg'><path d='M0 0 L1 1'", "broken.svg"),
        "laughs.svg": ('<?xml version="1.0"?><!DOCTYPE svg [<!ENTITY a "aaaaaaaaaa">'
                       '<!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;"><!ENTITY c "&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;">'
                       ']><svg xmlns="http://www.w3.org/2000/svg"><text>&c;</text></svg>', "laughs.svg"),
        "huge.svg": ("<svg xmlns='http://www.w3.org/2000/svg'><path id='far' d='M0 0 L1e400 0'/></svg>",
                     '<path id="far">'),
        "html.svg": ("<html><body/></html>", "html.svg"),
    }
    for file, (text, named) in cases.items():
        (tmp_path / file).write_text(text)
        with pytest.raises(ValueError) as e:
            gvd.sites_from_svg(str(tmp_path / file))
        assert named in str(e.value), str(e.value)
    with pytest.raises(ValueError, match="max_bytes"):
        gvd.sites_from_svg(str(tmp_path / "broken.svg"), max_bytes=10)
    with pytest.raises(ValueError, match="missing.svg"):
        gvd.sites_from_svg(str(tmp_path / "missing.svg"))


def test_a_site_past_the_servers_limit_is_refused_by_it(client, tmp_path):
    points = " ".join(f"{i % 100},{i // 100 % 100}" for i in range(100_001))
    sites = gvd.sites_from_svg(write(tmp_path, "long.svg", f'<polyline points="{points}"/>'))
    sid = f"long-{client.kind}"
    client.create_scene(sid, window=(0, 0, 100, 100), size=(64, 64))
    with pytest.raises(gvd.GvdError) as e:
        client.upsert_sites(sid, sites)
    assert e.value.code == grpc.StatusCode.RESOURCE_EXHAUSTED
    assert "--max-vertices-per-site" in e.value.message
