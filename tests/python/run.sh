#!/usr/bin/env bash
# The Python client's tests, on the package as a user gets it: an sdist built from a copy of
# client/python alone (no proto/, no protoc on the PATH), a wheel built from that sdist, the
# wheel installed offline (Debian's grpcio, protobuf and NumPy; pip --no-build-isolation) into
# a new virtual environment made with --system-site-packages, as its README says; then pytest
# against GVD_SERVER.
# Usage: bash tests/python/run.sh GVD_SERVER [VENV_DIR]
set -euo pipefail
cd "$(dirname "$0")/../.."
server=$(realpath "$1")
venv=$(realpath -m "${2:-build/python-venv}")
rm -rf "$venv"
/usr/bin/python3 -m venv --system-site-packages "$venv"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# A copy of the folder alone, so that the build sees nothing else of the checkout and leaves
# nothing in it; a PATH of the environment's python alone, so that nothing calls protoc.
cp -r client/python "$work/python"
mkdir "$work/bin" "$work/dist"
ln -s "$venv/bin/python" "$work/bin/python"
(cd "$work/python" && PATH=$work/bin python -c \
  'from setuptools import build_meta; build_meta.build_sdist("../dist")' >/dev/null)
sdist=$(echo "$work"/dist/gvd-*.tar.gz)
PATH=$work/bin "$venv/bin/pip" wheel -q --no-build-isolation --no-index --no-deps -w "$work/dist" "$sdist"
wheel=$(echo "$work"/dist/gvd-*.whl)
PATH=$work/bin "$venv/bin/pip" install -q --no-index "$wheel"
cd "$work"  # away from the checkout's client/python, which would shadow the installed package
GVD_SERVER=$server "$venv/bin/python" -m pytest -q -p no:cacheprovider "$OLDPWD/tests/python"
