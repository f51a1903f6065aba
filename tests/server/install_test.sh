#!/usr/bin/env bash
# The server and the CLI as installed into a fresh prefix (cmake --install): each starts without
# OpenImageIO in its memory and loads the module of OpenImageIO's calls from the prefix (lib/gvd
# beside bin/), not from the build folder, when it first needs it: the server at its first
# image, the CLI at its first field. The files are read apart from OpenImageIO and held against
# the two sites: the image's pixels in the colour of the nearer site, the field's values the
# distance to it.
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
# The CLI: no OpenImageIO for a command that writes no field; its module from the prefix for
# one that does (the loader's own account, LD_DEBUG=files).
if LD_DEBUG=files gvd scene ls 2>&1 >/dev/null | grep -E 'file=lib(OpenImageIO|gvd_field_image)'; then
  echo "FAIL: the CLI loaded OpenImageIO for a command that writes no field (above)"
  exit 1
fi
loaded=$(LD_DEBUG=files gvd --scene two clearance -o "$work/clearance.png" 2>&1 >/dev/null)
field_module=$(sed -n 's/.*needed by \([^ ]*libgvd_field_image.so\) .*/\1/p' <<<"$loaded" | sort -u)
if [[ $field_module != "$work/prefix/"*/gvd/libgvd_field_image.so ]]; then
  echo "FAIL: the CLI's field module came from '$field_module', not from the prefix $work/prefix"
  exit 1
fi

# The files read with Python's zlib, PNG's filters undone here. Pixel (x, row) of 40x30 over
# [0, 10]^2 has its centre at ((x + 0.5) / 4, 10 - (row + 0.5) / 3), row 0 at the top.
python3 - "$work/two.png" "$work/clearance.png" <<'EOF'
import math, struct, sys, zlib

def read_png(path):
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", path + " is not a PNG"
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
    assert interlace == 0 and depth in (8, 16) and colour_type in (0, 2), header
    bpp = (3 if colour_type == 2 else 1) * depth // 8
    raw, stride, rows, above = zlib.decompress(idat), bpp * width, [], bytearray(bpp * width)
    for r in range(height):
        kind, line = raw[r * (stride + 1)], bytearray(raw[r * (stride + 1) + 1:(r + 1) * (stride + 1)])
        for i in range(stride):
            left = line[i - bpp] if i >= bpp else 0
            up, corner = above[i], above[i - bpp] if i >= bpp else 0
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
    return width, height, depth, colour_type, rows

def centre(x, r):
    return (x + 0.5) * 10 / 40, 10 - (r + 0.5) * 10 / 30

distances = lambda cx, cy: (math.hypot(cx - 2, cy - 2), math.hypot(cx - 8, cy - 8))

# The image: 8-bit RGB, each pixel away from the bisector x + y = 10 in its nearer site's
# colour, one colour a site, none black.
width, height, depth, colour_type, rows = read_png(sys.argv[1])
assert (width, height, depth, colour_type) == (40, 30, 8, 2)
colours = {"a": set(), "b": set()}
for r, line in enumerate(rows):
    for x in range(width):
        da, db = distances(*centre(x, r))
        if abs(da - db) > 0.5:
            colours["a" if da < db else "b"].add(bytes(line[3 * x:3 * x + 3]))
assert len(colours["a"]) == 1 and len(colours["b"]) == 1, colours
assert colours["a"] != colours["b"] and b"\0\0\0" not in colours["a"] | colours["b"], colours

# The clearance field: 16-bit grey, the distance to the nearer site scaled so that the largest
# is 65535; within 1% of the largest (the raster's bound is far below it).
width, height, depth, colour_type, rows = read_png(sys.argv[2])
assert (width, height, depth, colour_type) == (40, 30, 16, 0)
truth = [[min(distances(*centre(x, r))) for x in range(width)] for r in range(height)]
top = max(max(row) for row in truth)
worst = max(abs((line[2 * x] << 8 | line[2 * x + 1]) / 65535 * top - truth[r][x])
            for r, line in enumerate(rows) for x in range(width))
assert worst <= 0.01 * top, f"clearance off by {worst} (largest {top})"
print(f"image: sites a {colours['a'].pop().hex()}, b {colours['b'].pop().hex()}; "
      f"clearance within {worst:.4f} of the distances (largest {top:.3f})")
EOF
echo "installed: the server's module from $module, the CLI's from $field_module"
