"""Byte builders for the probe's inputs: NIfTI-1, NIfTI-2, ANALYZE pairs and gzip streams.

Decisions:
- Written from the NIfTI-1/2 header layouts (nifti1.h, nifti2.h) with `struct`, not through any
  reader or writer under test, so a bad field is exactly the bytes the probe says it is.
- One builder per format takes every header field as an optional override; a field that is not
  given gets the value a well-formed file would have (sform from pixdim, magic, vox_offset 352),
  so each variant changes one thing.
- Voxels are packed with `struct` in the header's byte order; numpy is not needed (the volumes
  are at most a few hundred thousand voxels).
- gzip streams are built by hand (header, raw deflate, CRC-32, ISIZE) where the probe needs to
  break one of them; `gzip.compress` is used for well-formed members.
"""

import random
import struct
import zlib

# name -> (datatype code, bitpix, struct format or None for types the probe never fills with
# values: complex, float128, RGB).
DATATYPES = {
    "uint8": (2, 8, "B"),
    "int16": (4, 16, "h"),
    "int32": (8, 32, "i"),
    "float32": (16, 32, "f"),
    "complex64": (32, 64, None),
    "float64": (64, 64, "d"),
    "rgb24": (128, 24, None),
    "int8": (256, 8, "b"),
    "uint16": (512, 16, "H"),
    "uint32": (768, 32, "I"),
    "int64": (1024, 64, "q"),
    "uint64": (1280, 64, "Q"),
    "float128": (1536, 128, None),
    "complex128": (1792, 128, None),
    "complex256": (2048, 256, None),
    "rgba32": (2304, 32, None),
}


def voxel_count(dims):
    """Product of the spatial and later dims (what a reader would allocate)."""
    n = 1
    for d in dims:
        n *= d
    return n


def pack_voxels(values, dtype, endian="<"):
    """Packs a flat list of numbers as `dtype` in the given byte order."""
    fmt = DATATYPES[dtype][2]
    if fmt is None:
        raise ValueError(f"{dtype} has no struct format; pass raw bytes")
    return struct.pack(f"{endian}{len(values)}{fmt}", *values)


def zero_bytes(dims, dtype):
    """All-zero voxel bytes for types without a struct format (complex, RGB, float128)."""
    return bytes(voxel_count(dims) * DATATYPES[dtype][1] // 8)


def blob(dims, noise=30.0, seed=12):
    """A small 'head': background 0, a shell near 300 (CSF-like), a ball near 600 (GM-like) and
    a core near 900 (WM-like), with Gaussian noise (fixed seed) so the histogram has three
    broad peaks and every voxel has a gradient: what the renderer's adaptive windows need to
    show something (noise-free plateaus give no peaks and a blank picture). Fits int16."""
    rnd = random.Random(seed)
    nx, ny, nz = (list(dims) + [1, 1, 1])[:3]
    cx, cy, cz = (nx - 1) / 2, (ny - 1) / 2, (nz - 1) / 2
    scale = max(min(nx, ny, nz) / 2, 1)
    out = []
    for z in range(nz):
        for y in range(ny):
            for x in range(nx):
                r = ((x - cx) ** 2 + (y - cy) ** 2 + (z - cz) ** 2) ** 0.5 / scale
                v = 900 if r < 0.45 else 600 if r < 0.7 else 300 if r < 0.9 else 0
                out.append(max(0, round(v + rnd.gauss(0, noise))) if v else 0)
    frames = voxel_count(dims) // max(len(out), 1)
    return out * frames


def _nifti1_defaults(dims, dtype):
    code, bitpix, _ = DATATYPES[dtype]
    return {
        "sizeof_hdr": 348,
        "dim0": len(dims),
        "dims": list(dims),
        "datatype": code,
        "bitpix": bitpix,
        "pixdim": [1.0] * 8,
        "vox_offset": 352.0,
        "scl_slope": 1.0,
        "scl_inter": 0.0,
        "qform_code": 0,
        "sform_code": 1,
        "quatern": (0.0, 0.0, 0.0),
        "qoffset": (0.0, 0.0, 0.0),
        "srow": None,
        "magic": b"n+1\0",
        "extension": b"\0\0\0\0",
        "xyzt_units": 2,
    }


def nifti1_header(dims, dtype="int16", endian="<", **over):
    """The 348-byte NIfTI-1 header (plus nothing); `over` replaces any field of the defaults."""
    f = _nifti1_defaults(dims, dtype)
    unknown = set(over) - set(f)
    if unknown:
        raise KeyError(f"unknown NIfTI-1 fields {sorted(unknown)}")
    f.update(over)
    h = bytearray(348)
    e = endian
    struct.pack_into(f"{e}i", h, 0, f["sizeof_hdr"])
    dim = [f["dim0"]] + list(f["dims"]) + [1] * 7
    struct.pack_into(f"{e}8h", h, 40, *dim[:8])
    struct.pack_into(f"{e}hh", h, 70, f["datatype"], f["bitpix"])
    pix = (list(f["pixdim"]) + [1.0] * 8)[:8]
    struct.pack_into(f"{e}8f", h, 76, *pix)
    struct.pack_into(f"{e}fff", h, 108, f["vox_offset"], f["scl_slope"], f["scl_inter"])
    struct.pack_into(f"{e}B", h, 123, f["xyzt_units"])
    struct.pack_into(f"{e}hh", h, 252, f["qform_code"], f["sform_code"])
    struct.pack_into(f"{e}3f", h, 256, *f["quatern"])
    struct.pack_into(f"{e}3f", h, 268, *f["qoffset"])
    srow = f["srow"] or [
        [pix[1], 0.0, 0.0, 0.0],
        [0.0, pix[2], 0.0, 0.0],
        [0.0, 0.0, pix[3], 0.0],
    ]
    for i, row in enumerate(srow):
        struct.pack_into(f"{e}4f", h, 280 + 16 * i, *row)
    h[344:348] = f["magic"][:4].ljust(4, b"\0")
    return bytes(h), f


def nifti1(dims, dtype="int16", data=None, endian="<", extra=b"", **over):
    """A single-file NIfTI-1 (.nii): header, the 4 extension bytes, `extra` (extensions or
    padding), then the voxels (`data` bytes, or the blob in `dtype`)."""
    ext = over.pop("extension", b"\0\0\0\0")
    header, f = nifti1_header(dims, dtype, endian, **over)
    if data is None:
        data = _default_data(f["dims"], dtype, endian)
    return header + ext + extra + data


def analyze_pair(dims, dtype="int16", endian="<", magic=b"ni1\0", **over):
    """A .hdr/.img pair as (header bytes, image bytes): NIfTI-1 'ni1' by default, or ANALYZE 7.5
    with magic=b'\\0\\0\\0\\0'."""
    header, f = nifti1_header(dims, dtype, endian, magic=magic, vox_offset=0.0, **over)
    return header, _default_data(f["dims"], dtype, endian)


def _default_data(dims, dtype, endian):
    if DATATYPES[dtype][2] is None:
        return zero_bytes(dims, dtype)
    values = blob(dims)
    if DATATYPES[dtype][1] == 8:
        values = [min(v // 8, 127) for v in values]  # fits int8 and uint8
    return pack_voxels(values, dtype, endian)


def nifti2(dims, dtype="int16", data=None, endian="<", **over):
    """A single-file NIfTI-2: 540-byte header, 4 extension bytes, voxels at 544. `dims` are int64
    (so 2^31 is representable); `data` defaults to the blob (only for small dims)."""
    code, bitpix, _ = DATATYPES[dtype]
    f = {
        "sizeof_hdr": 540,
        "magic": b"n+2\0\r\n\x1a\n",
        "dim0": len(dims),
        "dims": list(dims),
        "datatype": code,
        "bitpix": bitpix,
        "pixdim": [1.0] * 8,
        "vox_offset": 544,
        "scl_slope": 1.0,
        "scl_inter": 0.0,
        "sform_code": 1,
    }
    f.update(over)
    e = endian
    h = bytearray(540)
    struct.pack_into(f"{e}i", h, 0, f["sizeof_hdr"])
    h[4:12] = f["magic"][:8].ljust(8, b"\0")
    struct.pack_into(f"{e}hh", h, 12, f["datatype"], f["bitpix"])
    dim = [f["dim0"]] + list(f["dims"]) + [1] * 7
    struct.pack_into(f"{e}8q", h, 16, *dim[:8])
    struct.pack_into(f"{e}8d", h, 104, *(list(f["pixdim"]) + [1.0] * 8)[:8])
    struct.pack_into(f"{e}qdd", h, 168, f["vox_offset"], f["scl_slope"], f["scl_inter"])
    struct.pack_into(f"{e}ii", h, 344, 0, f["sform_code"])
    for i in range(3):
        row = [0.0] * 4
        row[i] = 1.0
        struct.pack_into(f"{e}4d", h, 400 + 32 * i, *row)
    if data is None:
        data = _default_data(f["dims"], dtype, endian)
    return bytes(h) + b"\0\0\0\0" + data


def gz(payload, level=6):
    """One well-formed gzip member."""
    import gzip

    return gzip.compress(payload, compresslevel=level, mtime=0)


def gz_member_parts(payload, level=6):
    """(10-byte header, raw deflate body, 8-byte trailer) of one member, for breaking one part."""
    comp = zlib.compressobj(level, zlib.DEFLATED, -15)
    body = comp.compress(payload) + comp.flush()
    header = b"\x1f\x8b\x08\x00\x00\x00\x00\x00\x00\xff"
    trailer = struct.pack("<II", zlib.crc32(payload) & 0xFFFFFFFF, len(payload) & 0xFFFFFFFF)
    return header, body, trailer


def gz_with_names(payload):
    """A member whose header carries FEXTRA, FNAME and FCOMMENT (valid, rarely seen)."""
    _, body, trailer = gz_member_parts(payload)
    extra = b"AB\x04\x00xyzw"
    header = b"\x1f\x8b\x08\x1c\x00\x00\x00\x00\x00\xff"
    header += struct.pack("<H", len(extra)) + extra + b"scan.nii\0" + b"a comment\0"
    return header + body + trailer


def gz_bomb(header_bytes, inflated_size):
    """A member whose content is `header_bytes` followed by zeros up to `inflated_size` bytes,
    compressed in chunks so building it never holds the inflated bytes at once."""
    comp = zlib.compressobj(9, zlib.DEFLATED, -15)
    crc = zlib.crc32(header_bytes)
    parts = [comp.compress(header_bytes)]
    left = inflated_size - len(header_bytes)
    chunk = bytes(1 << 20)
    while left > 0:
        piece = chunk if left >= len(chunk) else bytes(left)
        crc = zlib.crc32(piece, crc)
        parts.append(comp.compress(piece))
        left -= len(piece)
    parts.append(comp.flush())
    header = b"\x1f\x8b\x08\x00\x00\x00\x00\x00\x02\xff"
    trailer = struct.pack("<II", crc & 0xFFFFFFFF, inflated_size & 0xFFFFFFFF)
    return header + b"".join(parts) + trailer
