#!/usr/bin/env bash
# The Python client's tests: installs client/python offline (Debian's grpcio, protobuf and
# NumPy, pip --no-build-isolation) into a virtual environment made with
# --system-site-packages, as its README says, then runs pytest against GVD_SERVER.
# Usage: bash tests/python/run.sh GVD_SERVER [VENV_DIR]
set -euo pipefail
cd "$(dirname "$0")/../.."
server=$(realpath "$1")
venv=${2:-build/python-venv}
rm -rf "$venv"
/usr/bin/python3 -m venv --system-site-packages "$venv"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# A copy, so that the build leaves nothing in the checkout.
cp -r client/python "$work/python"
GVD_PROTO_DIR=$PWD/proto "$venv/bin/pip" install -q --no-build-isolation --no-index "$work/python"
cd "$work"  # away from the checkout's client/python, which would shadow the installed package
GVD_SERVER=$server "$venv/bin/python" -m pytest -q -p no:cacheprovider "$OLDPWD/tests/python"
