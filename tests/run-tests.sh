#!/usr/bin/env bash
# Installs what the tests need (Debian 12), builds everything with tests, and runs the whole
# suite with CTest: unit tests, GL property tests on the EGL device (llvmpipe without a GPU),
# and integration tests against the real gvd-server and gvd CLI on loopback.
set -euo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=deploy/debian-deps.sh
. deploy/debian-deps.sh
gvd_install_packages build test
cmake -S . -B build/test -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DGVD_BUILD_TESTS=ON
cmake --build build/test
cd build/test
ctest --output-on-failure --timeout 600 -j "$(nproc)"
