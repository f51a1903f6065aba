#!/usr/bin/env bash
# The TypeScript client's tests: npm ci (the lock file's versions, from npm's registry), the
# messages generated from proto/ and compiled, then Node's test runner against GVD_SERVER.
# Usage: bash client/ts/run-tests.sh GVD_SERVER
set -euo pipefail
cd "$(dirname "$0")"
export GVD_SERVER
GVD_SERVER=$(realpath "$1")
npm ci --no-audit --no-fund --loglevel=error
npm test
