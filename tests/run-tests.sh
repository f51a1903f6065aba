#!/usr/bin/env bash
# Installs what the tests need (Debian 12), builds everything with tests, and runs the whole
# suite with CTest: unit tests, GL property tests on the EGL device (llvmpipe without a GPU),
# and integration tests against the real gvd-server and gvd CLI on loopback.
set -euo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=deploy/debian-deps.sh
. deploy/debian-deps.sh
gvd_install_packages build test
# Node.js and npm for the TypeScript client's tests: Debian's, unless a Node.js is here already
# (another distribution's package may hold npm within it).
command -v npm >/dev/null || gvd_install_packages node
cmake -S . -B build/test -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DGVD_BUILD_TESTS=ON
cmake --build build/test
cd build/test
ctest --output-on-failure --timeout 600 -j "$(nproc)"
