#!/usr/bin/env bash
# Installs what gvd needs (Debian 12), builds gvd-server and the gvd CLI, and starts the
# server on 127.0.0.1:50051 (gRPC) and 127.0.0.1:8080 (HTTP/JSON and the web app), with
# Mesa's software rasterizer when there is no GPU. Extra arguments go to gvd-server and
# override these, e.g. --listen 0.0.0.0:50051 --tokens tokens.txt --log-level debug (beyond
# loopback the API needs --tokens or --tls-client-ca, or --allow-unauthenticated).
set -euo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=deploy/debian-deps.sh
. deploy/debian-deps.sh
gvd_install_packages build
cmake -S . -B build/release -G Ninja -DCMAKE_BUILD_TYPE=Release -DGVD_BUILD_TESTS=OFF
cmake --build build/release --target gvd-server gvd
echo "gvd CLI: $(pwd)/build/release/client/gvd"
exec build/release/server/gvd-server --http-listen 127.0.0.1:8080 "$@"
