#!/usr/bin/env bash
# The Python client's generated messages (client/python/gvd/v1/voronoi_pb2.py, kept in the
# tree so that the package builds without protoc) are those protoc makes of proto/ now.
set -euo pipefail
cd "$(dirname "$0")/../.."
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
protoc -I proto --python_out "$work" gvd/v1/voronoi.proto
if ! cmp -s "$work/gvd/v1/voronoi_pb2.py" client/python/gvd/v1/voronoi_pb2.py; then
  echo "client/python/gvd/v1/voronoi_pb2.py is stale: run, from the repository's root," >&2
  echo "  protoc -I proto --python_out client/python gvd/v1/voronoi.proto" >&2
  exit 1
fi
echo "client/python's messages are fresh"
