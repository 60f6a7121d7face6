#!/usr/bin/env python3
"""A small EPI-like 4-D NIfTI-1 file for the README's 4-D figure and frame-change timing:
64x64x32 voxels of 3x3x3.5 mm, 20 frames of 2 s, int16; an ellipsoidal head (600, its core
800) with uniform noise (+-20, seeded) and a 5-voxel "activation" whose signal follows a sine
(+-40) over the frames. Standard library only. Usage: cine_phantom.py OUT.nii"""
import math
import random
import struct
import sys

NX, NY, NZ, NT = 64, 64, 32, 20


def header():
    h = bytearray(352)
    struct.pack_into('<i', h, 0, 348)
    for i, d in enumerate([4, NX, NY, NZ, NT, 1, 1, 1]):
        struct.pack_into('<h', h, 40 + 2 * i, d)
    struct.pack_into('<h', h, 70, 4)  # datatype int16
    struct.pack_into('<h', h, 72, 16)  # bitpix
    for i, p in enumerate([1, 3, 3, 3.5, 2.0]):
        struct.pack_into('<f', h, 76 + 4 * i, p)  # pixdim: mm, then the frame time in s
    struct.pack_into('<f', h, 108, 352.0)  # vox_offset
    struct.pack_into('<f', h, 112, 1.0)  # scl_slope
    h[123] = 2 | 8  # xyzt_units: mm, s
    struct.pack_into('<h', h, 254, 1)  # sform_code: scanner
    rows = [[3, 0, 0, -96], [0, 3, 0, -96], [0, 0, 3.5, -56]]
    for r, row in enumerate(rows):
        for c, v in enumerate(row):
            struct.pack_into('<f', h, 280 + 16 * r + 4 * c, v)
    h[344:348] = b'n+1\0'
    return h


def value(t, x, y, z):
    r = ((x - 32) / 26) ** 2 + ((y - 32) / 30) ** 2 + ((z - 16) / 14) ** 2
    if r >= 1:
        return random.randint(0, 15)
    active = (x - 40) ** 2 + (y - 30) ** 2 + (z - 18) ** 2 < 25
    v = 600 + (200 if r < 0.5 else 0) + random.randint(-20, 20)
    return int(v + (40 * math.sin(t / 3.0) if active else 0))


def main():
    random.seed(1)
    out = header()
    for t in range(NT):
        for z in range(NZ):
            for y in range(NY):
                for x in range(NX):
                    out += struct.pack('<h', value(t, x, y, z))
    with open(sys.argv[1], 'wb') as f:
        f.write(out)


if __name__ == '__main__':
    main()
