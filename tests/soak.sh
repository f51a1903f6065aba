#!/usr/bin/env bash
# A soak: mixed load on a real gvd-server for MINUTES (default 10), with SIGTERM and SIGKILL
# restarts, every answer checked against its version (tests/soak.py says what it does).
# Usage: bash tests/soak.sh [MINUTES] [--server PATH] [soak.py options]
#   --replicas 2: the replicated form, two gvd-servers on a PostgreSQL of the soak's own,
#   with kills of either replica and stops and crashes of the database.
# Without --server it builds gvd-server in Release (build/release), as deploy/run-server.sh.
# CI runs the one-minute forms as the ctests `soak_1min` and `soak_replicated_1min`.
set -euo pipefail
cd "$(dirname "$0")/.."
minutes=10
if [[ $# -gt 0 && $1 != --* ]]; then minutes=$1; shift; fi
server=""
args=()
while [[ $# -gt 0 ]]; do
  case $1 in
    --server) server=$2; shift 2 ;;
    *) args+=("$1"); shift ;;
  esac
done
if [[ -z $server ]]; then
  cmake -S . -B build/release -G Ninja -DCMAKE_BUILD_TYPE=Release -DGVD_BUILD_TESTS=OFF >/dev/null
  cmake --build build/release --target gvd-server >/dev/null
  server=build/release/server/gvd-server
fi
seconds=$(awk -v m="$minutes" 'BEGIN { print m * 60 }')
exec /usr/bin/python3 tests/soak.py --server "$server" --seconds "$seconds" "${args[@]}"
