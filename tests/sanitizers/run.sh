#!/usr/bin/env bash
# The sanitizer builds, as CI runs them after the test suite:
#  - ASan + UBSan: the test suite, but for the few tests noted below. LeakSanitizer checks the unit tests; it is off where
#    Mesa is loaded (GL tests, the server), as Mesa keeps driver allocations until exit.
#  - TSan: the server's concurrency tests (scene writers and readers, render thread, frame publication, watch streams, concurrent
#    queries and updates, crash and load tests), not the single-threaded CLI's (CliTest), whose calls the server tests here
#    make of the server too; with gRPC/protobuf/abseil suppressed: Debian
#    builds them without TSan, so it cannot see their synchronization (tsan.supp). This build
#    links gRPC's shared libraries (GVD_GRPC_STATIC=OFF), which those suppressions name
#    (called_from_lib): linked in, gRPC's socket and memory calls reach TSan as the
#    executable's own, unsuppressed, and their fds and frees read as races.
# Usage: bash tests/sanitizers/run.sh   (after bash tests/run-tests.sh installed the packages)
set -euo pipefail
cd "$(dirname "$0")/../.."
root=$PWD
jobs=$(nproc)
# -O1 and -g1: the build type's own -O2 -g would come after CMAKE_CXX_FLAGS and win, and
# compiles these builds in about twice the time (one test file under ASan: 71 s against 30 s).
# -g1 keeps line tables, function names and inlined frames: what the sanitizers' stack traces
# and TSan's suppressions by function name read.
opt="-O1 -g1 -DNDEBUG"

cmake -S . -B build/asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DGVD_WERROR=OFF \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="$opt" \
  -DCMAKE_CXX_FLAGS="-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined" \
  -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" >/dev/null
cmake --build build/asan --target gvd_unit_tests gvd_core_tests gvd_render_gl_tests gvd_integration_tests \
  gvd_server_unit_tests gvd_app_tests gvd_app_gl_tests gvd-server gvd gvd_fuzz_requests_replay gvd_fuzz_geometry_replay \
  gvd_fuzz_store_replay gvd_fuzz_http_replay gvd_fuzz_model_replay
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
(cd build/asan && ASAN_OPTIONS=detect_leaks=1 ctest --output-on-failure -j "$jobs" -R '^(Cone|Build|Frame|Exact|Nearest|Coverage|SiteIndex|Snapshot|SceneCore|Codec|Store\.|CpuPool|BoundaryEdges|TraceBoundaries|NeighborPairs|HiddenSites|GeometryMeetsBox|TrianglesFromEdges|Volume|fuzz_)')
# Some tests run in the plain build only, as they run no code of this build that the tests
# here do not: the browser tests (browser_*) and the clients' (python_client, ts_client)
# test code this build does not compile, against the calls HttpTest and ServerTest make
# here; the soak runs (soak_*) are a minute of the mixed load LoadTest drives here; the
# image tests (container_*, compose_*) run no code of this build; the C++ client's package
# test (cpp_client_package) links this build's client into a project built without the
# sanitizers, whose own calls ServerTest makes here.
(cd build/asan && ASAN_OPTIONS=detect_leaks=0 ctest --output-on-failure -j "$jobs" --timeout 900 \
  -E '^(Cone|Build|Frame|Exact|Nearest|Coverage|SiteIndex|Snapshot|SceneCore|Codec|Store\.|CpuPool|BoundaryEdges|TraceBoundaries|NeighborPairs|HiddenSites|GeometryMeetsBox|TrianglesFromEdges|Volume|fuzz_|deploy_lint|docs_|browser_|container_|compose_|python_|ts_client|cpp_client_|soak_)')

cmake -S . -B build/tsan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DGVD_WERROR=OFF -DGVD_GRPC_STATIC=OFF \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="$opt" -DCMAKE_CXX_FLAGS="-fsanitize=thread" -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=thread" >/dev/null
cmake --build build/tsan --target gvd_core_tests gvd_integration_tests gvd_server_unit_tests \
  gvd_app_tests gvd_app_gl_tests gvd-server
export TSAN_OPTIONS="halt_on_error=1 suppressions=$root/tests/sanitizers/tsan.supp"
(cd build/tsan && ctest --output-on-failure -j "$jobs" --timeout 900 \
  -R '^(SceneCore|SceneRegistry|Replicas|ReplicaFaults|Engines/LogStore|ServiceThreads|Store|CpuPool|PendingEventTest|MemoryBudgetUnit|FairRenders|ServerTest|SpaceServerTest|LoadTest|CrashTest|MetricsTest|AnalysisServerTest|AnalysisLimitsTest|WatchTest|WatchDrain|WatchReplicas|HttpTest|HttpSecurity|HttpDrain|HttpConversions|MosaicServerTest|GrpcPort)\.' \
  -E '^(Server|SpaceServer)Test\.TenThousand.*$')
# The ten-thousand-site accuracy tests (ServerTest.TenThousand*, SpaceServerTest.TenThousand*:
# one client, each answer against the oracle, a fifth of this run's time) are left out of
# TSan only: the threads they use serve every other server test here.
echo "sanitizer builds pass"
