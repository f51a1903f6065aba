#!/usr/bin/env bash
# The image in a real OCI runtime under a memory limit: gvd-server in the container takes its
# memory budget from the container's cgroup (3/4 of --memory), refuses the scene that would
# not fit with RESOURCE_EXHAUSTED naming --max-memory, keeps serving, and is never OOM-killed.
# Usage: bash tests/deploy/container_test.sh
# Environment: GVD_IMAGE, GVD_BUILD_IMAGE and GVD_OCI_RUNTIME as in tests/deploy/image.sh,
# which skips (exit 77) saying why where podman, a working runtime or the image of this
# source is missing; GVD_CONTAINER_MEMORY (default 4g).
set -euo pipefail
cd "$(dirname "$0")/../.."
# shellcheck source=tests/deploy/image.sh
source tests/deploy/image.sh
memory=${GVD_CONTAINER_MEMORY:-4g}
run=("${podman[@]}")
[[ -n $runtime ]] && run+=(--runtime "$runtime")

port=$((20000 + RANDOM % 20000))
name=gvd-memory-$$
cleanup() { "${podman[@]}" rm -f "$name" >/dev/null 2>&1 || true; }
trap cleanup EXIT
"${run[@]}" run -d --name "$name" --network=host --memory "$memory" "$image" \
  --listen "127.0.0.1:$port" --http-listen "127.0.0.1:$((port + 1))" \
  --metrics-listen "127.0.0.1:$((port + 2))" >/dev/null
http="http://127.0.0.1:$((port + 1))/gvd.v1.VoronoiService"
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
# An image: the server loads OpenImageIO's module, which the image holds beside it, at its first.
call CreateScene '{"sceneId": "picture", "widthPx": 64, "heightPx": 48,
  "window": {"minX": 0, "minY": 0, "maxX": 1, "maxY": 1}}' >/dev/null
call UpsertSites '{"sceneId": "picture", "sites": [{"id": "a", "point": {"x": 0.5, "y": 0.5}}]}' >/dev/null
picture=$(call RenderImage '{"sceneId": "picture", "minVersion": "2"}')
echo "$picture" | grep -q '"mimeType":"image/png"' \
  || { echo "FAIL: RenderImage in the container: ${picture:0:300}"; exit 1; }
call DeleteScene '{"sceneId": "picture"}' >/dev/null
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
