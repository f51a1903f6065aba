#!/usr/bin/env bash
# What one call costs through each transport of a gvd-server binary, for a before/after of a
# change to the transports or the core's call path:
#   capacity BIN [SERVICE]     single-point FindNearest over HTTP/JSON (wrk, 8 connections,
#                              10 s) and over gRPC (h2load, 8 connections, 200,000 calls), on a
#                              1024x1024 scene of 100,000 points
#   instructions BIN METHOD N [SERVICE]
#                              instructions the server spends per gRPC call of METHOD
#                              (FindNearest, Pick or UpsertSites), by difference: the server
#                              under callgrind serves a 256x256 scene of 1,000 points, rendered,
#                              then holds its renders (so no render is counted) and serves N
#                              calls over one connection; run it with N and with 0 and divide
#                              the difference of the totals by N
#   http-instructions BIN N [SERVICE]
#                              the same for a one-point FindNearest over HTTP/JSON (h2load
#                              --h1, one connection)
# SERVICE is the gRPC service's full name (gvd.v1.VoronoiService; give the old name to measure
# a binary from before the rename). Loopback ports 18080 and 18082.
# Usage: bash tests/bench/transports.sh capacity build/bench/server/gvd-server
set -euo pipefail
cd "$(dirname "$0")/../.."
# shellcheck source=deploy/debian-deps.sh
. deploy/debian-deps.sh
gvd_install_packages bench
mode=$1 bin=$2
dir=$(mktemp -d)
pid=
trap '[[ -n $pid ]] && kill $pid 2>/dev/null; wait 2>/dev/null; rm -rf "$dir"' EXIT

# start PORT SIDE POINTS [PREFIX...]: the server (under PREFIX), a scene of POINTS random
# points, rendered.
start() {
  local http=$1 side=$2 points=$3
  shift 3
  "$@" "$bin" --listen 127.0.0.1:0 --port-file "$dir/port" --http-listen "127.0.0.1:$http" \
    --data "$dir/data" --log-level warn --render-threads 1 >"$dir/log" 2>&1 &
  pid=$!
  for _ in $(seq 1200); do
    [[ -s $dir/port ]] && curl -s -o /dev/null "http://127.0.0.1:$http/" && break
    sleep 0.5
  done
  python3 - "http://127.0.0.1:$http/$service" "$side" "$points" <<'PY'
import json, random, sys, urllib.request
base, side, n = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
def post(method, body):
    req = urllib.request.Request(f"{base}/{method}", json.dumps(body).encode(),
                                 {"Content-Type": "application/json"})
    return json.load(urllib.request.urlopen(req, timeout=600))
post("CreateScene", {"sceneId": "bench", "window": {"maxX": 1, "maxY": 1},
                     "widthPx": side, "heightPx": side})
random.seed(2)
v = post("UpsertSites", {"sceneId": "bench", "sites": [
    {"id": f"p{i}", "point": {"x": random.random(), "y": random.random()}} for i in range(n)]})
post("FindNearest", {"sceneId": "bench", "minVersion": v["version"],
                     "points": [{"x": 0.5, "y": 0.5}]})
PY
}

# request METHOD: the gRPC request body (length-prefixed protobuf) of one call at (0.37, 0.61):
# FindNearestRequest.points and PickRequest.point are both field 2; UpsertSites moves site "m".
request() {
  python3 - "$dir/req.bin" "$1" <<'PY'
import struct, sys
pt = b"\x09" + struct.pack("<d", 0.37) + b"\x11" + struct.pack("<d", 0.61)
point = b"\x12" + bytes([len(pt)]) + pt
if sys.argv[2] == "UpsertSites":
    site = b"\x0a\x01m" + point
    msg = b"\x0a\x05bench" + b"\x12" + bytes([len(site)]) + site
else:
    msg = b"\x0a\x05bench" + point
open(sys.argv[1], "wb").write(b"\x00" + struct.pack(">I", len(msg)) + msg)
PY
}

grpc_load() {  # N CONNECTIONS THREADS METHOD
  h2load -n "$1" -c "$2" -t "$3" -m 1 -d "$dir/req.bin" -H 'content-type: application/grpc' \
    -H 'te: trailers' "http://127.0.0.1:$(head -1 "$dir/port")/$service/$4"
}

case $mode in
  capacity)
    service=${3:-gvd.v1.VoronoiService}
    start 18080 1024 100000
    base=http://127.0.0.1:18080/$service
    cat >"$dir/find.lua" <<'LUA'
wrk.method = "POST"
wrk.headers["Content-Type"] = "application/json"
wrk.body = '{"sceneId":"bench","points":[{"x":0.37,"y":0.61}]}'
LUA
    wrk -t2 -c8 -d3s -s "$dir/find.lua" "$base/FindNearest" >/dev/null  # warm-up
    echo "== HTTP/JSON FindNearest (wrk -t2 -c8 -d10s)"
    wrk -t2 -c8 -d10s -s "$dir/find.lua" "$base/FindNearest" | grep -E "Requests/sec|Latency|Non-2xx"
    request FindNearest
    grpc_load 20000 8 2 FindNearest >/dev/null  # warm-up
    echo "== gRPC FindNearest (h2load -n 200000 -c 8 -t 2 -m 1)"
    grpc_load 200000 8 2 FindNearest | grep -E "finished in|requests:|status codes"
    ;;
  instructions | http-instructions)
    if [[ $mode == instructions ]]; then
      method=$3 n=$4 service=${5:-gvd.v1.VoronoiService}
    else
      method=FindNearest n=$3 service=${4:-gvd.v1.VoronoiService}
    fi
    mkdir -p build/bench
    out=build/bench/callgrind.$mode.$method.$n
    GVD_TEST_HOLD_RENDERS="$dir/hold" start 18082 256 1000 \
      valgrind --tool=callgrind --callgrind-out-file="$out"
    touch "$dir/hold"
    if [[ $mode == instructions ]]; then
      request "$method"
      if ((n > 0)); then grpc_load "$n" 1 1 "$method" | grep -E "status codes"; fi
    elif ((n > 0)); then
      printf '{"sceneId":"bench","points":[{"x":0.37,"y":0.61}]}' >"$dir/req.json"
      h2load --h1 -n "$n" -c 1 -t 1 -d "$dir/req.json" -H 'content-type: application/json' \
        "http://127.0.0.1:18082/$service/FindNearest" | grep -E "status codes"
    fi
    kill -TERM $pid
    wait $pid || true
    pid=
    echo "$method, $n calls: $(grep -h '^summary:' "$out")"
    ;;
  *)
    echo "usage: $0 capacity BIN [SERVICE] | instructions BIN METHOD N [SERVICE] |" \
      "http-instructions BIN N [SERVICE]" >&2
    exit 2
    ;;
esac
