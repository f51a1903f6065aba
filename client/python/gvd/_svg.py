"""Sites from an SVG file: one path site per drawn element (gvd.sites_from_svg). It reads
with svgelements and defusedxml (the "svg" extra; Debian's python3-svgelements and
python3-defusedxml), imported when first called."""
import io
import math
import os
from typing import Any, Dict, List, Optional, Tuple, Union

try:
    import defusedxml.ElementTree
    import svgelements as se
except ImportError as _missing:  # the rest of the client works without them
    se = None
    _MISSING = _missing

_EPS = 2.0 ** -52


def sites_from_svg(path: Union[str, os.PathLike], *, upright: bool = False,
                   tolerance: float = 0.0, arc_error: float = 1e-6,
                   max_bytes: int = 64 << 20) -> List[Dict[str, Any]]:
    """The drawn elements of an SVG file as sites for Client.upsert_sites: one path site
    (the API's JSON form) per <path>, <rect>, <circle>, <ellipse>, <line>, <polyline> and
    <polygon>, `use` instances included, with every transform applied.

    Coordinates are the document's user units (its viewBox's, else its px), y pointing down
    as SVG has it; upright=True maps y to the viewBox's top plus bottom less y (its height
    less y when it starts at 0), for an image the right way up in the scene.

    Ids: the element's `id`, else "<tag>-<n>", n its index from 0 among the document's drawn
    elements of that tag. An id already given (a `use` instance of an element, or two
    elements that share one) gets "~2", "~3", ... appended, the first that is free.

    Lines and Beziers are kept as they are. Arcs, and the circles, ellipses and rounded
    corners SVG writes as arcs, become cubics, enough of them that each is within arc_error
    times the ellipse's largest radius of it; the site's approximation_error says how far
    (a proven bound), and the server adds it to every answer's error_bound. tolerance is each
    site's path.tolerance (0: the server's default). The fill rule is the element's
    fill-rule. An element with nothing to draw (a <path> of moves only) is no site.

    A file that cannot be read, or one past max_bytes, is a ValueError naming the file (and
    the element, for a bad one); so is XML that declares entities (it could expand without
    bound). Sites past the server's limits are refused by upsert_sites
    (RESOURCE_EXHAUSTED, naming the limit)."""
    name = os.fspath(path)
    if se is None:
        raise ImportError("gvd.sites_from_svg needs svgelements and defusedxml (pip's gvd[svg]; "
                          "Debian: python3-svgelements python3-defusedxml)") from _MISSING
    # The elements SVG draws as shapes; text and images are not read.
    shapes = (se.Path, se.Rect, se.Circle, se.Ellipse, se.SimpleLine, se.Polyline, se.Polygon)
    if not arc_error > 0:
        raise ValueError(f"arc_error is {arc_error}; it must be above 0")
    try:
        with open(name, "rb") as f:
            data = f.read(max_bytes + 1)
    except OSError as e:
        raise ValueError(f"{name}: {e.strerror or e}") from e
    if len(data) > max_bytes:
        raise ValueError(f"{name}: larger than max_bytes ({max_bytes} bytes)")
    try:
        # Refuses entity declarations and external references before svgelements (which
        # parses with the standard library's expat) sees the file.
        root = defusedxml.ElementTree.fromstring(data)
        # User units: the root's viewBox is taken off (its size becomes the viewport's, for
        # lengths in %), so that svgelements maps no coordinate through a viewport.
        box = None
        if "viewBox" in root.attrib:
            box = [float(v) for v in root.attrib.pop("viewBox").replace(",", " ").split()]
            if len(box) != 4 or not all(math.isfinite(v) for v in box) or box[2] <= 0 or box[3] <= 0:
                raise ValueError(f"the root's viewBox is not 4 numbers with a positive size: {box}")
            root.set("width", repr(box[2]))
            root.set("height", repr(box[3]))
            data = defusedxml.ElementTree.tostring(root)
        svg = se.SVG.parse(io.BytesIO(data), reify=True)
    except Exception as e:  # each parser's own error types; all mean "cannot read"
        raise ValueError(f"{name}: {type(e).__name__}: {e}") from e
    if not isinstance(svg, se.SVG):
        raise ValueError(f"{name}: not an SVG document")
    flip: Optional[float] = None
    if upright:
        flip = 2 * box[1] + box[3] if box else float(svg.height)
    sites: List[Dict[str, Any]] = []
    taken: set = set()
    counts: Dict[str, int] = {}
    for element in svg.elements():
        if not isinstance(element, shapes):
            continue
        tag = element.values.get("tag") or type(element).__name__.lower()
        where = f"<{tag}" + (f' id="{element.id}">' if element.id else ">")
        try:
            subpaths, approximation = _subpaths(element, arc_error)
        except (ValueError, ArithmeticError, TypeError) as e:
            raise ValueError(f"{name}: {where}: {e}") from e
        if not subpaths:
            continue
        n = counts.get(tag, 0)
        counts[tag] = n + 1
        base = element.id or f"{tag}-{n}"
        site_id, k = base, 1
        while site_id in taken:
            k += 1
            site_id = f"{base}~{k}"
        taken.add(site_id)
        if flip is not None:
            for sub in subpaths:
                for p in sub["points"]:
                    p["y"] = flip - p["y"]
        rule = str(element.values.get("fill-rule", "nonzero")).strip()
        site_path: Dict[str, Any] = {
            "subpaths": subpaths,
            "fill_rule": "FILL_RULE_EVEN_ODD" if rule == "evenodd" else "FILL_RULE_NONZERO",
        }
        if tolerance:
            site_path["tolerance"] = tolerance
        if approximation > 0:
            site_path["approximation_error"] = approximation
        sites.append({"id": site_id, "path": site_path})
    return sites


def _subpaths(element: Any, arc_error: float) -> Tuple[List[Dict[str, Any]], float]:
    shape = se.Path(element)
    shape.reify()
    subpaths: List[Dict[str, Any]] = []
    current: Optional[Dict[str, Any]] = None
    end: Optional[Tuple[float, float]] = None
    approximation = 0.0

    def point(p: Any) -> Tuple[float, float]:
        x, y = float(p[0]), float(p[1])
        if not (math.isfinite(x) and math.isfinite(y)):
            raise ValueError(f"a point ({x}, {y}) is not finite")
        return x, y

    def piece(start: Tuple[float, float], rest: List[Tuple[float, float]]) -> None:
        nonlocal current, end
        if current is None or end != start:
            current = {"points": [start], "degrees": [], "closed": False}
            subpaths.append(current)
        current["points"].extend(rest)
        current["degrees"].append(len(rest))
        end = rest[-1]

    for seg in shape.segments(transformed=True):
        if isinstance(seg, se.Move):
            current, end = None, None
            continue
        if isinstance(seg, se.Close):
            if current is not None:
                current["closed"] = True
            current, end = None, None
            continue
        start = point(seg.start)
        if isinstance(seg, se.Line):
            piece(start, [point(seg.end)])
        elif isinstance(seg, se.QuadraticBezier):
            piece(start, [point(seg.control), point(seg.end)])
        elif isinstance(seg, se.CubicBezier):
            piece(start, [point(seg.control1), point(seg.control2), point(seg.end)])
        elif isinstance(seg, se.Arc):
            cubics, error = _arc_cubics(seg, start, point(seg.end), arc_error)
            approximation = max(approximation, error)
            for c in cubics:
                piece(start, c)
                start = c[-1]
        else:
            raise ValueError(f"a path segment of kind {type(seg).__name__} is not read")
    for sub in subpaths:
        sub["points"] = [{"x": x, "y": y} for x, y in sub["points"]]
    return subpaths, approximation


def _arc_cubics(arc: Any, start: Tuple[float, float], end: Tuple[float, float],
                arc_error: float) -> Tuple[List[List[Tuple[float, float]]], float]:
    """Cubics for an elliptical arc, and a proven bound on how far they are from it.

    The arc is C + U cos t + V sin t over an interval of t (U, V: the ellipse's conjugate
    radii as transformed, svgelements' prx and pry less its centre): the affine image of a
    unit circle's arc. Each piece of angle phi of the unit circle is drawn by the cubic with
    handles 4/3 tan(phi/4) long, whose points are off the circle by at most
    4/27 sin^6(phi/4) / cos^2(phi/4) (Goldapp, CAGD 1991; the true worst is half of it), and
    the affine map stretches that by at most its largest singular value. Pieces of at most
    a quarter turn are halved until the bound is below arc_error times that value. Rounding
    and the ends pinned to the arc's own ends add what the returned bound states too."""
    c = (float(arc.center[0]), float(arc.center[1]))
    u = (float(arc.prx[0]) - c[0], float(arc.prx[1]) - c[1])
    v = (float(arc.pry[0]) - c[0], float(arc.pry[1]) - c[1])
    det = u[0] * v[1] - u[1] * v[0]
    # The largest singular value of [u v].
    f = u[0] ** 2 + u[1] ** 2 + v[0] ** 2 + v[1] ** 2
    g = math.sqrt(max(0.0, (f / 2) ** 2 - det * det))
    sigma = math.sqrt(f / 2 + g)
    if not math.isfinite(det) or det == 0:
        # A degenerate ellipse (a radius of 0): SVG draws a line.
        return [[end]], 0.0

    def angle(p: Tuple[float, float]) -> float:
        x, y = p[0] - c[0], p[1] - c[1]
        return math.atan2((u[0] * y - u[1] * x) / det, (x * v[1] - y * v[0]) / det)

    def at(t: float) -> Tuple[float, float]:
        return (c[0] + u[0] * math.cos(t) + v[0] * math.sin(t),
                c[1] + u[1] * math.cos(t) + v[1] * math.sin(t))

    t0 = angle(start)
    forward = (angle(end) - t0) % (2 * math.pi)
    if forward == 0:
        forward = 2 * math.pi  # a whole ellipse
    # The direction svgelements draws it: the candidate whose middle is its middle.
    middle = arc.point(0.5)
    sweep = min((forward, forward - 2 * math.pi),
                key=lambda d: math.dist(at(t0 + d / 2), (float(middle[0]), float(middle[1]))))
    n = max(1, math.ceil(abs(sweep) / (math.pi / 2) - 1e-12))

    def bound(phi: float) -> float:
        s = math.sin(phi / 4)
        return 4 / 27 * s ** 6 / math.cos(phi / 4) ** 2

    while sigma * bound(abs(sweep) / n) > arc_error * sigma and n < 1 << 16:
        n *= 2
    phi = sweep / n
    k = 4 / 3 * math.tan(phi / 4)
    cubics = []
    for i in range(n):
        a, b = t0 + i * phi, t0 + (i + 1) * phi
        p0, p3 = at(a), at(b)
        d0 = (-u[0] * math.sin(a) + v[0] * math.cos(a), -u[1] * math.sin(a) + v[1] * math.cos(a))
        d3 = (-u[0] * math.sin(b) + v[0] * math.cos(b), -u[1] * math.sin(b) + v[1] * math.cos(b))
        p1 = (p0[0] + k * d0[0], p0[1] + k * d0[1])
        p2 = (p3[0] - k * d3[0], p3[1] - k * d3[1])
        cubics.append([p1, p2, p3])
    # Pin the ends to the arc's own, and state how far that and rounding move the pieces.
    pinned = max(math.dist(at(t0), start), math.dist(at(t0 + sweep), end))
    cubics[-1][-1] = end
    scale = math.hypot(*c) + 2 * sigma
    error = sigma * bound(abs(phi)) + pinned + 64 * _EPS * scale
    return cubics, error
