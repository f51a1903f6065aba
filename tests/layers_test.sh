#!/usr/bin/env bash
# The layers as the design promises them, checked on the sources: each rule a folder and the
# includes (or words) it must not hold. Prints every line that breaks a rule; exits 1 then.
set -euo pipefail
cd "$(dirname "$0")/.."

failed=0
# forbid FOLDER REGEX WHY: no line of the C++ sources under FOLDER matches REGEX.
forbid() {
  local folder=$1 regex=$2 why=$3 hits
  hits=$(grep -rnE --include='*.h' --include='*.cc' "$regex" "$folder" || true)
  if [[ -n $hits ]]; then
    echo "$folder: $why:"
    echo "$hits"
    failed=1
  fi
}

forbid client '#include "(server|render)/' "a client knows only the proto"
forbid render '#include "(server|client)/' "the engine knows no service and no client"
forbid server/app '#include "(render/gl|server/grpc|server/http)/' \
  "the core renders through the seam and knows no transport"
forbid server/grpc '#include "render/(plan|analysis|gl)/' "a transport only translates"
forbid server/http '#include "render/(plan|analysis|gl)/' "a transport only translates"
forbid server/http 'grpcpp|grpc::' "HTTP calls the core, not gRPC"

# One scene handle over the dimension: few lines at the edges name the 3D scene.
edges=$(grep -rnE '\bScene3\b|scene3|Find3' server/grpc server/http server/app || true)
count=$(grep -c . <<<"$edges" || true)
if ((count > 6)); then
  echo "server/{grpc,http,app}: $count lines name a dimension's scene (at most 6):"
  echo "$edges"
  failed=1
fi

((failed == 0)) && echo "layers hold"
exit "$failed"
