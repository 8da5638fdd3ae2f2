#!/usr/bin/env python3
"""Write a 256x256 8-bit greyscale PNG of a shaded, textured sphere on black (stdlib only).

Usage: sphere_png.py OUT.png   (the sphere: cx = cy = 127.5, r = 116)
"""
import math
import struct
import sys
import zlib

SIZE, R = 256, 116.0


def chunk(kind, data):
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def main(path):
    c = (SIZE - 1) / 2
    rows = bytearray()
    for y in range(SIZE):
        rows.append(0)  # filter: none
        for x in range(SIZE):
            dx, dy = (x - c) / R, (y - c) / R
            d2 = dx * dx + dy * dy
            if d2 > 1.0:
                rows.append(0)
                continue
            nz = math.sqrt(1.0 - d2)
            v = 40 + 150 * nz + 30 * math.sin(9 * dx) * math.cos(7 * dy) + 25 * max(0.0, -dx - dy) ** 8
            rows.append(max(0, min(255, int(v))))
    png = b"\x89PNG\r\n\x1a\n"
    png += chunk(b"IHDR", struct.pack(">IIBBBBB", SIZE, SIZE, 8, 0, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(bytes(rows), 9))
    png += chunk(b"IEND", b"")
    with open(path, "wb") as f:
        f.write(png)


if __name__ == "__main__":
    main(sys.argv[1])
