"""morphray: GPU volume rendering and tissue peaks of MRI volumes, from Python.

    import morphray
    vol = morphray.open("sub-01_T1w.nii.gz")      # or a nibabel image, or (array, affine)
    vol.peaks()["table1"]["wm_norm"]              # the paper's Table-1 row, tissue peaks
    rgba = vol.render(size=(512, 512), azimuth=35, elevation=20)   # (H, W, 4) uint8
    vol                                           # shows a thumbnail in Jupyter

One Vulkan device per process serves every volume; `configure()` chooses it and the GPU
memory budget before the first volume is opened. GPU work runs with the GIL released.
Errors derive from `morphray.Error` (InputError, DeviceError, MemoryBudgetError); bad arguments
raise ValueError.
"""

from __future__ import annotations

import json
import os
import struct
import zlib

import numpy as np

from . import _native
from ._native import DeviceError, Error, InputError, MemoryBudgetError

__all__ = [
    "Volume",
    "open",
    "phantom",
    "configure",
    "device_name",
    "Error",
    "InputError",
    "DeviceError",
    "MemoryBudgetError",
]
__version__ = _native.__version__

# Sample types the engine takes as they are; other dtypes become float32.
_NATIVE_DTYPES = (np.uint8, np.int8, np.uint16, np.int16, np.float32)


def configure(device=None, memory_budget=None, validation=False):
    """Chooses the process's device and GPU memory budget.

    device: an index or a name substring as `morphray devices` lists them (None: the default
    choice). memory_budget: bytes of GPU memory the engine may hold (None: what the device
    allows); a volume over it is bricked. Changing either replaces the engine: volumes opened
    before must be opened again.
    """
    if memory_budget is not None:
        memory_budget = int(memory_budget)
        if memory_budget <= 0:
            raise ValueError("memory_budget must be a positive number of bytes")
    _native.configure(device=None if device is None else str(device),
                      memory_budget=memory_budget, validation=bool(validation))


def device_name() -> str:
    """The name of the Vulkan device the process renders on (starts it if needed)."""
    return _native.device_name()


def _as_volume_array(array):
    array = np.asanyarray(array)
    if array.ndim == 4 and array.shape[3] == 1:
        array = array[..., 0]
    if array.ndim != 3:
        raise InputError(
            f"a volume array must be 3D (i, j, k), not of shape {array.shape}; "
            "pick one frame of a 4D series with array[..., t]")
    if array.dtype not in _NATIVE_DTYPES:
        array = array.astype(np.float32)
    return array


def _open_array(array, affine, name):
    affine = np.asarray(affine, dtype=np.float64)
    if affine.shape != (4, 4):
        raise InputError(f"the affine must be 4x4, not of shape {affine.shape}")
    return Volume(_native.open_array(_as_volume_array(array), affine, name=name))


def open(source, frame: int = 0, series=None) -> "Volume":
    """Opens a volume on the process's device and analyses its histogram.

    source: a path (str or os.PathLike) to a NIfTI-1/2 or ANALYZE file (.nii, .nii.gz,
    .hdr/.img) or a DICOM series (a folder, a DICOMDIR or a .dcm file), a nibabel image
    (anything with `.dataobj` and `.affine`), or an `(array, affine)` pair with the array indexed
    (i, j, k) and the 4x4 voxel-to-RAS+ mm affine.
    frame: which volume of a 4D file or image.
    series: for DICOM, a SeriesInstanceUID or the index `morphray info PATH` lists (default: the
    largest 3-D image series).
    """
    if isinstance(source, (str, os.PathLike)):
        return Volume(_native.open_file(
            os.fspath(source), frame=int(frame),
            series=None if series is None else str(series)))
    if hasattr(source, "dataobj") and hasattr(source, "affine"):
        data = np.asanyarray(source.dataobj)
        if data.ndim == 4:
            if not 0 <= frame < data.shape[3]:
                raise InputError(f"frame {frame} is out of range: the image has {data.shape[3]} frames")
            data = data[..., frame]
        name = getattr(source, "get_filename", lambda: None)() or "nibabel image"
        return _open_array(data, source.affine, str(name))
    if isinstance(source, tuple) and len(source) == 2:
        return _open_array(source[0], source[1], "array")
    raise TypeError(
        "morphray.open takes a path, a nibabel image or an (array, affine) pair, "
        f"not {type(source).__name__}")


def phantom(shape=(256, 256, 192), seed=None, noise=True, head=False, spacing=1.0) -> "Volume":
    """Opens the synthetic T1 phantom (the paper's cohort-A size at 1 mm by default).

    head=True makes a whole head around the brain (skin, fat, muscle, skull, eyes, a face and a
    neck: `morphray phantom --head`), which brain extraction finds and masks; spacing is the
    voxel size in mm (the anatomy scales with the grid: 96x108x90 voxels of 2 mm hold a brain of
    about 800 cm^3).
    """
    return Volume(_native.open_phantom(tuple(int(n) for n in shape), seed=seed, noise=noise,
                                       head=bool(head), spacing=float(spacing)))


def _png(rgba: np.ndarray) -> bytes:
    """An RGBA8 PNG of an (H, W, 4) uint8 array (zlib only, no imaging library needed)."""
    height, width, _ = rgba.shape
    raw = b"".join(b"\x00" + rgba[row].tobytes() for row in range(height))

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
            + chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b""))


class Volume:
    """A volume on the GPU with its tissue analysis; made by `morphray.open`."""

    def __init__(self, native):
        self._native = native

    @property
    def label(self) -> str:
        """The input's name (path, "phantom", or the array's name)."""
        return self._native.label

    @property
    def shape(self) -> tuple:
        """Voxels along i, j, k."""
        return self._native.shape

    @property
    def warnings(self) -> list:
        """The loader's repairs and warnings about the input."""
        return self._native.warnings

    @property
    def layout(self) -> str:
        """"whole", or "bricked" when the volume is over the memory budget."""
        return self._native.layout

    def peaks(self) -> dict:
        """The tissue analysis: {"table1": the paper's Table-1 row, "peaks": {"csf", "gm", "wm"}
        each {"norm", "raw"} or None, "windows", "paper_windows", "in_paper_window",
        "contrast", "background_threshold", "dims", "file", "warnings"}."""
        return json.loads(self._native.summary_json())

    def render(self, size=(512, 512), mode="dvr", tissues=None, windows="adaptive",
               azimuth=0.0, elevation=0.0, zoom=1.0, projection="perspective",
               curvature=False, shading=False, step=0.5, jitter=True,
               background=(0.0, 0.0, 0.0), brain="auto", head_opacity=None,
               head_color=None) -> np.ndarray:
        """Renders one frame; returns an (H, W, 4) uint8 RGBA array (rows top to bottom).

        The arguments are `morphray render`'s: size=(W, H); mode "dvr", "mip" or "minip";
        tissues, e.g. ["gm", "wm"] (default csf, gm, wm), "head" among them drawing the head
        (skin, fat, muscle) translucent around an extracted brain; windows "adaptive" (on this
        volume's peaks) or "paper"; azimuth and elevation in degrees; zoom; projection
        "perspective" or "orthographic"; curvature and shading (the paper's eq. 3 and Phong);
        step in voxels; jitter; background RGB in 0..1; brain "auto" (a head scan shows its
        brain: tissues are classified inside the extracted brain only), "on" (mask whenever a
        brain is found, also in a skull-stripped volume) or "off" (every voxel); head_opacity
        (per mm, 0..1) and head_color (RGB in 0..1) style the head layer (`--opacity head=`,
        `--color head=`). Switching between "auto" and "on" costs nothing; "off" and back
        recomputes the derived volumes once.
        """
        width, height = (int(v) for v in size)
        if tissues is not None:
            tissues = [tissues] if isinstance(tissues, str) else [str(t) for t in tissues]
        r, g, b = (float(c) for c in background)
        return self._native.render(
            width, height, mode=str(mode), tissues=tissues, windows=str(windows),
            azimuth=float(azimuth), elevation=float(elevation), zoom=float(zoom),
            projection=str(projection), curvature=bool(curvature), shading=bool(shading),
            step=float(step), jitter=bool(jitter), background=(r, g, b), brain=str(brain),
            head_opacity=None if head_opacity is None else float(head_opacity),
            head_color=None if head_color is None else tuple(float(c) for c in head_color))

    def derive(self, maps=("gradient", "curvature")) -> dict:
        """The derived maps as (i, j, k) arrays on the input grid, computed on the GPU:
        "gradient" = |grad I_norm| per mm (the paper's eq. 4 term), "curvature" = k = g^T H g
        (eq. 3) and "vesselness" (Frangi, 0..1) as float32; "brain" as uint8, 1 inside the
        extracted brain (as brain="on" masks; all 0 when no brain-like region was found, which
        `brain_report()` says)."""
        if isinstance(maps, str):
            maps = [maps]
        return self._native.derive([str(m) for m in maps])

    def brain_report(self) -> dict:
        """What brain extraction decided: {"decision": "head" | "skull_stripped" | "not_found",
        "describe": the same in words, "masks_with_auto": whether brain="auto" masks this
        volume, "brain_cm3", "outside_fraction" (tissue-band cells outside the brain), "params"
        (band, radii in mm), "host_ms", "total_ms"}. The report of the mask the volume holds,
        or of a new extraction when it holds none."""
        return json.loads(self._native.brain_report_json())

    def _repr_png_(self) -> bytes:
        """A 256x256 DVR thumbnail for Jupyter."""
        return _png(self.render(size=(256, 256), azimuth=35.0, elevation=20.0))

    def __repr__(self) -> str:
        x, y, z = self.shape
        return f"<morphray.Volume {self.label!r} {x}x{y}x{z} ({self.layout})>"
