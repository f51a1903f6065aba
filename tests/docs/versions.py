#!/usr/bin/python3
"""One version across the project: CMakeLists.txt's project() version is the one gvd-server
--version prints, the Python and TypeScript packages carry, and CHANGELOG.md's newest entry
names. Prints each disagreement and exits 1 if there is one.

Usage: versions.py ROOT GVD_SERVER"""
import json
import re
import subprocess
import sys


def read(root, path):
    with open(f"{root}/{path}", encoding="utf-8") as f:
        return f.read()


def main(root, server):
    want = re.search(r"project\(gvd VERSION (\S+)", read(root, "CMakeLists.txt")).group(1)
    printed = subprocess.run([server, "--version"], capture_output=True, text=True, check=True).stdout
    found = {
        "gvd-server --version": printed.split()[-1] if printed.startswith("gvd-server ") else printed,
        "client/python/pyproject.toml": re.search(r'^version = "([^"]+)"', read(root, "client/python/pyproject.toml"), re.M).group(1),
        "client/python/gvd/__init__.py": re.search(r'^__version__ = "([^"]+)"', read(root, "client/python/gvd/__init__.py"), re.M).group(1),
        "client/ts/package.json": json.loads(read(root, "client/ts/package.json"))["version"],
        "CHANGELOG.md": re.search(r"^## (\S+)", read(root, "CHANGELOG.md"), re.M).group(1),
    }
    bad = [f"{where}: {v!r}, not {want!r} (CMakeLists.txt)" for where, v in found.items() if v != want]
    for line in bad:
        print(line)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
