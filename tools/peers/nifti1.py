"""A small NIfTI-1 reader for the peer benchmarks (gzip + numpy only, no nibabel).

nibabel is not carried to the device (the carry limit is tight), so the peer scripts read the
volume themselves. What this reader does, following morphray's loader contract
(tests/nifti_loader.rs) where it matters for rendering:

- gzip is sniffed by its magic bytes, never by the extension, and every gzip member is inflated
  (multi-member files are legal); the output is capped at what the header declares.
- sizeof_hdr is read in both byte orders: 348 = NIfTI-1 (that picks the byte order), 540 =
  NIfTI-2 (refused with a clear message), anything else = not NIfTI. The magic must be "n+1"
  (single file); "ni1" (.hdr/.img pair) and ANALYZE 7.5 (no magic) are refused clearly.
- dim[0] in 3..7, dim[1..3] >= 1; dims above 3 are frames: frame 0 is used (with a note).
- datatypes: uint8, int8, int16, uint16, int32, uint32, int64, uint64, float32, float64.
  Complex and RGB are refused by name.
- vox_offset below 352 means 352 (the spec); the data must fit in the file.
- scl_slope / scl_inter are applied when the slope is finite and non-zero and the pair is not
  the identity (this turns the data into float32, as any consumer would have to).
- Non-finite voxels (float data) are set to the finite minimum and counted: both peers would
  otherwise smear NaN through their interpolation.
- pixdim[1..3] non-finite or <= 0 are repaired to 1 mm (with a note).
- Orientation: sform if sform_code > 0, else qform if qform_code > 0, else pixdim scaling.
  The volume is then permuted/flipped to the closest RAS+ voxel order (x fastest = patient's
  right, y = anterior, z = superior), as nibabel's as_closest_canonical would, so that both
  peers can put the camera in the same world frame morphray uses. An oblique residual rotation
  is dropped (reported in `notes`): the peers render axis-aligned boxes only.

`load(path)` returns a `Volume`; every failure raises `NiftiError` with a one-line message.
"""

import os
import struct
import zlib

import numpy as np


class NiftiError(Exception):
    """A NIfTI file this reader cannot use; the message is meant for a person."""


# NIfTI-1 datatype code -> (name, numpy type)
_DATATYPES = {
    2: ("uint8", np.uint8),
    4: ("int16", np.int16),
    8: ("int32", np.int32),
    16: ("float32", np.float32),
    64: ("float64", np.float64),
    256: ("int8", np.int8),
    512: ("uint16", np.uint16),
    768: ("uint32", np.uint32),
    1024: ("int64", np.int64),
    1280: ("uint64", np.uint64),
}
_UNSUPPORTED = {
    1: "binary (1 bit)",
    32: "complex64",
    128: "RGB24",
    1536: "float128",
    1792: "complex128",
    2048: "complex256",
    2304: "RGBA32",
}


class Volume:
    """A scalar volume in RAS+ voxel order.

    data     numpy array, shape (nz, ny, nx), C-contiguous (x fastest), native byte order
    spacing  (sx, sy, sz) in mm, for the array's x, y, z axes after reorientation
    """

    def __init__(self, path, data, spacing, datatype, affine_source, notes):
        self.path = path
        self.data = data
        self.spacing = tuple(float(s) for s in spacing)
        self.datatype = datatype
        self.affine_source = affine_source
        self.notes = notes

    @property
    def dims(self):
        """(nx, ny, nz)."""
        nz, ny, nx = self.data.shape
        return (nx, ny, nz)

    @property
    def extent_mm(self):
        """World size of the voxel box (voxel centres at integer indices, box = [-0.5, n-0.5])."""
        return tuple(n * s for n, s in zip(self.dims, self.spacing))

    def describe(self):
        return {
            "path": os.path.abspath(self.path),
            "dims": list(self.dims),
            "spacing_mm": list(self.spacing),
            "datatype": self.datatype,
            "affine_source": self.affine_source,
            "notes": list(self.notes),
        }


def _inflate_all(raw, cap):
    """Inflates every gzip member of `raw`, stopping with an error past `cap` bytes."""
    out = []
    total = 0
    pos = raw
    while pos:
        d = zlib.decompressobj(16 + zlib.MAX_WBITS)
        try:
            chunk = d.decompress(pos, cap - total + 1)
        except zlib.error as e:
            raise NiftiError(f"corrupt gzip data ({e})") from None
        total += len(chunk)
        out.append(chunk)
        if total > cap:
            # More bytes than the header can explain: stop before filling memory.
            raise NiftiError(f"gzip stream inflates past {cap} bytes, more than the header declares")
        if not d.eof:
            if d.unconsumed_tail:
                raise NiftiError(f"gzip stream inflates past {cap} bytes, more than the header declares")
            raise NiftiError("gzip stream is truncated (file ends inside the compressed data)")
        pos = d.unused_data
        # Trailing zero padding after the last member is tolerated (gzip(1) does too).
        if pos and not pos.startswith(b"\x1f\x8b"):
            if pos.strip(b"\x00"):
                raise NiftiError("garbage after the last gzip member")
            break
    return b"".join(out)


def _read_bytes(path):
    """Reads the file and inflates it if it is gzip; returns the raw NIfTI bytes."""
    try:
        with open(path, "rb") as f:
            raw = f.read()
    except FileNotFoundError:
        raise NiftiError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise NiftiError(f"{path}: is a directory, not a NIfTI file") from None
    except OSError as e:
        raise NiftiError(f"{path}: cannot read ({e.strerror or e})") from None
    if raw[:2] == b"\x1f\x8b":
        # Peek at the header first to know how much the data may inflate to.
        try:
            head = zlib.decompressobj(16 + zlib.MAX_WBITS).decompress(raw, 348)
        except zlib.error as e:
            raise NiftiError(f"{path}: corrupt gzip data ({e})") from None
        order, _ = _byte_order(head, path)
        cap = _declared_size(head, order) + 64 * 1024 * 1024  # header, extensions, slack
        try:
            return _inflate_all(raw, cap)
        except NiftiError as e:
            raise NiftiError(f"{path}: {e}") from None
    return raw


def _byte_order(head, path):
    if len(head) < 348:
        raise NiftiError(f"{path}: not a NIfTI-1 file (only {len(head)} bytes, a header needs 348)")
    for order in ("<", ">"):
        n = struct.unpack(order + "i", head[:4])[0]
        if n == 348:
            return order, 1
        if n == 540:
            raise NiftiError(f"{path}: NIfTI-2 is not supported by the peer scripts (NIfTI-1 only)")
    raise NiftiError(f"{path}: not a NIfTI-1 file (sizeof_hdr is neither 348 nor 540 in either byte order)")


def _declared_size(head, order):
    """Upper bound of the bytes the header declares (offset + all frames), for the gzip cap."""
    dim = struct.unpack(order + "8h", head[40:56])
    bitpix = struct.unpack(order + "h", head[72:74])[0]
    vox_offset = struct.unpack(order + "f", head[108:112])[0]
    n = 1
    for d in dim[1 : 1 + max(0, min(7, dim[0]))]:
        n *= max(1, d)
    off = vox_offset if np.isfinite(vox_offset) and 0 <= vox_offset < 2**31 else 0
    return int(off) + n * max(1, bitpix // 8)


def _quatern_to_rotation(b, c, d):
    a2 = 1.0 - (b * b + c * c + d * d)
    if a2 < 0:
        # Slightly over 1 from rounding: a = 0; clearly over: normalize (b, c, d).
        s = np.sqrt(b * b + c * c + d * d)
        if a2 < -1e-5:
            b, c, d = b / s, c / s, d / s
        a = 0.0
    else:
        a = np.sqrt(a2)
    return np.array(
        [
            [a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)],
            [2 * (b * c + a * d), a * a + c * c - b * b - d * d, 2 * (c * d - a * b)],
            [2 * (b * d - a * c), 2 * (c * d + a * b), a * a + d * d - c * c - b * b],
        ]
    )


def _linear_part(head, order, spacing, notes):
    """The 3x3 voxel->world matrix (columns = voxel axes) and where it came from."""
    qform_code, sform_code = struct.unpack(order + "2h", head[252:256])
    if sform_code > 0:
        srow = np.array(struct.unpack(order + "12f", head[280:328]), dtype=np.float64).reshape(3, 4)
        m = srow[:, :3]
        if np.all(np.isfinite(m)) and abs(np.linalg.det(m)) > 1e-12:
            return m, "sform"
        notes.append("sform is singular or non-finite; falling back")
    if qform_code > 0:
        b, c, d = struct.unpack(order + "3f", head[256:268])
        qfac = struct.unpack(order + "f", head[76:80])[0]
        qfac = -1.0 if qfac < 0 else 1.0
        if all(np.isfinite(x) for x in (b, c, d)):
            r = _quatern_to_rotation(float(b), float(c), float(d))
            return r @ np.diag([spacing[0], spacing[1], spacing[2] * qfac]), "qform"
        notes.append("qform quaternion is non-finite; falling back")
    return np.diag(spacing), "pixdim"


def _canonical(data, m, notes):
    """Permutes/flips `data` (shape (nz, ny, nx), index order k, j, i) to RAS+ order.

    `m` columns are voxel axes i, j, k in world (RAS) mm. Returns (data, spacing) where spacing
    is per world axis x, y, z. A view when only flips are needed; one copy when axes move.
    """
    a = np.abs(m)
    # Greedy assignment, largest |component| first (as nibabel.io_orientation does).
    world_of_axis = [-1, -1, -1]
    used_world = set()
    for flat in np.argsort(-a, axis=None):
        w, v = divmod(int(flat), 3)
        if world_of_axis[v] < 0 and w not in used_world:
            world_of_axis[v] = w
            used_world.add(w)
    spacing_world = [0.0, 0.0, 0.0]
    for v in range(3):
        spacing_world[world_of_axis[v]] = float(np.linalg.norm(m[:, v]))
    off_axis = max(
        float(np.linalg.norm(np.delete(m[:, v], world_of_axis[v])) / max(np.linalg.norm(m[:, v]), 1e-12))
        for v in range(3)
    )
    if off_axis > 1e-3:
        notes.append(f"oblique affine (off-axis fraction {off_axis:.3f}): rendered as the closest axis-aligned box")
    # Array axis of voxel axis v: i -> 2, j -> 1, k -> 0. Flip where the axis points to -world.
    out = data
    for v in range(3):
        if m[world_of_axis[v], v] < 0:
            out = np.flip(out, axis=2 - v)
    # New array axis order: (z, y, x) = voxel axes mapped to world 2, 1, 0.
    axis_for_world = {world_of_axis[v]: 2 - v for v in range(3)}
    perm = (axis_for_world[2], axis_for_world[1], axis_for_world[0])
    if perm != (0, 1, 2):
        out = np.transpose(out, perm)
        notes.append(f"voxel axes permuted to RAS+ (array axes {perm})")
    if out is not data:
        out = np.ascontiguousarray(out)
    return out, spacing_world


def load(path):
    """Reads a NIfTI-1 file (.nii or .nii.gz) into a RAS+ `Volume` (frame 0)."""
    notes = []
    raw = _read_bytes(path)
    order, _ = _byte_order(raw, path)
    head = raw[:348]
    magic = head[344:348]
    if magic == b"ni1\x00":
        raise NiftiError(f"{path}: a NIfTI-1 .hdr/.img pair; give a single-file .nii or .nii.gz")
    if magic != b"n+1\x00":
        raise NiftiError(f"{path}: no NIfTI-1 magic (ANALYZE 7.5 or damaged header); not supported")

    dim = struct.unpack(order + "8h", head[40:56])
    ndim = dim[0]
    if not 1 <= ndim <= 7:
        raise NiftiError(f"{path}: dim[0] = {ndim}, must be 1..7")
    if ndim < 3:
        raise NiftiError(f"{path}: a {ndim}-D image; the peers render 3-D volumes")
    shape = [int(d) for d in dim[1 : ndim + 1]]
    if any(d < 1 for d in shape):
        raise NiftiError(f"{path}: dim = {shape} has a size below 1")
    nx, ny, nz = shape[:3]
    frames = 1
    for d in shape[3:]:
        frames *= d
    if frames > 1:
        notes.append(f"{frames} frames; rendering frame 0")

    datatype = struct.unpack(order + "h", head[70:72])[0]
    if datatype in _UNSUPPORTED:
        raise NiftiError(f"{path}: datatype {_UNSUPPORTED[datatype]} is not supported (scalar volumes only)")
    if datatype not in _DATATYPES:
        raise NiftiError(f"{path}: unknown NIfTI datatype code {datatype}")
    dtname, dtype = _DATATYPES[datatype]
    dt = np.dtype(dtype).newbyteorder(order)

    vox_offset = struct.unpack(order + "f", head[108:112])[0]
    if not np.isfinite(vox_offset) or vox_offset < 0 or vox_offset != int(vox_offset):
        raise NiftiError(f"{path}: vox_offset {vox_offset} is not a non-negative integer")
    offset = max(352, int(vox_offset))
    count = nx * ny * nz
    need = offset + count * dt.itemsize
    if len(raw) < need:
        raise NiftiError(
            f"{path}: file ends at byte {len(raw)}, header promises {count * dt.itemsize} bytes of voxels from byte {offset}"
        )

    pixdim = list(struct.unpack(order + "8f", head[76:108]))
    spacing = []
    for i, p in enumerate(pixdim[1:4]):
        if not np.isfinite(p) or p <= 0:
            notes.append(f"pixdim[{i + 1}] = {p} repaired to 1 mm")
            p = 1.0
        spacing.append(float(p))

    data = np.frombuffer(raw, dtype=dt, count=count, offset=offset).reshape(nz, ny, nx)
    if not dt.isnative:
        data = data.astype(dt.newbyteorder("="))

    slope, inter = struct.unpack(order + "2f", head[112:120])
    if np.isfinite(slope) and slope != 0 and not (slope == 1 and inter == 0):
        if not np.isfinite(inter):
            notes.append("scl_inter non-finite: ignored")
            inter = 0.0
        data = data.astype(np.float32) * np.float32(slope) + np.float32(inter)
        notes.append(f"scaled by scl_slope {slope:g}, scl_inter {inter:g}")
        dtname = f"{dtname} (scaled to float32)"

    if data.dtype.kind == "f":
        bad = ~np.isfinite(data)
        nbad = int(bad.sum())
        if nbad:
            if nbad == data.size:
                raise NiftiError(f"{path}: every voxel is NaN or infinite")
            data = np.array(data, dtype=np.float32)
            data[bad] = np.nanmin(np.where(bad, np.inf, data))
            notes.append(f"{nbad} non-finite voxels set to the minimum")

    m, source = _linear_part(head, order, spacing, notes)
    data, spacing_world = _canonical(data, m, notes)
    return Volume(path, data, spacing_world, dtname, source, notes)


if __name__ == "__main__":
    import sys
    import time

    for p in sys.argv[1:]:
        t = time.perf_counter()
        try:
            v = load(p)
        except NiftiError as e:
            print(f"error: {e}")
            continue
        print(
            f"{p}: {v.dims} {v.spacing} {v.datatype} {v.affine_source} {v.notes} "
            f"range {v.data.min()}..{v.data.max()} in {1e3 * (time.perf_counter() - t):.0f} ms"
        )
