#!/usr/bin/env bash
# The image in a real OCI runtime under a memory limit: gvd-server in the container takes its
# memory budget from the container's cgroup (3/4 of --memory), refuses the scene that would
# not fit with RESOURCE_EXHAUSTED naming --max-memory, keeps serving, and is never OOM-killed.
# Usage: bash tests/deploy/container_test.sh
# Environment: GVD_IMAGE (default localhost/gvd:test; built from deploy/Dockerfile when
# absent, which needs the debian:bookworm base images: see deploy/README.md),
# GVD_OCI_RUNTIME (an OCI runtime for podman's --runtime; default: ../shared/tools/runc-norlimits
# beside the checkout where it exists, for sandboxes that refuse rlimits, else podman's own),
# GVD_CONTAINER_MEMORY (default 4g).
# Exits 77 (ctest's skip) saying why where podman is absent.
set -euo pipefail
cd "$(dirname "$0")/../.."
if ! command -v podman >/dev/null; then
  echo "SKIP: podman is not installed (Debian: apt-get install podman runc)"
  exit 77
fi
image=${GVD_IMAGE:-localhost/gvd:test}
memory=${GVD_CONTAINER_MEMORY:-4g}
runtime=${GVD_OCI_RUNTIME:-}
if [[ -z $runtime && -x ../shared/tools/runc-norlimits ]]; then
  runtime=$(realpath ../shared/tools/runc-norlimits)
fi
podman=(podman --storage-driver vfs)
run=("${podman[@]}")
[[ -n $runtime ]] && run+=(--runtime "$runtime")

if ! "${podman[@]}" image exists "$image"; then
  if ! "${podman[@]}" image exists docker.io/library/debian:bookworm; then
    echo "SKIP: no image $image and no debian:bookworm base to build it from (deploy/README.md)"
    exit 77
  fi
  "${podman[@]}" build --pull=never --network=host --isolation=chroot \
    -f deploy/Dockerfile -t "$image" .
fi

port=$((20000 + RANDOM % 20000))
name=gvd-memory-$$
cleanup() { "${podman[@]}" rm -f "$name" >/dev/null 2>&1 || true; }
trap cleanup EXIT
"${run[@]}" run -d --name "$name" --network=host --memory "$memory" "$image" \
  --listen "127.0.0.1:$port" --http-listen "127.0.0.1:$((port + 1))" \
  --metrics-listen "127.0.0.1:$((port + 2))" >/dev/null
http="http://127.0.0.1:$((port + 1))/gvd.v1.Voronoi"
for _ in $(seq 120); do
  "${podman[@]}" logs "$name" 2>&1 | grep -q event=http_listening && break
  [[ $("${podman[@]}" inspect -f '{{.State.Running}}' "$name") == true ]] || break
  sleep 1
done
logs=$("${podman[@]}" logs "$name" 2>&1)
echo "$logs" | grep -E 'event=(render_context|memory_budget)'
# The budget comes from the container's limit, not the machine's memory.
limit=$(numfmt --from=iec "${memory^^}")
budget=$(echo "$logs" | sed -n 's/.*event=memory_budget max_memory=\([0-9]*\).*from=cgroup.*/\1/p')
# shellcheck disable=SC2017  # the server's own rounding: limit / 4 * 3
[[ $budget == $((limit / 4 * 3)) ]] || { echo "FAIL: budget '$budget', expected 3/4 of $limit from the cgroup"; exit 1; }

call() { curl -s -H 'Content-Type: application/json' -d "$2" "$http/$1"; }
# 4096x4096 scenes (24 bytes a pixel: 384 MiB each) until one does not fit.
refused=""
for k in $(seq 1 16); do
  answer=$(call CreateScene "{\"sceneId\": \"s$k\", \"widthPx\": 4096, \"heightPx\": 4096,
    \"window\": {\"minX\": 0, \"minY\": 0, \"maxX\": 1, \"maxY\": 1}}")
  if echo "$answer" | grep -q '"code":"resource_exhausted"'; then refused=$answer; break; fi
  echo "$answer" | grep -q "\"sceneId\":\"s$k\"" || { echo "FAIL: CreateScene s$k: $answer"; exit 1; }
  call UpsertSites "{\"sceneId\": \"s$k\", \"sites\": [{\"id\": \"a\", \"point\": {\"x\": 0.5, \"y\": 0.5}}]}" >/dev/null
  call FindNearest "{\"sceneId\": \"s$k\", \"points\": [{\"x\": 0.1, \"y\": 0.2}], \"minVersion\": \"2\"}" \
    | grep -q '"siteId":"a"' || { echo "FAIL: scene s$k does not answer"; exit 1; }
  echo "scene s$k: 4096x4096, rendered; container memory $("${podman[@]}" stats --no-stream --format '{{.MemUsage}}' "$name")"
done
[[ -n $refused ]] || { echo "FAIL: 16 scenes of 384 MiB fit a $memory container"; exit 1; }
echo "scene s$k refused: $refused"
echo "$refused" | grep -q -- '--max-memory' || { echo "FAIL: the refusal does not name --max-memory"; exit 1; }
# Still serving, every accepted scene answers, and no OOM kill.
for j in $(seq 1 $((k - 1))); do
  call FindNearest "{\"sceneId\": \"s$j\", \"points\": [{\"x\": 0.9, \"y\": 0.9}]}" | grep -q '"siteId":"a"' \
    || { echo "FAIL: scene s$j stopped answering"; exit 1; }
done
[[ $("${podman[@]}" inspect -f '{{.State.Running}} {{.State.OOMKilled}}' "$name") == "true false" ]] \
  || { echo "FAIL: the container is not running, or was OOM-killed"; exit 1; }
curl -s "http://127.0.0.1:$((port + 2))/metrics" | grep -E '^gvd_memory(_limit)?_bytes '
"${podman[@]}" stop -t 30 "$name" >/dev/null
echo "exit code $("${podman[@]}" inspect -f '{{.State.ExitCode}}' "$name") after SIGTERM"
[[ $("${podman[@]}" inspect -f '{{.State.ExitCode}} {{.State.OOMKilled}}' "$name") == "0 false" ]] \
  || { echo "FAIL: the container did not stop cleanly"; exit 1; }
echo "container_test: $((k - 1)) scenes fit the ${memory} container's budget, the next was refused by name, no OOM kill"
