#!/usr/bin/env bash
# The TypeScript client's tests: npm ci (the lock file's versions, from npm's registry); its
# generated messages (src/gen, kept in the tree) checked against what protoc makes of proto/
# now; then, from a copy of this folder alone with no protoc on the PATH, npm pack, and the
# tarball installed into a new project that imports it and its browser bundle; then the
# build and Node's test runner against GVD_SERVER; last, the selection app's copy of the bundle
# (server/web/gvd-client.js, kept in the tree so the server builds without npm) checked against
# the bundle just built.
# Usage: bash client/ts/run-tests.sh GVD_SERVER
set -euo pipefail
cd "$(dirname "$0")"
export GVD_SERVER
GVD_SERVER=$(realpath "$1")
npm ci --no-audit --no-fund --loglevel=error
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/gen"
protoc --plugin=protoc-gen-es=./node_modules/.bin/protoc-gen-es --es_out="$work/gen" \
  --es_opt=target=ts,import_extension=js -I ../../proto gvd/v1/voronoi.proto
if ! diff -r -q "$work/gen" src/gen >/dev/null; then
  echo "client/ts/src/gen is stale: run npm run generate in client/ts (it needs protoc)" >&2
  exit 1
fi
mkdir "$work/bin" "$work/copy" "$work/user"
for tool in node npm sh; do ln -s "$(command -v "$tool")" "$work/bin/$tool"; done
tar --exclude=./dist --exclude='./*.tgz' -cf - . | tar -xf - -C "$work/copy"
(cd "$work/copy" && PATH=$work/bin npm pack --silent --pack-destination "$work" >/dev/null)
(cd "$work/user" && npm init -y >/dev/null &&
  npm install --no-audit --no-fund --loglevel=error "$work"/gvd-client-*.tgz &&
  node --input-type=module -e '
    import { createGvdClient, Code } from "@gvd/client";
    const bundle = await import("@gvd/client/bundle");
    if (typeof createGvdClient !== "function" || typeof bundle.createGvdClient !== "function" ||
        Code.NotFound !== 5) throw new Error("the packed client does not import");')
echo "npm pack from the folder alone: installs and imports"
npm test
if ! cmp -s dist/gvd-client.bundle.js ../../server/web/gvd-client.js; then
  echo "server/web/gvd-client.js is stale: run npm run app in client/ts" >&2
  exit 1
fi
