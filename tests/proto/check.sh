#!/usr/bin/env bash
# The API's checks with buf (npm's @bufbuild/buf, at the version package-lock.json holds):
# STANDARD lint of proto/ (proto/buf.yaml), and no breaking change, in WIRE_JSON mode (JSON
# clients read field and enum names), against the previous commit's proto/.
# Usage: bash tests/proto/check.sh
set -euo pipefail
cd "$(dirname "$0")"
npm ci --no-audit --no-fund --loglevel=error >/dev/null
buf=$PWD/node_modules/.bin/buf
cd ../..
"$buf" lint proto
echo "buf lint: proto/ keeps the STANDARD rules"
# The repository's own git directory (a worktree's is shared), and the commit before this one
# by its hash (a worktree's HEAD is not the shared directory's).
git_dir=$(git rev-parse --path-format=absolute --git-common-dir)
if ! git rev-parse --verify --quiet HEAD~1 >/dev/null && git remote get-url origin >/dev/null 2>&1; then
  git fetch --quiet --deepen=1 origin  # a shallow clone: its parent commit from its origin
fi
if ! previous=$(git rev-parse --verify --quiet HEAD~1); then
  echo "buf breaking: this clone has no commit before HEAD to compare with" >&2
  exit 1
fi
"$buf" breaking proto --against "$git_dir#ref=$previous,subdir=proto"
echo "buf breaking: proto/ breaks nothing of HEAD~1's, in WIRE_JSON mode"
