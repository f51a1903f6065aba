#!/usr/bin/env bash
# Makes the README's gallery with the gvd CLI against a running gvd-server:
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
export GVD_SERVER="127.0.0.1:$(cat "$work/port")"
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
