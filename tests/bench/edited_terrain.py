#!/usr/bin/env python3
"""Writes an image sequence of a terrain being edited: frame 0 a smooth 512 x 512 terrain, each
frame after it the one before with one more bump (0.1 high, radius 8 texels) at another place, as
16-bit PGM files DIR/h_0.pgm .. h_<N-1>.pgm. What docs/figures.md times `sequence` on (a frame's
cone map updated where the frame changed, against a whole bake of it).

    python3 tests/bench/edited_terrain.py DIR [FRAMES]
"""
import math
import os
import struct
import sys


def main():
    if len(sys.argv) not in (2, 3):
        sys.exit(__doc__)
    out_dir = sys.argv[1]
    frames = int(sys.argv[2]) if len(sys.argv) == 3 else 5
    n = 512
    os.makedirs(out_dir, exist_ok=True)
    heights = [[0.35 + 0.1 * math.sin(i * 0.05) * math.cos(j * 0.04) + 0.05 * math.sin(i * 0.013 + j * 0.021)
                for j in range(n)] for i in range(n)]
    for frame in range(frames):
        if frame > 0:
            ci, cj = (100 + 60 * frame) % n, (150 + 40 * frame) % n
            for i in range(max(0, ci - 9), min(n, ci + 10)):
                for j in range(max(0, cj - 9), min(n, cj + 10)):
                    d = ((i - ci) ** 2 + (j - cj) ** 2) / 64.0
                    if d < 1.0:
                        heights[i][j] += 0.1 * (1.0 - d)
        data = bytearray()
        for row in heights:
            data += struct.pack(">%dH" % n, *[int(min(1.0, max(0.0, v)) * 65535 + 0.5) for v in row])
        path = os.path.join(out_dir, "h_%d.pgm" % frame)
        with open(path + ".tmp", "wb") as f:
            f.write(b"P5\n%d %d\n65535\n" % (n, n))
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(path + ".tmp", path)


if __name__ == "__main__":
    main()
