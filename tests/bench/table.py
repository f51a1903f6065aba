#!/usr/bin/env python3
"""Turns gvd_bench's JSON output into the markdown table of tests/bench/README.md."""
import json
import sys


def main(paths):
    rows = {}
    for path in paths:
        data = json.load(open(path))
        for b in data["benchmarks"]:
            if b.get("run_type") == "aggregate" or b.get("error_occurred"):
                continue
            rows[b["name"].split("/min_time")[0].split("/real_time")[0]] = b
    ctx = data["context"]
    print(f"Machine: {ctx.get('num_cpus')} CPUs, {ctx.get('host_name', '')}; "
          f"renderer: {next((b.get('label') for b in rows.values() if 'Render' in b['name']), '?')}")
    print()
    print("| benchmark | gvd | reference | gvd vs reference |")
    print("|---|---|---|---|")

    def ms(b):
        return b["real_time"] * {"ms": 1, "us": 1e-3, "ns": 1e-6}[b["time_unit"]]

    for n in (1000, 10000, 100000, 1000000):
        for size in (1024, 2048):
            for mode, label in ((0, "mesh"), (1, "exact")):
                g = rows.get(f"BM_Render/{n}/{size}/{mode}")
                o = rows.get(f"BM_OpenCVDistanceTransform/{n}/{size}")
                if not g:
                    continue
                ref = f"{ms(o):.1f} ms (OpenCV distanceTransform, labels)" if o else "n/a"
                ratio = f"{ms(o) / ms(g):.2f}x" if o else ""
                how = (f"computed, {g['candidates_px']:.1f} candidates/px"
                       if g.get("candidates_px") else f"fill {g['fill']:.1f}x grid")
                print(f"| full render, {n:,} points, {size}x{size}, {label} mode | {ms(g):.1f} ms "
                      f"({how}) | {ref} | {ratio} |")
    o = rows.get("BM_OpenCVDistanceTransform/1000000/4096")
    for path, label in ((0, "mesh mode"), (1, "exact mode, computed"), (2, "exact mode, drawn")):
        g = rows.get(f"BM_Large4096/{path}")
        if g:
            how = (f"{g['candidates_px']:.1f} candidates/px" if g.get("candidates_px")
                   else f"fill {g['fill']:.1f}x grid")
            ref = f"{ms(o):.1f} ms (OpenCV distanceTransform, labels)" if o else ""
            ratio = f"{ms(o) / ms(g):.2f}x" if o else ""
            print(f"| full render, 1,000,000 points, 4096x4096, {label} | {ms(g):.1f} ms ({how}) "
                  f"| {ref} | {ratio} |")
    kinds = ("1,000 segments", "1,000 polylines of 8 points", "1,000 hexagons",
             "1,000 hexagons, inside only", "1,000 cubic Beziers",
             "1,000 weighted points with max_distance", "100 points, FARTHEST",
             "20 polylines of 5,000 random points across the window")
    for kind, name in enumerate(kinds):
        for mode, label in ((0, "mesh"), (1, "exact")):
            g = rows.get(f"BM_RenderKind/{kind}/{mode}")
            if g:
                how = (f"computed, {g['candidates_px']:.1f} candidates/px"
                       if g.get("candidates_px") else f"fill {g['fill']:.1f}x grid")
                print(f"| full render, {name}, 1024x1024, {label} mode | "
                      f"{ms(g):.1f} ms ({how}) | | |")
    full = rows.get("BM_Render/100000/1024/0")
    ocv = rows.get("BM_OpenCVDistanceTransform/100000/1024")
    for kind, name in ((0, "add"), (1, "move"), (2, "delete")):
        for computed, how in ((1, "computed"), (0, "drawn")):
            u = rows.get(f"BM_UpdateOneSite/{kind}/1/{computed}")
            if not u:
                continue
            vs = []
            if full:
                vs.append(f"{ms(full) / ms(u):.0f}x faster than our full render")
            if ocv:
                vs.append(f"{ms(ocv) / ms(u):.0f}x faster than OpenCV's recompute")
            print(f"| one-site {name}, 100,000 points, 1024x1024, windows {how} | {ms(u):.3f} ms "
                  f"({u['pixels']:.0f} px redrawn) | full render {ms(full):.0f} ms"
                  + (f", OpenCV {ms(ocv):.1f} ms" if ocv else "") + f" | {'; '.join(vs)} |")
    fn = rows.get("BM_FrameNearest")
    nf = rows.get("BM_NanoflannNearest")
    if fn and nf:
        print(f"| FindNearest in process, 1 thread | {fn['items_per_second'] / 1e6:.2f} M/s "
              f"| {nf['items_per_second'] / 1e6:.2f} M/s (nanoflann kd-tree) "
              f"| {fn['items_per_second'] / nf['items_per_second']:.2f}x |")
    for batch in (1, 1000, 1000000):
        for exact, label in ((0, "raster"), (1, "exact")):
            g = rows.get(f"BM_GrpcFindNearest/{batch}/{exact}")
            if not g:
                continue
            if batch == 1:
                print(f"| FindNearest over loopback, 1 point per call, {label} | "
                      f"{ms(g) * 1e3:.0f} us per call | | |")
                continue
            ref = f"{nf['items_per_second'] / 1e6:.2f} M/s" if nf else "n/a"
            ratio = f"{g['items_per_second'] / nf['items_per_second']:.2f}x" if nf else ""
            print(f"| FindNearest over loopback, batch {batch:,}, {label} | "
                  f"{g['items_per_second'] / 1e6:.2f} M points/s | {ref} (nanoflann, 1 thread) "
                  f"| {ratio} |")
    mem = rows.get("BM_GrpcUpsert/0")
    disk = rows.get("BM_GrpcUpsert/1")
    if mem and disk:
        print(f"| one-site upserts over loopback, store on disk (WAL, synchronous=FULL) | "
              f"{disk['items_per_second']:.0f}/s, commit {disk['commit_us']:.0f} us | "
              f"store in memory: {mem['items_per_second']:.0f}/s, commit {mem['commit_us']:.0f} us "
              f"| {disk['items_per_second'] / mem['items_per_second']:.2f}x |")
    lat = rows.get("BM_LatencyUnderWriter/iterations:20000")
    if lat:
        print(f"| single-point FindNearest latency under a writer | p50 {lat['p50_us']:.0f} us, "
              f"p99 {lat['p99_us']:.0f} us | writer: {lat['moves_per_s']:.0f} moves/s | |")
    pick = rows.get("BM_GrpcPick")
    if pick:
        print(f"| Pick over loopback, 1 point per call, 100,000 points | {ms(pick) * 1e3:.0f} us "
              f"per call | | |")
    # Structure and applications (gvd_analysis_bench), 1024x1024, from a rendered frame.
    for n in (1000, 10000):
        boost = rows.get(f"BM_BoostPolygonVoronoi/{n}")
        for method, label in ((0, "full scan"), (1, "continuation")):
            b = rows.get(f"BM_Boundaries/{n}/{method}")
            if b:
                ref = f"{ms(boost):.1f} ms (Boost.Polygon voronoi, exact, points only)" if boost else ""
                print(f"| boundaries as polylines, {n:,} points, {label} | {ms(b):.1f} ms "
                      f"({b['polylines']:.0f} polylines) | {ref} | |")
        qh = rows.get(f"BM_QhullDelaunay/{n}")
        for refined, label in ((0, "pixel pairs only"), (1, "refined by zoom windows")):
            d = rows.get(f"BM_Delaunay/{n}/{refined}")
            if d:
                ref = f"{ms(qh):.1f} ms (Qhull)" if qh else ""
                print(f"| Delaunay, {n:,} points, {label} | {ms(d):.0f} ms ({d['triangles']:.0f} "
                      f"triangles, {d['zoom_windows']:.0f} zoom windows) | {ref} | |")
    for k in (8, 32):
        for field, label in ((0, "path on a ready field"), (1, "clearance field and path")):
            p = rows.get(f"BM_PlanMaze/{k}/{field}")
            if p:
                print(f"| plan across a {k}x{k} maze, {label} | {ms(p):.1f} ms | | |")
    for size in (8, 32, 64):
        z = rows.get(f"BM_ZoomWindows/{size}")
        if z:
            print(f"| zoom windows of {size}x{size} px, batches of 128 | "
                  f"{z['items_per_second']:.0f} windows/s | | |")


if __name__ == "__main__":
    main(sys.argv[1:])
