#!/usr/bin/env bash
# Builds gvd_bench (Release, with OpenCV when libopencv-dev is installed) and prints the
# benchmark table of tests/bench/README.md. Usage: bash tests/bench/run.sh [gbench flags]
set -euo pipefail
cd "$(dirname "$0")/../.."
# shellcheck source=deploy/debian-deps.sh
. deploy/debian-deps.sh
gvd_install_packages build test bench
cmake -S . -B build/bench -G Ninja -DCMAKE_BUILD_TYPE=Release -DGVD_BUILD_TESTS=ON >/dev/null
cmake --build build/bench --target gvd_bench gvd_analysis_bench gvd-server
bench=build/bench/tests/bench/gvd_bench
# Full renders with llvmpipe's rasterizer threads (one per core, its default); updates and
# queries as gvd-server runs them by default (rasterizing on the render thread).
env -u LP_NUM_THREADS "$bench" --benchmark_filter='Render|OpenCVDistanceTransform/[0-9]+/[12]' \
  --benchmark_out=build/bench/render.json --benchmark_out_format=json "$@" >&2
LP_NUM_THREADS=0 "$bench" --benchmark_filter='Update|Nearest|Grpc|Latency' \
  --benchmark_out=build/bench/serve.json --benchmark_out_format=json "$@" >&2
# Boundaries, Delaunay, zoom windows and plans as the server's render thread runs them.
LP_NUM_THREADS=0 build/bench/tests/bench/gvd_analysis_bench \
  --benchmark_out=build/bench/analysis.json --benchmark_out_format=json "$@" >&2
python3 tests/bench/table.py build/bench/render.json build/bench/serve.json build/bench/analysis.json
# What users wait for, through a real gvd-server on its default flags and a Python client.
/usr/bin/python3 tests/bench/serve.py build/bench/server/gvd-server
