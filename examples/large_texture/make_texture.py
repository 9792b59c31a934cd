#!/usr/bin/env python3
"""Writes big.ppm beside this file: 4096 x 4096 8-bit RGB texels (48 MiB), a checkerboard of two
colours with noise, for close.rib. Deterministic; the standard library only."""
import pathlib
import random

SIDE, SQUARE = 4096, 64
noise = random.Random(1)
# Two colours, each byte of noise mapped to a shade around it.
shades = [bytes(min(255, base + b % 48) for b in range(256)) for base in (150, 40, 90, 20, 40, 120)]
rows = []
for y in range(SIDE):
    row = bytearray(noise.randbytes(3 * SIDE))
    for x0 in range(0, SIDE, SQUARE):
        dark = (x0 // SQUARE + y // SQUARE) % 2
        for c in range(3):
            span = slice(3 * x0 + c, 3 * (x0 + SQUARE), 3)
            row[span] = bytes(row[span]).translate(shades[3 * dark + c])
    rows.append(bytes(row))
out = pathlib.Path(__file__).with_name("big.ppm")
out.write_bytes(b"P6\n%d %d\n255\n" % (SIDE, SIDE) + b"".join(rows))
print(out)
