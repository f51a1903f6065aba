#!/usr/bin/env bash
# The server and the CLI as installed into a fresh prefix (cmake --install): the server starts
# without OpenImageIO in its memory, and its first image loads the image module from the
# prefix (lib/gvd beside bin/), not from the build folder; the image is a PNG of the scene's
# size whose pixels hold the sites' colours (two sites: two colours, no empty pixel).
# Usage: bash tests/server/install_test.sh BUILD_DIR
set -euo pipefail
build=$(realpath "$1")
# shellcheck source=tests/support/server.sh
source "$(dirname "$0")/../support/server.sh"
cmake --install "$build" --prefix "$work/prefix" >/dev/null
gvd_server_start "$work/prefix/bin/gvd-server"
gvd() { "$work/prefix/bin/gvd" --server "127.0.0.1:$port" "$@"; }
# mapped NAME: the paths of the files whose name holds NAME in the server's memory.
mapped() { awk -v n="$1" 'index($6, n) {print $6}' "/proc/$gvd_server_pid/maps" | sort -u; }

if [[ -n $(mapped libOpenImageIO) || -n $(mapped libgvd_image_codec) ]]; then
  echo "FAIL: the server loaded OpenImageIO before any image:"
  mapped libOpenImageIO
  mapped libgvd_image_codec
  exit 1
fi
gvd scene create two --window 0,0,10,10 --size 40x30 >/dev/null
gvd --scene two sites add a 2 2 b 8 8 >/dev/null
gvd render two -o "$work/two.png" >/dev/null
module=$(mapped libgvd_image_codec)
if [[ $module != "$work/prefix/"*/gvd/libgvd_image_codec.so ]]; then
  echo "FAIL: the image module came from '$module', not from the prefix $work/prefix"
  exit 1
fi
# The image read apart from OpenImageIO (Python's zlib and PNG's filters undone here): 40x30
# RGB, each pixel the colour of the site nearer to its centre (the bisector x + y = 10 aside),
# one colour for each site, none black.
python3 - "$work/two.png" <<'EOF'
import math, struct, sys, zlib
data = open(sys.argv[1], "rb").read()
assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
at, idat, header = 8, b"", None
while at < len(data):
    (n,) = struct.unpack(">I", data[at:at + 4])
    kind, body = data[at + 4:at + 8], data[at + 8:at + 8 + n]
    if kind == b"IHDR":
        header = struct.unpack(">IIBBBBB", body)
    elif kind == b"IDAT":
        idat += body
    at += 12 + n
width, height, depth, colour_type, _, _, interlace = header
assert (width, height, depth, colour_type, interlace) == (40, 30, 8, 2, 0), header
raw, stride, rows, above = zlib.decompress(idat), 3 * width, [], bytearray(3 * width)
for r in range(height):
    kind, line = raw[r * (stride + 1)], bytearray(raw[r * (stride + 1) + 1:(r + 1) * (stride + 1)])
    for i in range(stride):
        left = line[i - 3] if i >= 3 else 0
        up, corner = above[i], above[i - 3] if i >= 3 else 0
        if kind == 1: line[i] = (line[i] + left) & 255
        elif kind == 2: line[i] = (line[i] + up) & 255
        elif kind == 3: line[i] = (line[i] + (left + up) // 2) & 255
        elif kind == 4:
            p = left + up - corner
            pa, pb, pc = abs(p - left), abs(p - up), abs(p - corner)
            line[i] = (line[i] + (left if pa <= pb and pa <= pc else up if pb <= pc else corner)) & 255
        else: assert kind == 0, kind
    rows.append(line)
    above = line
colours = {"a": set(), "b": set()}
for r, line in enumerate(rows):  # row 0 at the top of the window (y = 10)
    for x in range(width):
        cx, cy = (x + 0.5) * 10 / width, 10 - (r + 0.5) * 10 / height
        da, db = math.hypot(cx - 2, cy - 2), math.hypot(cx - 8, cy - 8)
        if abs(da - db) > 0.5:
            colours["a" if da < db else "b"].add(bytes(line[3 * x:3 * x + 3]))
assert len(colours["a"]) == 1 and len(colours["b"]) == 1, colours
assert colours["a"] != colours["b"] and b"\0\0\0" not in colours["a"] | colours["b"], colours
print(f"a {width}x{height} image: site a {colours['a'].pop().hex()}, b {colours['b'].pop().hex()}")
EOF
echo "installed server: OpenImageIO loaded at the first image, from $module"
