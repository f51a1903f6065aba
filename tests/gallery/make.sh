#!/usr/bin/env bash
# Makes the gallery of the READMEs with the gvd CLI against a running gvd-server:
#   bash tests/gallery/make.sh [BUILD_DIR]   (default build/test)
# The paper's cover plate (four points, a segment, a triangle and a cubic Bezier) and its
# Figure 11 (nearest, farthest and weighted diagrams of the same sites).
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build/test}
out=tests/gallery
work=$(mktemp -d)
trap 'kill "$server" 2>/dev/null || true; wait "$server" 2>/dev/null || true; rm -rf "$work"' EXIT
"$build/server/gvd-server" --listen 127.0.0.1:0 --port-file "$work/port" --data :memory: \
  --log-level warn &
server=$!
for _ in $(seq 100); do [ -s "$work/port" ] && break; sleep 0.1; done
GVD_SERVER="127.0.0.1:$(cat "$work/port")"
export GVD_SERVER
gvd() { "$build/client/gvd" "$@"; }

# The cover plate.
gvd scene create cover --window 0,0,1,1 --size 512x512 >/dev/null
export GVD_SCENE=cover
gvd sites add p1 0.15 0.8 p2 0.35 0.55 p3 0.8 0.85 p4 0.55 0.3 >/dev/null
gvd sites add segment seg 0.1,0.15 0.35,0.35 >/dev/null
gvd sites add polygon tri 0.65,0.45 0.9,0.55 0.75,0.7 >/dev/null
gvd sites add bezier curve 0.5,0.95 0.2,0.55 0.95,0.2 0.7,0.05 >/dev/null
gvd render cover -o "$out/cover-ids.png" --layer ids --draw-sites
gvd render cover -o "$out/cover-distance.png" --layer distance --draw-sites
gvd render cover -o "$out/cover-features.png" --layer features --draw-sites

# Figure 11: the same points, nearest, farthest and weighted.
sites=(a 0.2 0.3 b 0.7 0.2 c 0.5 0.6 d 0.85 0.75 e 0.3 0.8 f 0.6 0.4)
for kind in nearest farthest weighted; do
  diagram=nearest
  [ "$kind" = farthest ] && diagram=farthest
  gvd scene create "fig11-$kind" --window 0,0,1,1 --size 256x256 --diagram "$diagram" >/dev/null
  export GVD_SCENE="fig11-$kind"
  gvd sites add "${sites[@]}" >/dev/null
  if [ "$kind" = weighted ]; then
    gvd sites add c 0.5 0.6 --multiplicative 0.75 >/dev/null
    gvd sites add f 0.6 0.4 --additive 0.08 >/dev/null
  fi
  gvd render "fig11-$kind" -o "$out/fig11-$kind.png" --layer ids --draw-sites
done

# Planning (paper sec. 7.1): a path of maximal clearance through a maze of segment walls,
# drawn over the distance field.
python3 - "$work/maze.json" <<'PY'
import json, random, sys
k, c = 12, 1 / 12
random.seed(4)
below = {(x, y) for x in range(k) for y in range(k + 1)}
left = {(x, y) for x in range(k + 1) for y in range(k)}
seen, stack = {(0, 0)}, [(0, 0)]
while stack:
    x, y = stack[-1]
    nxt = [(x + dx, y + dy) for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1))
           if 0 <= x + dx < k and 0 <= y + dy < k and (x + dx, y + dy) not in seen]
    if not nxt:
        stack.pop()
        continue
    nx, ny = random.choice(nxt)
    if nx != x:
        left.discard((max(x, nx), y))
    else:
        below.discard((x, max(y, ny)))
    seen.add((nx, ny))
    stack.append((nx, ny))
seg = lambda i, a, b: {"id": i, "segment": {"a": {"x": a[0], "y": a[1]}, "b": {"x": b[0], "y": b[1]}}}
sites = [seg(f"h{x}_{y}", (x * c, y * c), ((x + 1) * c, y * c)) for x, y in sorted(below)]
sites += [seg(f"v{x}_{y}", (x * c, y * c), (x * c, (y + 1) * c)) for x, y in sorted(left)]
json.dump(sites, open(sys.argv[1], "w"))
PY
gvd scene create maze --window 0,0,1,1 --size 512x512 >/dev/null
export GVD_SCENE=maze
gvd sites add --file "$work/maze.json" >/dev/null
gvd plan --from 0.0417,0.0417 --to 0.9583,0.9583 --radius 0.03 -o "$out/plan-maze.png" >/dev/null

# Mosaics (paper sec. 7.3) of a photograph (coffee.jpg: Rachel Michetti, CC0, from
# scikit-image's sample data), from the server: random tiles, and adaptive ones.
gvd mosaic "$out/coffee.jpg" "$out/coffee-mosaic.jpg" --tiles 1500 --seed 1 >/dev/null
gvd mosaic "$out/coffee.jpg" "$out/coffee-mosaic-adaptive.jpg" --tiles 1500 --seed 1 \
  --adaptive >/dev/null

# A 3D diagram (paper sec. 4.2, colour plate 3 in spirit): the Utah teapots of Debian's
# assimp-testmodels (apt-get install assimp-testmodels), one mesh of faces, edges and vertices; a thin slab of voxels through
# the nearest teapot's spout and handle, and its middle slice per feature and by distance.
gvd scene create teapot --window -0.6,-0.12,0.47,0.65,0.52,0.486 --size 640x328x8 >/dev/null
export GVD_SCENE=teapot
gvd sites add mesh teapots --file /usr/share/assimp/models/Collada/teapots.DAE >/dev/null
gvd render teapot -o "$out/teapot-features.png" --layer features --z 0.478
gvd render teapot -o "$out/teapot-distance.png" --layer distance --z 0.478
