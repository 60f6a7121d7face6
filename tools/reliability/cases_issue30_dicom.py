"""Issue 30's DICOM cases: Siemens mosaics, deflate bombs, series and NIfTI larger than the
memory available, tags that contradict the pixel data, a named file among duplicates, and the
messages that replaced unhelpful ones. Each case says what the output must say.

Decisions:
- The files are written here with the standard library only (explicit VR little endian, or
  deflated: the same data set through raw deflate), so the probe needs no pydicom. Series are
  tiny (16 x 16 pixels); the values are a known ramp.
- Memory refusals use `MORPHRAY_MEM_AVAILABLE` (host_memory.rs), which stands in for
  /proc/meminfo's MemAvailable, so they happen on any machine.
- The deflate bomb is 256 MiB of zeros after the pixel data (about 256 KB on disk, written in
  chunks): morphray must stop at the header's declared size plus slack (about 1 MB), not hold it.
"""

import os
import struct
import zlib

import nifti as nf
from case import Case

MR = "1.2.840.10008.5.1.4.1.1.4"
EXPLICIT_LE = "1.2.840.10008.1.2.1"
DEFLATED = "1.2.840.10008.1.2.1.99"
TILE = 16


def _uid(s):
    b = s.encode()
    return b + b"\0" if len(b) % 2 else b


def _text(s):
    b = s.encode()
    return b + b" " if len(b) % 2 else b


def _element(group, elem, vr, value):
    """One explicit-VR little-endian element."""
    head = struct.pack("<HH", group, elem) + vr.encode()
    if vr in ("OB", "OW", "SQ", "UN", "UT", "UC", "UR"):
        return head + b"\0\0" + struct.pack("<I", len(value)) + value
    return head + struct.pack("<H", len(value)) + value


def _us(v):
    return struct.pack("<H", v)


def _ds(values):
    return _text("\\".join(f"{v:g}" for v in values))


def csa(tags):
    """A Siemens CSA image header ("SV10") with string-valued tags."""
    out = b"SV10\x04\x03\x02\x01" + struct.pack("<II", len(tags), 77)
    for name, values in tags:
        tag = name.encode().ljust(64, b"\0") + struct.pack("<i4sii", len(values), b"DS", 0,
                                                           len(values)) + struct.pack("<i", 77)
        out += tag
        for v in values:
            raw = v.encode() + b"\0"
            out += struct.pack("<4i", len(raw), len(raw), 77, len(raw))
            out += raw.ljust((len(raw) + 3) // 4 * 4, b"\0")
    return out


def dicom_file(series_uid, instance, position, pixels, rows, cols, image_type="ORIGINAL\\PRIMARY",
               bits_stored=16, extra=(), syntax=EXPLICIT_LE, trailer=None):
    """Bytes of one MR image file. `pixels`: little-endian uint16 bytes as stored; `extra`:
    more (group, element, vr, value) elements; `trailer`: a private OB after the pixel data, as
    (bytes, length) or an iterable of chunks (deflated files only)."""
    sop = f"{series_uid}.{instance}"
    elements = [
        (0x0008, 0x0008, "CS", _text(image_type)),
        (0x0008, 0x0016, "UI", _uid(MR)),
        (0x0008, 0x0018, "UI", _uid(sop)),
        (0x0008, 0x0060, "CS", _text("MR")),
        (0x0008, 0x0070, "LO", _text("SIEMENS")),
        (0x0018, 0x0050, "DS", _ds([3.0])),
        (0x0020, 0x000D, "UI", _uid("1.2.826.0.1.3680043.2.1125.77.1")),
        (0x0020, 0x000E, "UI", _uid(series_uid)),
        (0x0020, 0x0011, "IS", _text("7")),
        (0x0020, 0x0013, "IS", _text(str(instance))),
        (0x0020, 0x0032, "DS", _ds(position)),
        (0x0020, 0x0037, "DS", _ds([1, 0, 0, 0, 1, 0])),
        (0x0020, 0x0052, "UI", _uid("1.2.826.0.1.3680043.2.1125.77.2")),
        (0x0028, 0x0002, "US", _us(1)),
        (0x0028, 0x0004, "CS", _text("MONOCHROME2")),
        (0x0028, 0x0010, "US", _us(rows)),
        (0x0028, 0x0011, "US", _us(cols)),
        (0x0028, 0x0030, "DS", _ds([2.0, 2.0])),
        (0x0028, 0x0100, "US", _us(16)),
        (0x0028, 0x0101, "US", _us(bits_stored)),
        (0x0028, 0x0102, "US", _us(15)),
        (0x0028, 0x0103, "US", _us(0)),
    ] + list(extra)
    elements.sort(key=lambda e: (e[0], e[1]))
    body = b"".join(_element(*e) for e in elements)
    body += _element(0x7FE0, 0x0010, "OW", pixels)
    meta_items = (_element(0x0002, 0x0001, "OB", b"\0\1") + _element(0x0002, 0x0002, "UI", _uid(MR))
                  + _element(0x0002, 0x0003, "UI", _uid(sop))
                  + _element(0x0002, 0x0010, "UI", _uid(syntax))
                  + _element(0x0002, 0x0012, "UI", _uid("1.2.826.0.1.3680043.2.1125.77")))
    meta = _element(0x0002, 0x0000, "UL", struct.pack("<I", len(meta_items))) + meta_items
    head = b"\0" * 128 + b"DICM" + meta
    if syntax != DEFLATED:
        return head + body
    z = zlib.compressobj(6, zlib.DEFLATED, -15)
    out = [head, z.compress(body)]
    if trailer is not None:
        size, chunk = trailer
        out.append(z.compress(struct.pack("<HH", 0x7FE1, 0x0010) + b"OB\0\0"
                              + struct.pack("<I", size)))
        zeros = b"\0" * chunk
        for _ in range(size // chunk):
            out.append(z.compress(zeros))
    out.append(z.flush())
    return b"".join(out)


def ramp(n, offset=0):
    return b"".join(struct.pack("<H", (i * 7 + offset) % 4000) for i in range(n))


def series(ws, name, slices, uid, **kw):
    """A folder of `slices` 16 x 16 axial files, 3 mm apart; returns (folder, files)."""
    files = []
    for k in range(slices):
        data = dicom_file(uid, k + 1, [-16, -16, 3.0 * k], ramp(TILE * TILE, k), TILE, TILE, **kw)
        files.append(ws.write(f"{name}/s{k:03}.dcm", data))
    return os.path.dirname(files[0]), files


def mosaic(ws, name, images):
    """One Siemens mosaic of `images` 16 x 16 slices in a ceil(sqrt) grid."""
    side = 1
    while side * side < images:
        side += 1
    rows = cols = TILE * side
    tiles = [ramp(TILE * TILE, m * 100) for m in range(images)]
    pixels = bytearray(rows * cols * 2)
    for m, tile in enumerate(tiles):
        gr, gc = divmod(m, side)
        for y in range(TILE):
            at = ((gr * TILE + y) * cols + gc * TILE) * 2
            pixels[at:at + TILE * 2] = tile[y * TILE * 2:(y + 1) * TILE * 2]
    extra = [
        (0x0019, 0x0010, "LO", _text("SIEMENS MR HEADER")),
        (0x0019, 0x100A, "US", _us(images)),
        (0x0029, 0x0010, "LO", _text("SIEMENS CSA HEADER")),
        (0x0029, 0x1010, "OB", csa([("NumberOfImagesInMosaic", [str(images)]),
                                    ("SliceNormalVector", ["0", "0", "1"])])),
    ]
    return ws.write(f"{name}/mosaic.dcm", dicom_file(
        "1.2.826.0.1.3680043.2.1125.77.10", 1, [-100, -100, 0], bytes(pixels), rows, cols,
        image_type="ORIGINAL\\PRIMARY\\M\\ND\\MOSAIC", extra=extra))


def dicom_mosaics(ws):
    cls = "dicom: mosaic"
    one = mosaic(ws, "mosaic/one", 7)
    return [
        Case(cls, "7 slices in a 3x3 grid", ["info", one], expect="ok", quick=True,
             says=r"16x16x7", never_says=r"48x48x1|single slice"),
        Case(cls, "convert writes the slices", ["convert", one, "-o", ws.fresh("mosaic.nii")],
             expect="ok", never_says=r"single slice"),
    ]


def dicom_bounds(ws):
    cls = "dicom: bounds"
    bomb_dir = ws.path("bomb")
    for n in range(2):
        ws.write(f"bomb/b{n}.dcm", dicom_file(
            "1.2.826.0.1.3680043.2.1125.77.20", n + 1, [0, 0, 3.0 * n], ramp(TILE * TILE),
            TILE, TILE, syntax=DEFLATED, trailer=(256 << 20, 1 << 20)))
    honest, _ = series(ws, "honest", 4, "1.2.826.0.1.3680043.2.1125.77.21")
    nii = ws.write("memory/big.nii.gz", nf.gz(nf.nifti1((16, 16, 16))))
    low = {"MORPHRAY_MEM_AVAILABLE": "1000"}
    return [
        Case(cls, "deflate bomb (2 files, 256 MiB each)", ["info", bomb_dir], expect="error",
             says=r"inflates past 1\.1 MB, more than its header declares"),
        Case(cls, "series larger than MemAvailable", ["info", honest], expect="error", env=low,
             says=r"needs .* of memory but only 1\.0 KB is available \(MemAvailable\)"),
        Case(cls, "nii.gz larger than MemAvailable", ["info", nii], expect="error", env=low,
             says=r"inflating the .* needs .* but only 1\.0 KB is available"),
    ]


def dicom_tags(ws):
    cls = "dicom: tags vs data"
    uid = "1.2.826.0.1.3680043.2.1125.77.30"
    bits0 = ws.write("tags/bits0.dcm", dicom_file(uid, 1, [0, 0, 0], ramp(256), TILE, TILE,
                                                  bits_stored=0))
    longer = ws.write("tags/longer.dcm", dicom_file(uid, 2, [0, 0, 3], ramp(512), TILE, TILE))
    shorter = ws.write("tags/shorter.dcm", dicom_file(uid, 3, [0, 0, 6], ramp(128), TILE, TILE))
    folder, files = series(ws, "named", 3, "1.2.826.0.1.3680043.2.1125.77.31")
    twin = ws.write("named/twin.dcm", dicom_file("1.2.826.0.1.3680043.2.1125.77.31", 9,
                                                 [-16, -16, 3.0], ramp(256, 999), TILE, TILE))
    return [
        Case(cls, "BitsStored 0", ["info", bits0], expect="error",
             says=r"BitsStored 0 contradicts BitsAllocated 16"),
        Case(cls, "PixelData longer than Rows x Columns", ["info", longer], expect="error",
             says=r"PixelData holds 1024 bytes but .* declare 512"),
        Case(cls, "PixelData shorter than Rows x Columns", ["info", shorter], expect="error",
             says=r"declare 512 bytes of pixels but PixelData holds only 256",
             never_says=r"out of range"),
        Case(cls, "a named file among duplicates wins", ["info", twin], expect="ok",
             says=r"named on the command line.*s001\.dcm"),
    ]


def dicom_messages(ws):
    cls = "dicom: messages"
    single, _ = series(ws, "single", 1, "1.2.826.0.1.3680043.2.1125.77.40")
    own = ws.path("uid-per-file")
    for n in range(30):
        ws.write(f"uid-per-file/f{n:02}.dcm", dicom_file(f"1.2.826.0.1.3680043.2.1125.77.41.{n}", 1,
                                                [0, 0, 3.0 * n], ramp(256), TILE, TILE))
    return [
        Case(cls, "one slice: info lists it", ["info", single], expect="ok", says=r"16x16x1"),
        Case(cls, "one slice: convert says what to do", ["convert", single, "-o",
             ws.fresh("single.nii")], expect="error",
             says=r"holds one 2-D slice \(16x16\), not a 3-D volume.*--series 0"),
        Case(cls, "every file its own series", ["convert", own, "-o", ws.fresh("uids.nii")],
             expect="error", says=r"every one of its 30 image files is its own series",
             never_says=r"image of 1 slice"),
    ]


BUILDERS = (dicom_mosaics, dicom_bounds, dicom_tags, dicom_messages)
