#!/usr/bin/env python3
"""Writes the test environment of `mitsuba_compare.py` (`write_envmap`) with the standard
library alone: an uncompressed float32 scanline EXR, 256x128, equirectangular. A sky
gradient, a colour ramp in azimuth (fading at the poles) and a bright blob (sigma 12 deg)
toward Mitsuba-local (theta 55, phi 70): no symmetry that would hide a wrong orientation.

    python3 tools/scripts/test_envmap.py OUT.exr [--upside-down]

--upside-down mirrors it through the horizon (the blob 55 deg from the nadir, the bright
side of the gradient below): light from under the sheet, for the transmission term
(runtime/ENV_MEASUREMENTS.md, "Light through the cloth").
"""
import math
import struct
import sys


def pixel(x, y, width, height):
    v, u = (y + 0.5) / height, (x + 0.5) / width
    theta, phi = v * math.pi, u * 2 * math.pi
    d = (math.sin(theta) * math.sin(phi), math.cos(theta), -math.sin(theta) * math.cos(phi))
    bt, bp = math.radians(55.0), math.radians(70.0)
    b = (math.sin(bt) * math.sin(bp), math.cos(bt), -math.sin(bt) * math.cos(bp))
    ang = math.acos(max(-1.0, min(1.0, sum(p * q for p, q in zip(d, b)))))
    blob = 6.0 * math.exp(-0.5 * (ang / math.radians(12.0)) ** 2)
    up, st = max(0.0, min(1.0, d[1])), math.sin(theta)
    return (0.2 + 0.3 * up + 0.1 * st * math.sin(phi) + blob * 1.0,
            0.25 + 0.2 * up + 0.1 * st * math.cos(phi) + blob * 0.8,
            0.15 + 0.4 * up + blob * 0.5)


def attr(name, kind, data):
    return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(data)) + data


def write_exr(path, width, height, f):
    channels = b"".join(c.encode() + b"\0" + struct.pack("<i", 2) + b"\0\0\0\0" + struct.pack("<ii", 1, 1) for c in "BGR") + b"\0"
    window = struct.pack("<iiii", 0, 0, width - 1, height - 1)
    header = b"\x76\x2f\x31\x01" + struct.pack("<i", 2)
    header += attr("channels", "chlist", channels) + attr("compression", "compression", b"\0")
    header += attr("dataWindow", "box2i", window) + attr("displayWindow", "box2i", window)
    header += attr("lineOrder", "lineOrder", b"\0") + attr("pixelAspectRatio", "float", struct.pack("<f", 1.0))
    header += attr("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0)) + attr("screenWindowWidth", "float", struct.pack("<f", 1.0)) + b"\0"
    lines = []
    for y in range(height):
        row = [f(x, y, width, height) for x in range(width)]
        data = b"".join(struct.pack("<f", p[c]) for c in (2, 1, 0) for p in row)  # B, G, R planes
        lines.append(struct.pack("<ii", y, len(data)) + data)
    offset, table = len(header) + 8 * height, b""
    for line in lines:
        table += struct.pack("<Q", offset)
        offset += len(line)
    with open(path, "wb") as out:
        out.write(header + table + b"".join(lines))


if __name__ == "__main__":
    if len(sys.argv) not in (2, 3) or (len(sys.argv) == 3 and sys.argv[2] != "--upside-down"):
        sys.exit(__doc__)
    flip = len(sys.argv) == 3
    write_exr(sys.argv[1], 256, 128, (lambda x, y, w, h: pixel(x, h - 1 - y, w, h)) if flip else pixel)
