#!/usr/bin/env bash
# The README's first command, checked: deploy/run-server.sh builds gvd-server and gvd in
# Release and starts the server (on llvmpipe without a GPU); the CLI then takes the README's
# tour against it, and SIGTERM must stop it cleanly.
# Usage: bash tests/smoke-server.sh
set -euo pipefail
cd "$(dirname "$0")/.."
work=$(mktemp -d)
bash deploy/run-server.sh --listen 127.0.0.1:0 --http-listen 127.0.0.1:0 \
  --port-file "$work/port" --data :memory: --log-level warn >"$work/server.log" 2>&1 &
server=$!
trap 'kill "$server" 2>/dev/null || true; rm -rf "$work"' EXIT
for _ in $(seq 3600); do
  [ -s "$work/port" ] && break
  if ! kill -0 "$server" 2>/dev/null; then
    cat "$work/server.log" >&2
    echo "smoke-server: deploy/run-server.sh exited before serving" >&2
    exit 1
  fi
  sleep 1
done
[ -s "$work/port" ] || { echo "smoke-server: no port after an hour" >&2; exit 1; }
gvd() { build/release/client/gvd --server "127.0.0.1:$(head -1 "$work/port")" "$@"; }
http="http://127.0.0.1:$(sed -n 2p "$work/port")"
[ "$(gvd health)" = SERVING ]
gvd scene create demo --window 0,0,100,100 --size 256x256 >/dev/null
gvd --scene demo sites add a 10 10 b 80 20 c 50 90 >/dev/null
gvd --scene demo nearest 60 60 --exact | grep -q $'^60\t60\tc\t31.622776601683793\t0\tyes'
gvd --scene demo neighbors --min-version 2 2>/dev/null | grep -q '^a b$'
# The README's curl call, and the web app.
# Each body is read whole before it is searched: grep -q stops reading at its match, and
# under pipefail curl's write error (23) on the closed pipe would fail the script.
answer=$(curl -sf -H 'Content-Type: application/json' \
  -d '{"sceneId": "demo", "points": [{"x": 12, "y": 11}], "exact": true}' \
  "$http/gvd.v1.VoronoiService/FindNearest")
[[ $answer == *'"siteId":"a","distance":2.23606797749979'* ]]
page=$(curl -sf "$http/")
[[ $page == *'<title>gvd — nearest-object selection</title>'* ]]
app=$(curl -sf "$http/app.js")
[[ $app == *pointerrawupdate* ]]
kill -TERM "$server"
wait "$server"
echo "smoke-server: the README's first command builds, serves and stops cleanly"
