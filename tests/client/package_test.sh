#!/usr/bin/env bash
# The C++ client as another project gets it: the build's "client" component installed into a
# fresh prefix, a project of its own (tests/client/package) built with find_package(gvd) and
# gvd::client, run against a real server; the package names nothing of GL or PostgreSQL.
# Usage: bash tests/client/package_test.sh BUILD_DIR GVD_SERVER
set -euo pipefail
build=$(realpath "$1")
server=$(realpath "$2")
here=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=tests/support/server.sh
source "$here/../support/server.sh"
cmake --install "$build" --component client --prefix "$work/prefix" >/dev/null
if grep -rliE 'opengl|egl|postgres|libpq|sqlite' "$work/prefix/lib/cmake/gvd"; then
  echo "FAIL: the installed package names GL or a store (above)"
  exit 1
fi
cmake -S "$here/package" -B "$work/user" -G Ninja -DCMAKE_PREFIX_PATH="$work/prefix" >/dev/null
cmake --build "$work/user" >/dev/null
gvd_server_start "$server"
got=$("$work/user/nearest" "127.0.0.1:$port" 12 11)
# The oracle: a at (10, 10) is nearest to (12, 11), at sqrt(5).
want="a $(python3 -c 'import math; print("%.17g" % math.hypot(2, 1))')"
[[ $got == "$want" ]] || { echo "FAIL: got '$got', want '$want'"; exit 1; }
echo "find_package(gvd) builds a client that answers: $got"
