#!/usr/bin/python3
"""Writes the seed corpus of the fuzz_image target (tests/fuzz/corpus/image/): small height images in
every format the target picks, whole and cut short, each prefixed with the target's two choice bytes
(format index, load settings; see fuzz_image.cpp).

Usage: /usr/bin/python3 tests/fuzz/make_image_corpus.py EXR_FILE
EXR_FILE is a small float EXR with a `height` channel and displace's mapping attributes, as
`displace sim` writes it (an EXR writer is not in Debian's python); the other formats are made with
Pillow (python3-pil, which python3-matplotlib brings) and, for Radiance HDR, by hand.
"""
import io
import math
import pathlib
import struct
import sys

from PIL import Image

FORMATS = ["png", "jpg", "exr", "tif", "bmp", "hdr"]  # fuzz_image.cpp's order
out = pathlib.Path(__file__).resolve().parent / "corpus" / "image"
out.mkdir(parents=True, exist_ok=True)


def heights(w, h):
    return [[0.5 + 0.5 * math.sin(0.7 * x) * math.cos(0.5 * y) for x in range(w)] for y in range(h)]


def save(name, fmt, settings, data):
    (out / name).write_bytes(bytes([FORMATS.index(fmt), settings]) + data)
    # the same file cut after 60% of its bytes: the truncated-file paths
    (out / ("cut_" + name)).write_bytes(bytes([FORMATS.index(fmt), settings]) + data[: len(data) * 6 // 10])


def pillow(image, fmt, **options):
    buffer = io.BytesIO()
    image.save(buffer, format=fmt, **options)
    return buffer.getvalue()


def grey8(w, h):
    image = Image.new("L", (w, h))
    image.putdata([int(255 * v) for row in heights(w, h) for v in row])
    return image


def grey16(w, h):
    image = Image.new("I;16", (w, h))
    image.putdata([int(65535 * v) for row in heights(w, h) for v in row])
    return image


def rgb(w, h):
    g = grey8(w, h)
    return Image.merge("RGB", (g, g, g))


def radiance(w, h):
    header = f"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n".encode()
    pixels = bytearray()
    for row in heights(w, h):
        for v in row:
            mantissa, exponent = math.frexp(max(v, 1e-6))
            m = int(mantissa * 256)
            pixels += bytes([m, m, m, exponent + 128])
    return header + bytes(pixels)


save("grey8.png", "png", 0, pillow(grey8(16, 12), "PNG"))
save("grey16.png", "png", 1, pillow(grey16(8, 8), "PNG"))
save("rgb.png", "png", 2 | (1 << 2), pillow(rgb(8, 8), "PNG"))
save("grey.jpg", "jpg", 0, pillow(grey8(16, 16), "JPEG", quality=90))
save("rgb.jpg", "jpg", 2, pillow(rgb(16, 8), "JPEG", quality=75))
save("grey8.tif", "tif", 0, pillow(grey8(8, 8), "TIFF"))
save("grey16_lzw.tif", "tif", 1, pillow(grey16(8, 8), "TIFF", compression="tiff_lzw"))
save("grey.bmp", "bmp", 0, pillow(grey8(8, 6), "BMP"))
save("grey.hdr", "hdr", 2, radiance(8, 8))
save("grey_range.hdr", "hdr", 16, radiance(4, 4))
exr = pathlib.Path(sys.argv[1]).read_bytes()
save("height.exr", "exr", 0, exr)
save("height_range.exr", "exr", 16 | 1, exr)
print(f"{len(list(out.iterdir()))} files in {out}")
