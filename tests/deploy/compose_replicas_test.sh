#!/usr/bin/env bash
# deploy/compose.yaml's "replicas" profile for real: docker-compose (through podman's Docker
# API) starts PostgreSQL and two gvd replicas from the images; the replica tour of server/README.md runs against
# their published ports (gRPC 50051 and 50052, HTTP 8080 and 8081, which must be free),
# writing through one replica and reading through the other; a replica killed while a write
# lands through the other catches up when started again. Answers are checked against the
# exact nearest sites, computed here in double precision.
# Usage: bash tests/deploy/compose_replicas_test.sh [GVD_CLI]   (default build/test/client/gvd)
# Needs podman, docker-compose (Debian's 1.29, which knows profiles), the image of this source
# and postgres:15-bookworm (deploy/README.md). Environment: GVD_IMAGE, GVD_BUILD_IMAGE and
# GVD_OCI_RUNTIME as in tests/deploy/image.sh. Exits 77 (ctest's skip) saying why where one
# is missing.
set -euo pipefail
cd "$(dirname "$0")/../.."
cli=$(realpath "${1:-build/test/client/gvd}")
[[ -x $cli ]] || { echo "FAIL: no gvd CLI at $cli"; exit 1; }
for tool in docker-compose python3 curl; do
  if ! command -v "$tool" >/dev/null; then
    echo "SKIP: $tool is not installed (Debian: apt-get install podman runc docker-compose" \
      "golang-github-containernetworking-plugin-dnsname curl)"
    exit 77
  fi
done
needs_exec=1  # podman runs PostgreSQL's healthcheck with exec
# shellcheck source=tests/deploy/image.sh
source tests/deploy/image.sh
if ! "${podman[@]}" image exists postgres:15-bookworm; then
  echo "SKIP: no image postgres:15-bookworm (docker.io/library/postgres; deploy/README.md)"
  exit 77
fi
work=$(mktemp -d /tmp/gvd-compose-XXXXXX)
service=
checker=
compose=()
cleanup() {
  set +e
  [[ -n $checker ]] && kill "$checker" 2>/dev/null
  [[ ${#compose[@]} -gt 0 ]] && "${compose[@]}" down -v >/dev/null 2>&1
  [[ -n $service ]] && kill "$service" 2>/dev/null
  rm -rf "$work"
}
trap cleanup EXIT
if [[ -n $runtime && -z ${CONTAINERS_CONF:-} ]]; then
  printf '[engine]\nruntime = "gvd"\n[engine.runtimes]\ngvd = ["%s"]\n' "$runtime" \
    >"$work/containers.conf"
  export CONTAINERS_CONF=$work/containers.conf
fi
export GVD_IMAGE=$image  # deploy/compose.yaml's image

# docker-compose talks to podman's Docker-compatible API on a socket of this test's own.
"${podman[@]}" system service --time=0 "unix://$work/podman.sock" 2>"$work/podman.log" &
service=$!
export DOCKER_HOST=unix://$work/podman.sock
project=gvdcompose$$
compose=(docker-compose --ansi never -p "$project" -f deploy/compose.yaml --profile replicas)
for _ in $(seq 100); do [[ -S $work/podman.sock ]] && break; sleep 0.1; done

# Podman runs healthchecks from systemd timers; where there is no systemd, nothing would, and
# the replicas would wait forever for PostgreSQL's (depends_on: service_healthy): the test
# runs them, every second.
while :; do
  for c in $("${podman[@]}" ps -q --filter "label=com.docker.compose.project=$project"); do
    "${podman[@]}" healthcheck run "$c" >/dev/null 2>&1 || true
  done
  sleep 1
done &
checker=$!
for port in 50051 50052 8080 8081; do
  if (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null; then
    echo "FAIL: port $port is taken; the installation publishes 50051, 50052, 8080 and 8081"
    exit 1
  fi
done
if ! timeout 300 "${compose[@]}" up -d --no-build; then
  "${compose[@]}" logs
  cat "$work/podman.log"
  echo "FAIL: the installation did not start (podman runs a healthcheck with exec: the OCI"
  echo "runtime must allow it, GVD_OCI_RUNTIME included)"
  exit 1
fi
gvd() {  # gvd PORT ARGS...: the CLI against the replica published on PORT
  "$cli" --timeout 20 --server "127.0.0.1:$1" "${@:2}"
}
serving() {  # serving PORT: waits until that replica's health says SERVING
  for _ in $(seq 120); do
    [[ $(gvd "$1" health 2>/dev/null) == SERVING ]] && return 0
    sleep 1
  done
  "${compose[@]}" logs
  echo "FAIL: the replica on $1 is not SERVING"
  exit 1
}
serving 50051
serving 50052
echo "two replicas SERVING on one PostgreSQL"

# Sites (id x y) and what the nearest of each query point must be, with its distance.
expect() {  # expect "SITES" "POINTS" OUTPUT: each answer line names the exact nearest site
  python3 - "$1" "$2" "$3" <<'EOF'
import math, sys
s = sys.argv[1].split()
sites = {s[i]: (float(s[i + 1]), float(s[i + 2])) for i in range(0, len(s), 3)}
p = [float(v) for v in sys.argv[2].split()]
lines = [l.split() for l in sys.argv[3].splitlines()[1:] if l.strip()]  # after the header
assert len(lines) == len(p) // 2, f"{len(lines)} answers for {len(p) // 2} points"
for (x, y), line in zip(zip(p[::2], p[1::2]), lines):
    d = {k: math.hypot(x - a, y - b) for k, (a, b) in sites.items()}
    best = min(d.values())
    site, dist = line[2], float(line[3])
    assert d[site] == best, f"({x}, {y}) answered {site}, the nearest is at {best}"
    assert abs(dist - best) <= 1e-9 * (1 + best), f"({x}, {y}) {site} at {dist}, exactly {best}"
EOF
}
# server/README.md's replica tour: write through one replica, read through the other.
gvd 50051 scene create city --window 0,0,100,100 --size 512x512
gvd 50051 --scene city sites add a 10 10 b 80 20 c 50 90
out=$(gvd 50052 --scene city nearest 12 11 60 60 --min-version 2 --exact)
echo "$out"
expect "a 10 10 b 80 20 c 50 90" "12 11 60 60" "$out"
gvd 50052 --scene city sites add d 60 60
out=$(gvd 50051 --scene city nearest 60 61 --min-version 3 --exact)
echo "$out"
expect "a 10 10 b 80 20 c 50 90 d 60 60" "60 61" "$out"

# The published HTTP ports, one per replica, answer for the same scene at the same version.
for port in 8080 8081; do
  answer=$(curl -sf -H 'Content-Type: application/json' \
    -d '{"sceneId":"city","points":[{"x":60,"y":61}],"minVersion":"3","exact":true}' \
    "http://127.0.0.1:$port/gvd.v1.VoronoiService/FindNearest")
  echo "HTTP $port: $answer"
  [[ $answer == *'"siteId":"d"'* && $answer == *'"version":"3"'* ]] \
    || { echo "FAIL: HTTP $port answered $answer"; exit 1; }
done

# A replica killed while a write lands through the other catches up when started again.
"${compose[@]}" kill gvd-2
gvd 50051 --scene city sites add e 90 90
"${compose[@]}" start gvd-2
serving 50052
out=$(gvd 50052 --scene city nearest 88 91 12 11 --min-version 4 --exact)
echo "$out"
expect "a 10 10 b 80 20 c 50 90 d 60 60 e 90 90" "88 91 12 11" "$out"
scene=$(gvd 50052 scene get city)
echo "$scene"
[[ $scene == *"version 4, 5 sites"*"store version 4"* ]] || { echo "FAIL: $scene"; exit 1; }
echo "compose replicas: the tour passed through both replicas, and a killed one caught up"
