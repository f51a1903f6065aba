#!/usr/bin/python3
"""The generalized Voronoi diagram of real shapes from GeoJSON files, drawn with matplotlib.

Usage: geojson_diagram.py SERVER FILE.geojson... [--size 1024] [--grid 600] [--out diagram.png]

Each polygon ring, line and point of the files becomes a site of a new scene (named after
its file and part; ids "name#k"); a grid of query points over their bounds is answered
through the gvd client (one packed FindNearest), and the picture shows each point coloured by
its nearest shape, shaded by the distance, with the shapes on top. SERVER is the gRPC
address ("127.0.0.1:50051") or the HTTP URL ("http://127.0.0.1:8080").

Real shapes to try, from npm's registry: `npm pack world-geojson` and the cantons of
Switzerland in package/states/switzerland/*.geojson.
"""
import argparse
import json
import os

import matplotlib
import numpy as np

import gvd

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  pylint: disable=wrong-import-position


def shapes(path):
    """(name, kind, coordinates) for every part of every geometry in a GeoJSON file."""
    with open(path, encoding="utf-8") as f:
        data = json.load(f)
    features = data["features"] if data.get("type") == "FeatureCollection" else [data]
    name = os.path.splitext(os.path.basename(path))[0]
    for feature in features:
        g = feature.get("geometry", feature)
        parts = {"MultiPolygon": [("Polygon", p) for p in g["coordinates"]],
                 "MultiLineString": [("LineString", p) for p in g["coordinates"]],
                 "MultiPoint": [("Point", p) for p in g["coordinates"]]}.get(
                     g["type"], [(g["type"], g["coordinates"])])
        for kind, coordinates in parts:
            if kind == "Polygon":
                for ring in coordinates:  # the outer ring and any holes, each an outline
                    yield name, "Polygon", [ring]
            else:
                yield name, kind, coordinates


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("server")
    ap.add_argument("files", nargs="+")
    ap.add_argument("--size", type=int, default=1024, help="the scene's raster side")
    ap.add_argument("--grid", type=int, default=600, help="query points along the long side")
    ap.add_argument("--out", default="diagram.png")
    args = ap.parse_args()

    sites, names, outlines = [], [], []
    for path in args.files:
        for k, (name, kind, coordinates) in enumerate(shapes(path)):
            sites.append({"id": f"{name}#{k}", "type": kind, "coordinates": coordinates})
            names.append(name)
            outlines.append(np.array(coordinates[0] if kind == "Polygon" else coordinates,
                                     dtype=float).reshape(-1, 2))
    every = np.vstack(outlines)
    lo, hi = every.min(axis=0), every.max(axis=0)
    pad = 0.05 * (hi - lo).max()
    window = (lo[0] - pad, lo[1] - pad, hi[0] + pad, hi[1] + pad)

    with gvd.Client(args.server) as c:
        scene = "geojson-" + str(os.getpid())
        c.create_scene(scene, window=window, size=(args.size, args.size))
        try:
            version = c.upsert_sites(scene, sites)
            w, h = window[2] - window[0], window[3] - window[1]
            nx = args.grid if w >= h else max(2, int(args.grid * w / h))
            ny = args.grid if h > w else max(2, int(args.grid * h / w))
            xs = np.linspace(window[0], window[2], nx)
            ys = np.linspace(window[1], window[3], ny)
            q = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
            r = c.find_nearest(scene, q, min_version=version)
        finally:
            c.delete_scene(scene)

    shape_of = {n: i for i, n in enumerate(sorted(set(names)))}
    owner = np.array([shape_of[s.split("#")[0]] if s else -1 for s in r.site_ids]).reshape(ny, nx)
    distance = r.distances.reshape(ny, nx)
    colours = plt.get_cmap("tab20")(owner % 20)
    shade = 1 - 0.6 * np.clip(distance / np.percentile(distance, 99), 0, 1)
    colours[..., :3] *= shade[..., None]
    fig, ax = plt.subplots(figsize=(10, 10 * ny / nx))
    ax.imshow(colours, origin="lower", extent=(window[0], window[2], window[1], window[3]))
    for outline in outlines:
        ax.plot(outline[:, 0], outline[:, 1], color="black", linewidth=0.6)
    ax.set_title(f"nearest of {len(shape_of)} shapes ({len(sites)} outlines), "
                 f"{len(q):,} points, version {r.version}")
    fig.savefig(args.out, dpi=120, bbox_inches="tight")
    print(f"{args.out}: {len(sites)} sites from {len(args.files)} files, {len(q):,} points, "
          f"largest error bound {r.error_bounds.max():.3g}")


if __name__ == "__main__":
    main()
