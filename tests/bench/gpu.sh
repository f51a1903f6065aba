#!/usr/bin/env bash
# The GPU run: builds gvd (Release), runs the GL tests and the benchmark table, the 4096x4096
# rows included, on the machine's NVIDIA GPU through EGL, and fails if anything would render
# on Mesa's software rasterizer instead. Usage: bash tests/bench/gpu.sh [gbench flags]
#
# It needs NVIDIA's driver (libEGL_nvidia.so.0 and friends). Where the driver's libraries are
# mounted without a glvnd vendor file (a container given the GPU), it names NVIDIA's vendor
# library to glvnd's EGL loader; set __EGL_VENDOR_LIBRARY_FILENAMES to override.
set -euo pipefail
cd "$(dirname "$0")/../.."
# shellcheck source=deploy/debian-deps.sh
. deploy/debian-deps.sh
gvd_install_packages build test bench
if [ -z "${__EGL_VENDOR_LIBRARY_FILENAMES:-}" ] &&
  ! compgen -G '/usr/share/glvnd/egl_vendor.d/*nvidia*.json' >/dev/null &&
  ! compgen -G '/etc/glvnd/egl_vendor.d/*nvidia*.json' >/dev/null; then
  for f in /usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json deploy/10_nvidia.json; do
    if [ -f "$f" ]; then
      __EGL_VENDOR_LIBRARY_FILENAMES="$(realpath "$f")"
      export __EGL_VENDOR_LIBRARY_FILENAMES
      break
    fi
  done
fi
echo "GPU: $(nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader 2>&1 || true)"
cmake -S . -B build/gpu -G Ninja -DCMAKE_BUILD_TYPE=Release -DGVD_BUILD_TESTS=ON >/dev/null
cmake --build build/gpu
# A hardware EGL device or nothing: the tests and the bench fail rather than fall back.
export GVD_EGL_DEVICE=hardware GVD_REQUIRE_GL=1
(cd build/gpu && ctest -L gl --output-on-failure)
bench=build/gpu/tests/bench/gvd_bench
"$bench" --benchmark_filter='Render|OpenCVDistanceTransform|Large4096' \
  --benchmark_out=build/gpu/render.json --benchmark_out_format=json "$@" >&2
"$bench" --benchmark_filter='Update|Nearest|Grpc|Latency' \
  --benchmark_out=build/gpu/serve.json --benchmark_out_format=json "$@" >&2
build/gpu/tests/bench/gvd_analysis_bench \
  --benchmark_out=build/gpu/analysis.json --benchmark_out_format=json "$@" >&2
python3 - build/gpu/render.json <<'PY'
import json, sys
labels = {b.get("label", "") for b in json.load(open(sys.argv[1]))["benchmarks"]
          if b["name"].startswith(("BM_Render", "BM_Large"))}
print("GL renderer:", "; ".join(sorted(labels)), file=sys.stderr)
if not labels or any("llvmpipe" in l or "softpipe" in l for l in labels):
    sys.exit("the benchmarks did not render on a GPU")
PY
python3 tests/bench/table.py build/gpu/render.json build/gpu/serve.json build/gpu/analysis.json
