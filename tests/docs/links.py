#!/usr/bin/python3
"""Every relative link of the project's Markdown files resolves: each [text](target) and
![alt](target) whose target is not a URL or an anchor names a file or folder that exists,
relative to the file that links it (the #fragment aside). Prints each broken link as
FILE:LINE: TARGET and exits 1 if there is one.

Usage: links.py ROOT (the repository: its Markdown files outside build/ and node_modules/)."""
import os
import re
import sys

LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
SKIP_DIRS = {"build", "node_modules", ".git", "dist"}


def markdown_files(root):
    for folder, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if d not in SKIP_DIRS)
        for name in sorted(files):
            if name.endswith(".md"):
                yield os.path.join(folder, name)


def broken_links(path):
    in_code = False
    with open(path, encoding="utf-8") as f:
        for number, line in enumerate(f, 1):
            if line.lstrip().startswith("```"):
                in_code = not in_code
                continue
            if in_code:
                continue
            for target in LINK.findall(re.sub(r"`[^`]*`", "", line)):
                if re.match(r"^[a-z][a-z0-9+.-]*:", target) or target.startswith("#"):
                    continue
                file_part = target.split("#", 1)[0]
                if not os.path.exists(os.path.join(os.path.dirname(path), file_part)):
                    yield number, target


def main():
    root = sys.argv[1]
    files = list(markdown_files(root))
    bad = [(p, n, t) for p in files for n, t in broken_links(p)]
    for p, n, t in bad:
        print(f"{os.path.relpath(p, root)}:{n}: {t}")
    print(f"{len(files)} Markdown files, {len(bad)} broken links")
    return 1 if bad or not files else 0


if __name__ == "__main__":
    sys.exit(main())
