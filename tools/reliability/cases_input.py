"""Bad inputs: NIfTI headers, gzip streams, voxel data and paths (issue 12's input side).

Decisions:
- Header variants run `info` (CPU only, the same loader every command uses: fast, so many
  variants are affordable); a few that change what a picture shows (scaling, orientation, 4-D
  frames, odd data) also run `render`, where a silently wrong image would appear.
- The base volume is 16^3 int16 (8 KiB of voxels): big enough to have a histogram and a
  picture, small enough that every variant loads in milliseconds.
- Expectations follow the loader contract (`tests/nifti_loader.rs`, the documented outcomes); where
  the contract allows a repair or a refusal, the case says "any".
"""

import os
import struct

import nifti as nf
from case import Case, info, render_case

DIMS = (16, 16, 16)
F32_MAX = 3.4028234663852886e38


def _header_case(ws, cls, name, data, expect, quick=False, ext=".nii"):
    folder = "".join(c if c.isalnum() else "-" for c in cls)
    path = ws.write(f"{folder}/{name}{ext}", data)
    return Case(cls, name, info(path), expect=expect, quick=quick)


def truncated(ws):
    cls = "nifti: truncated"
    whole = nf.nifti1(DIMS)
    lengths = sorted(set(list(range(0, 401, 13)) + [1, 4, 40, 108, 347, 348, 351, 352, 353]))
    lengths += [352 + 4096, len(whole) - 1]
    quick = {0, 4, 347, 352}
    return [
        _header_case(ws, cls, f"len{n}", whole[:n], "error", quick=n in quick) for n in lengths
    ]


def sizeof_and_order(ws):
    cls = "nifti: sizeof_hdr, byte order"
    le, be = nf.nifti1(DIMS), nf.nifti1(DIMS, endian=">")
    mixed = bytearray(be)
    struct.pack_into("<8h", mixed, 40, 3, 16, 16, 16, 1, 1, 1, 1)
    swapped_size = bytearray(le)
    struct.pack_into(">i", swapped_size, 0, 348)
    variants = [
        ("little-endian", le, "ok"),
        ("big-endian", be, "ok"),
        ("sizeof0", nf.nifti1(DIMS, sizeof_hdr=0), "error"),
        ("sizeof347", nf.nifti1(DIMS, sizeof_hdr=347), "error"),
        ("sizeof540-on-nifti1", nf.nifti1(DIMS, sizeof_hdr=540), "error"),
        ("sizeof-minus1", nf.nifti1(DIMS, sizeof_hdr=-1), "error"),
        ("be-size-le-dims", bytes(mixed), "error"),
        ("be-size-le-rest", bytes(swapped_size), "error"),
    ]
    return [_header_case(ws, cls, n, d, e, quick=n == "big-endian") for n, d, e in variants]


def dims(ws):
    cls = "nifti: dim[]"
    small = nf.pack_voxels([1] * 16, "int16")
    big = [32767] * 7
    blob16 = nf.pack_voxels(nf.blob(DIMS), "int16")
    variants = [
        ("dim0-0", nf.nifti1(DIMS, dim0=0), "error"),
        ("dim0-8", nf.nifti1(DIMS, dim0=8), "error"),
        ("dim0-neg", nf.nifti1(DIMS, dim0=-1), "error"),
        ("dim0-1", nf.nifti1((16,), data=small), "any"),
        ("dim0-2", nf.nifti1((4, 4), data=small), "any"),
        ("dim2-zero", nf.nifti1((16, 0, 16), data=small), "error"),
        ("dim1-neg", nf.nifti1((-5, 16, 16), data=small), "error"),
        ("dim3-min", nf.nifti1((16, 16, -32768), data=small), "error"),
        ("dims-32767^3", nf.nifti1((32767,) * 3, data=small), "error"),
        ("dims-32767^7", nf.nifti1(big, data=small), "error"),
        ("dims-above-dim0-junk", nf.nifti1(DIMS + (-1, -7, 0, 9), dim0=3, data=blob16), "ok"),
        ("nifti2", nf.nifti2(DIMS), "ok"),
        ("nifti2-2^31x1x1", nf.nifti2((1 << 31, 1, 1), data=small), "error"),
        ("nifti2-2^31^3", nf.nifti2((1 << 31,) * 3, data=small), "error"),
        ("nifti2-2^62x4", nf.nifti2((1 << 62, 4, 1), data=small), "error"),
        ("nifti2-dim-neg", nf.nifti2((16, -1, 16), data=small), "error"),
    ]
    return [_header_case(ws, cls, n, d, e, quick=n == "dims-32767^7") for n, d, e in variants]


def datatypes(ws):
    cls = "nifti: datatype, bitpix"
    out = []
    for dt in ("complex64", "complex128", "complex256", "float128"):
        out.append(_header_case(ws, cls, dt, nf.nifti1(DIMS, dt), "error"))
    for code in (0, 9999, -1):
        data = nf.nifti1(DIMS, datatype=code, bitpix=16)
        out.append(_header_case(ws, cls, f"code{code}", data, "error", quick=code == 0))
    for dt in ("rgb24", "rgba32", "uint8", "int8", "uint16", "int32", "uint32", "int64", "uint64"):
        out.append(_header_case(ws, cls, dt, nf.nifti1(DIMS, dt), "ok"))
    out.append(_header_case(ws, cls, "float64", nf.nifti1(DIMS, "float64"), "ok"))
    for name, dt, bitpix in (("int16-bitpix8", "int16", 8), ("float32-bitpix64", "float32", 64)):
        out.append(_header_case(ws, cls, name, nf.nifti1(DIMS, dt, bitpix=bitpix), "ok"))
    out.append(_header_case(ws, cls, "bitpix0", nf.nifti1(DIMS, bitpix=0), "ok"))
    return out


def vox_offset(ws):
    cls = "nifti: vox_offset"
    nan, inf = float("nan"), float("inf")
    length = 352 + 8192
    variants = [
        ("nan", nf.nifti1(DIMS, vox_offset=nan), "error"),
        ("inf", nf.nifti1(DIMS, vox_offset=inf), "error"),
        ("neg", nf.nifti1(DIMS, vox_offset=-1.0), "error"),
        ("fractional", nf.nifti1(DIMS, vox_offset=352.5), "error"),
        ("1e20", nf.nifti1(DIMS, vox_offset=1e20), "error"),
        ("2^31", nf.nifti1(DIMS, vox_offset=2.0**31), "error"),
        ("1e9", nf.nifti1(DIMS, vox_offset=1e9), "error"),
        ("at-eof", nf.nifti1(DIMS, vox_offset=float(length)), "error"),
        ("zero", nf.nifti1(DIMS, vox_offset=0.0), "ok"),
        ("100", nf.nifti1(DIMS, vox_offset=100.0), "any"),
        ("353-padded", nf.nifti1(DIMS, vox_offset=353.0, extra=b"\0"), "ok"),
    ]
    out = [_header_case(ws, cls, n, d, e, quick=n in ("nan", "1e20")) for n, d, e in variants]
    out[4].never_says = "18446744073709551615"  # 1e20: the number as written, never usize::MAX
    return out


def magic(ws):
    cls = "nifti: magic"
    variants = [
        ("n+2-in-348", nf.nifti1(DIMS, magic=b"n+2\0"), "error"),
        ("garbage", nf.nifti1(DIMS, magic=b"xyz\0"), "error"),
        ("uppercase", nf.nifti1(DIMS, magic=b"N+1\0"), "error"),
        ("ni1-single-file", nf.nifti1(DIMS, magic=b"ni1\0"), "error"),
        ("no-nul", nf.nifti1(DIMS, magic=b"n+1X"), "any"),
        ("analyze-zeros", nf.nifti1(DIMS, magic=b"\0\0\0\0"), "any"),
        ("nifti2-bad-eol", nf.nifti2(DIMS, magic=b"n+2\0\n\r\x1a\n"), "error"),
    ]
    out = [_header_case(ws, cls, n, d, e, quick=n == "n+2-in-348") for n, d, e in variants]
    for case in out[:3]:
        case.says = "magic"  # not "no .img file was found"
    return out


def scaling(ws):
    cls = "nifti: scl_slope, scl_inter"
    nan, inf = float("nan"), float("inf")
    variants = [
        ("slope-nan", {"scl_slope": nan}, "ok"),
        ("slope-0", {"scl_slope": 0.0}, "ok"),
        ("slope-inf", {"scl_slope": inf}, "ok"),
        ("slope-neginf", {"scl_slope": -inf}, "ok"),
        ("slope-neg1", {"scl_slope": -1.0}, "ok"),
        ("slope-denormal", {"scl_slope": 1e-45}, "any"),
        ("slope-1e38", {"scl_slope": 1e38}, "any"),
        ("inter-nan", {"scl_inter": nan}, "ok"),
        ("inter-inf", {"scl_inter": inf}, "ok"),
    ]
    out = []
    for name, over, expect in variants:
        path = ws.write(f"scaling/{name}.nii", nf.nifti1(DIMS, **over))
        out.append(Case(cls, name, info(path), expect=expect, quick=name == "slope-nan"))
        if name in ("slope-nan", "slope-0", "inter-nan", "slope-1e38", "slope-neg1"):
            lit = expect == "ok"
            out.append(render_case(ws, cls, f"render {name}", path, expect=expect, lit=lit))
    return out


def orientation(ws):
    cls = "nifti: quaternion, pixdim, sform"
    nan, inf = float("nan"), float("inf")
    q = {"qform_code": 1, "sform_code": 0}
    pix = lambda *p: {"pixdim": [1.0, *p, 1.0, 1.0, 1.0, 1.0]}  # noqa: E731
    variants = [
        ("qform-identity", {**q}, "ok"),
        ("quat-111", {**q, "quatern": (1.0, 1.0, 1.0)}, "ok"),
        ("quat-slightly-over", {**q, "quatern": (1.0000001, 0.0, 0.0)}, "ok"),
        ("quat-nan", {**q, "quatern": (nan, 0.0, 0.0)}, "any"),
        ("qfac-0", {**q, "pixdim": [0.0, 1, 1, 1, 1, 1, 1, 1]}, "ok"),
        ("qfac-5", {**q, "pixdim": [5.0, 1, 1, 1, 1, 1, 1, 1]}, "ok"),
        ("qoffset-inf", {**q, "qoffset": (inf, 0.0, 0.0)}, "any"),
        ("pixdim-0", pix(0.0, 1.0, 1.0), "ok"),
        ("pixdim-neg", pix(-2.0, 1.0, 1.0), "ok"),
        ("pixdim-nan", pix(nan, 1.0, 1.0), "ok"),
        ("pixdim-inf", pix(1.0, inf, 1.0), "ok"),
        ("pixdim-1e-30", pix(1e-30, 1.0, 1.0), "any"),
        ("pixdim-1e30", pix(1.0, 1.0, 1e30), "any"),
        ("sform-nan", {"srow": [[nan, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]]}, "any"),
        ("sform-singular", {"srow": [[0.0] * 4] * 3}, "any"),
        ("sform-code-99", {"sform_code": 99}, "any"),
        ("q-and-s-disagree", {"qform_code": 1, "sform_code": 1, "quatern": (0.0, 0.0, 1.0)}, "ok"),
    ]
    rendered = ("quat-111", "quat-nan", "pixdim-nan", "pixdim-1e30", "sform-singular", "sform-nan")
    out = []
    for name, over, expect in variants:
        path = ws.write(f"orientation/{name}.nii", nf.nifti1(DIMS, **over))
        out.append(Case(cls, name, info(path), expect=expect, quick=name == "quat-nan"))
        if name in rendered:
            lit = expect == "ok"
            # A repaired pixdim is a warning on every command that loads the volume.
            says = "pixdim" if name == "pixdim-nan" else None
            out.append(render_case(ws, cls, f"render {name}", path, expect=expect, lit=lit,
                                   says=says))
    return out


def frames(ws):
    cls = "nifti: 4-D and beyond"
    four = ws.write("frames/four.nii", nf.nifti1(DIMS + (3,)))
    five = ws.write("frames/five.nii", nf.nifti1(DIMS + (1, 2)))
    zero_t = ws.write("frames/t0.nii", nf.nifti1(DIMS + (0,), data=b""))
    huge_t = ws.write("frames/t32767.nii.gz", nf.gz(nf.nifti1(DIMS + (32767,), data=bytes(64))))
    return [
        Case(cls, "4d info", info(four), expect="ok", quick=True),
        Case(cls, "4d info --frame 1000000", info(four, "--frame", "1000000"), expect="error"),
        render_case(ws, cls, "4d render default frame", four, lit=True, says="frame"),
        render_case(ws, cls, "4d render --frame 2", four, "--frame", "2", lit=True),
        render_case(ws, cls, "4d render --frame 3", four, "--frame", "3", expect="error"),
        render_case(ws, cls, "3d render --frame 1", ws.write("frames/three.nii", nf.nifti1(DIMS)),
                    "--frame", "1", expect="error"),
        Case(cls, "4d peaks", ws.gpu("peaks", four), expect="ok", gpu=True),
        Case(cls, "5d info", info(five), expect="ok"),
        Case(cls, "dim4-zero", info(zero_t), expect="error"),
        Case(cls, "32767 frames declared, 64 bytes", info(huge_t), expect="error"),
    ]


def extensions(ws):
    cls = "nifti: extensions"

    def ext(esize, ecode=6, body=b""):
        return struct.pack("<ii", esize, ecode) + body

    one = ext(16, 6, b"comment\0")
    many = b"".join(ext(16, 6, b"x" * 8) for _ in range(1000))
    variants = [
        ("ext_noroom", nf.nifti1(DIMS, extension=b"\x01\0\0\0"), "ok"),
        ("esize-0", nf.nifti1(DIMS, extension=b"\x01\0\0\0", extra=ext(0), vox_offset=360.0),
         "ok"),
        ("esize-20", nf.nifti1(DIMS, extension=b"\x01\0\0\0", extra=ext(20) + bytes(8),
                               vox_offset=368.0), "ok"),
        ("esize-1e9", nf.nifti1(DIMS, extension=b"\x01\0\0\0", extra=ext(10**9) + bytes(8),
                                vox_offset=368.0), "ok"),
        ("esize-neg", nf.nifti1(DIMS, extension=b"\x01\0\0\0", extra=ext(-16) + bytes(8),
                                vox_offset=368.0), "ok"),
        ("one-valid", nf.nifti1(DIMS, extension=b"\x01\0\0\0", extra=one, vox_offset=368.0), "ok"),
        ("1000-valid", nf.nifti1(DIMS, extension=b"\x01\0\0\0", extra=many,
                                 vox_offset=352.0 + len(many)), "ok"),
    ]
    out = [_header_case(ws, cls, n, d, e, quick=n == "ext_noroom") for n, d, e in variants]
    out[0].says = "extension"  # the flag says an extension follows; there is no room for one
    return out


def gzip_streams(ws):
    cls = "gzip"
    plain = nf.nifti1(DIMS)
    whole = nf.gz(plain)
    head, body, trailer = nf.gz_member_parts(plain)
    bad_crc = head + body + bytes([trailer[0] ^ 0xFF]) + trailer[1:]
    bad_isize = head + body + trailer[:4] + struct.pack("<I", 12345)
    flipped = bytearray(whole)
    flipped[len(whole) // 2] ^= 0x55
    tiny_header = nf.nifti1((4, 4, 6), "uint8", data=b"")
    huge_declared = nf.nifti1((2048, 2048, 2048), "float32", data=bytes(1024))
    variants = [
        ("valid", whole, "ok"),
        ("plain-named-gz", plain, "ok"),
        ("fname-fextra-fcomment", nf.gz_with_names(plain), "ok"),
        ("truncated-10", whole[:10], "error"),
        ("truncated-half", whole[: len(whole) // 2], "error"),
        ("truncated-no-isize", whole[:-4], "error"),
        ("truncated-no-trailer", whole[:-8], "error"),
        ("bad-crc", bad_crc, "error"),
        ("bad-isize", bad_isize, "any"),
        ("flipped-byte", bytes(flipped), "error"),
        ("trailing-garbage", whole + b"garbage!" * 8, "any"),
        ("zero-pad-512", whole + bytes(512), "any"),
        ("multi-member-split", nf.gz(plain[:352]) + nf.gz(plain[352:]), "ok"),
        ("50-members", b"".join(nf.gz(plain[i : i + 175]) for i in range(0, len(plain), 175)),
         "ok"),
        ("empty-content", nf.gz(b""), "error"),
        ("header-only", nf.gz(plain[:352]), "error"),
        ("gzip-of-gzip", nf.gz(whole), "any"),
        ("bomb-96B-declared-100MB", nf.gz_bomb(tiny_header, 100 << 20), "error"),
        ("32GiB-declared-1KiB-given", nf.gz(huge_declared), "error"),
    ]
    out = []
    for name, data, expect in variants:
        path = ws.write(f"gzip/{name}.nii.gz", data)
        quick = name in ("bomb-96B-declared-100MB", "32GiB-declared-1KiB-given", "bad-crc")
        out.append(Case(cls, name, info(path), expect=expect, quick=quick))
    bomb = ws.path("gzip/bomb-96B-declared-100MB.nii.gz")
    out.append(render_case(ws, cls, "render bomb", bomb, expect="error"))
    out.append(render_case(ws, cls, "render valid", ws.path("gzip/valid.nii.gz"), lit=True))
    return out


def data(ws):
    cls = "data: odd voxel values"
    nan, inf = float("nan"), float("inf")
    n = 16**3
    ramp32 = [float(i) for i in range(32**3)]
    # The blob with a NaN slab (x < 4): the rest must still render (NaN voxels are transparent).
    nan_slab = [nan if i % 16 < 4 else float(v) for i, v in enumerate(nf.blob(DIMS))]
    extremes = [(-1.7e308 if i % 2 else 1.7e308) for i in range(n)]
    variants = [
        ("all-nan", nf.nifti1(DIMS, "float32", nf.pack_voxels([nan] * n, "float32")), "any",
         False),
        ("nan-and-inf", nf.nifti1(DIMS, "float32", nf.pack_voxels(
            [(nan, inf, -inf)[i % 3] for i in range(n)], "float32")), "any", False),
        ("constant", nf.nifti1(DIMS, data=nf.pack_voxels([7] * n, "int16")), "any", False),
        ("two-valued", nf.nifti1(DIMS, data=nf.pack_voxels([(0, 100)[i % 2] for i in range(n)],
                                                           "int16")), "any", False),
        ("float64-1.7e308", nf.nifti1(DIMS, "float64", nf.pack_voxels(extremes, "float64")),
         "any", False),
        ("float32-max", nf.nifti1(DIMS, "float32", nf.pack_voxels(
            [F32_MAX if i % 2 else -F32_MAX for i in range(n)], "float32")), "any", False),
        ("nan-slab", nf.nifti1(DIMS, "float32", nf.pack_voxels(nan_slab, "float32")), "ok", True),
        ("ramp-32^3", nf.nifti1((32, 32, 32), "float32", nf.pack_voxels(ramp32, "float32")),
         "ok", False),
        ("thin-70000x1x1", nf.nifti2((70000, 1, 1), "float32", nf.pack_voxels(
            [float(i % 97) for i in range(70000)], "float32")), "any", False),
        ("uint64-max", nf.nifti1(DIMS, "uint64", nf.pack_voxels(
            [(0, 2**64 - 1)[i % 2] for i in range(n)], "uint64")), "any", False),
    ]
    out = []
    for name, blob, expect, lit in variants:
        path = ws.write(f"data/{name}.nii", blob)
        out.append(Case(cls, f"info {name}", info(path), expect="ok"))
        quick = name in ("all-nan", "float64-1.7e308")
        out.append(render_case(ws, cls, f"render {name}", path, expect=expect, lit=lit,
                               quick=quick))
    return out


def paths(ws):
    cls = "paths"
    fifo = ws.path("paths/fifo.nii")
    os.makedirs(os.path.dirname(fifo), exist_ok=True)
    os.mkfifo(fifo)
    zero_link = ws.path("paths/zero.nii")
    os.symlink("/dev/zero", zero_link)
    hdr, img = nf.analyze_pair(DIMS)
    for stem in ("pair", "upper"):
        ws.write(f"paths/{stem}.hdr", hdr)
    ws.write("paths/pair.img", img)
    ws.write("paths/upper.IMG", img)
    ws.write("paths/gzpair.hdr", hdr)
    ws.write("paths/gzpair.img.gz", nf.gz(img))
    ahdr, aimg = nf.analyze_pair(DIMS, magic=b"\0\0\0\0")
    ws.write("paths/analyze.hdr", ahdr)
    ws.write("paths/analyze.img", aimg)
    ws.write("paths/lonely.hdr", hdr)
    variants = [
        ("directory", ws.path("paths"), "error", True),
        ("fifo", fifo, "error", True),
        ("/dev/zero", "/dev/zero", "error", True),
        ("symlink-to-/dev/zero", zero_link, "error", False),
        ("/dev/null", "/dev/null", "error", False),
        ("missing", ws.path("paths/missing.nii"), "error", False),
        ("empty", ws.write("paths/empty.nii", b""), "error", False),
        ("pair.hdr", ws.path("paths/pair.hdr"), "ok", False),
        ("pair.img", ws.path("paths/pair.img"), "ok", True),
        ("upper.IMG", ws.path("paths/upper.IMG"), "ok", False),
        ("gzpair.img.gz", ws.path("paths/gzpair.img.gz"), "ok", False),
        ("analyze.hdr", ws.path("paths/analyze.hdr"), "ok", False),
        ("hdr-without-img", ws.path("paths/lonely.hdr"), "error", False),
    ]
    out = [Case(cls, f"info {n}", info(p), expect=e, quick=q) for n, p, e, q in variants]
    out.append(render_case(ws, cls, "render fifo", fifo, expect="error"))
    out.append(render_case(ws, cls, "render directory", ws.path("paths"), expect="error"))
    return out


BUILDERS = (
    truncated,
    sizeof_and_order,
    dims,
    datatypes,
    vox_offset,
    magic,
    scaling,
    orientation,
    frames,
    extensions,
    gzip_streams,
    data,
    paths,
)
