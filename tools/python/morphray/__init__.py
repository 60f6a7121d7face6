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
import warnings
import zlib

import numpy as np

from . import _native
from ._native import DeviceError, Error, InputError, MemoryBudgetError

__all__ = [
    "Volume",
    "scene_options",
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

# ---------------------------------------------------------------------------------------------
# Scene options: the command line's own (one option model, `morphray::cli::scene_options`).
# Keyword arguments are written as the words a shell would pass and parsed by the library, so
# names, units, defaults and errors are `morphray render`'s. Python spellings: underscores for
# dashes (clip_plane), True/False for on/off switches and flags, tuples for pairs and lists, a
# dict for the repeatable TISSUE=VALUE options (window={"wm": (0.7, 0.9)}, opacity={"csf": 0.1},
# color={"wm": "#f0f0e0"}), colours as "#rrggbb" or (R, G, B) in 0..255.

_SCENE_OPTIONS = {long.replace("-", "_"): (long, kind, values, default, help_)
                  for long, kind, values, default, help_ in _native.scene_options()}
# Python-only spelling kept for convenience: jitter=False is no_jitter=True.
_ALIASES = {"jitter": lambda v: ("no_jitter", not v)}


def _number(value) -> str:
    if isinstance(value, bool):
        raise TypeError("expected a number, not a bool")
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    return repr(float(value))


def _item(value) -> str:
    """One value as the command line writes it: a str as it is, a path as its str (`matcap`),
    a number, or a tuple of numbers joined the way its option expects (pairs LO:HI, everything
    else by commas)."""
    if isinstance(value, str):
        return value
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if isinstance(value, (tuple, list, np.ndarray)):
        parts = [_number(v) for v in value]
        return ":".join(parts) if len(parts) == 2 else ",".join(parts)
    return _number(value)


def _value(name: str, value) -> str:
    if name == "size" and not isinstance(value, str):
        if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
            return f"{int(value)}x{int(value)}"
        return "x".join(str(int(v)) for v in value)
    if name == "crop" and not isinstance(value, str):
        return ",".join(f"{_number(a)}:{_number(b)}" for a, b in value)
    if name == "pan" and not isinstance(value, str):
        return ",".join(_number(v) for v in value)
    return _item(value)


def _layer_specs(layers) -> list:
    """render(layers=...)'s value as a list of `--layer` spec strings (None: none)."""
    if layers is None:
        return []
    if isinstance(layers, (str, os.PathLike)):
        layers = [layers]
    return [os.fspath(spec) for spec in layers]


def _scene_words(caller: str, options: dict) -> list:
    """The command-line words of `options` (keyword arguments of `caller`)."""
    words = []
    for name, value in options.items():
        if name in _ALIASES:
            name, value = _ALIASES[name](value)
        if name not in _SCENE_OPTIONS:
            known = ", ".join(sorted(list(_SCENE_OPTIONS) + list(_ALIASES)))
            raise TypeError(f"{caller}() got an unexpected keyword argument {name!r}; the scene "
                            f"options are {known} (`morphray render --help` explains each)")
        if value is None:
            continue
        long, kind, values, _, _ = _SCENE_OPTIONS[name]
        flag = f"--{long}"
        if kind == "flag":
            if value:
                words.append(flag)
        elif isinstance(value, bool):
            if set(values) != {"on", "off"}:
                raise TypeError(f"{name} takes one of {values}, not a bool")
            words.append(f"{flag}={'on' if value else 'off'}")
        elif kind == "list":
            items = [value] if isinstance(value, str) else list(value)
            if not items:
                items = [""]
            words.append(f"{flag}=" + ",".join(str(v) for v in items))
        elif kind == "repeated":
            if isinstance(value, dict):
                entries = [f"{k}={_item(v)}" for k, v in value.items()]
            elif isinstance(value, str) or (isinstance(value, tuple) and value
                                            and not isinstance(value[0], (tuple, list))):
                entries = [_item(value)]
            else:
                entries = [_item(v) for v in value]
            words.extend(f"{flag}={e}" for e in entries)
        else:
            words.append(f"{flag}={_value(name, value)}")
    return words


def scene_options() -> list:
    """The scene options render() and open() take, as (name, kind, accepted values, default,
    help) tuples: the command line's, with underscores for dashes."""
    return [(name, kind, values, default, help_)
            for name, (_, kind, values, default, help_) in _SCENE_OPTIONS.items()]


def _identity(normalize, contrast, modality) -> dict:
    return {"normalize": str(normalize), "contrast": str(contrast), "modality": str(modality)}



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


def _open_array(array, affine, name, scene, identity):
    affine = np.asarray(affine, dtype=np.float64)
    if affine.shape != (4, 4):
        raise InputError(f"the affine must be 4x4, not of shape {affine.shape}")
    return Volume(_native.open_array(_as_volume_array(array), affine, scene, identity, name=name))


def open(source, frame: int = 0, series=None, normalize="robust", contrast="auto",
         modality="auto", **scene) -> "Volume":
    """Opens a volume on the process's device and analyses its histogram.

    source: a path (str or os.PathLike) to a NIfTI-1/2 or ANALYZE file (.nii, .nii.gz,
    .hdr/.img) or a DICOM series (a folder, a DICOMDIR or a .dcm file), a nibabel image
    (anything with `.dataobj` and `.affine`), or an `(array, affine)` pair with the array indexed
    (i, j, k) and the 4x4 voxel-to-RAS+ mm affine.
    frame: which volume of a 4D file or image.
    series: for DICOM, a SeriesInstanceUID or the index `morphray info PATH` lists (default: the
    largest 3-D image series).
    normalize ("robust" or "minmax"), contrast ("auto", "t1", "t2", "pd", "flair") and modality
    ("auto", "mr", "ct", "pt", "other"): as `--normalize`, `--contrast` and `--modality`.
    **scene: render()'s scene options (e.g. preset="angio", tissues=["gm", "wm"]): the scene the
    volume is planned for, as the command line plans for its arguments; render() may still ask
    for another scene.
    """
    words = _scene_words("open", scene)
    identity = _identity(normalize, contrast, modality)
    if isinstance(source, (str, os.PathLike)):
        return Volume(_native.open_file(
            os.fspath(source), words, identity, frame=int(frame),
            series=None if series is None else str(series)))
    if hasattr(source, "dataobj") and hasattr(source, "affine"):
        data = np.asanyarray(source.dataobj)
        if data.ndim == 4:
            if not 0 <= frame < data.shape[3]:
                raise InputError(f"frame {frame} is out of range: the image has {data.shape[3]} frames")
            data = data[..., frame]
        name = getattr(source, "get_filename", lambda: None)() or "nibabel image"
        return _open_array(data, source.affine, str(name), words, identity)
    if isinstance(source, tuple) and len(source) == 2:
        return _open_array(source[0], source[1], "array", words, identity)
    raise TypeError(
        "morphray.open takes a path, a nibabel image or an (array, affine) pair, "
        f"not {type(source).__name__}")


def phantom(shape=(256, 256, 192), seed=None, noise=True, head=False, spacing=1.0,
            normalize="robust", **scene) -> "Volume":
    """Opens the synthetic T1 phantom (the paper's cohort-A size at 1 mm by default).

    head=True makes a whole head around the brain (skin, fat, muscle, skull, eyes, a face and a
    neck: `morphray phantom --head`), which brain extraction finds and masks; spacing is the
    voxel size in mm (the anatomy scales with the grid: 96x108x90 voxels of 2 mm hold a brain of
    about 800 cm^3). normalize and **scene as for open().
    """
    return Volume(_native.open_phantom(_scene_words("phantom", scene),
                                       _identity(normalize, "auto", "auto"),
                                       dims=tuple(int(n) for n in shape), seed=seed, noise=noise,
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

    @property
    def affine(self) -> np.ndarray:
        """The 4x4 voxel-to-world (RAS+ mm) affine of (i, j, k) indices, as nibabel's."""
        return np.array(self.header["affine"], dtype=np.float64)

    @property
    def spacing(self) -> tuple:
        """Voxel size along i, j, k in mm (the header's pixdim)."""
        return tuple(self.header["pixdim"])

    @property
    def header(self) -> dict:
        """A NIfTI-like header: "dim", "pixdim", "datatype" (stored dtype), "scl_slope",
        "scl_inter", "affine" (4x4 rows), "affine_source" (sform, qform, pixdim, dicom or
        synthetic), "xyz_units", "descrip", and "facts" (what the file says about the scan:
        modality, sequence, timing, names)."""
        return json.loads(_native.volume_header(self._native))

    def __array__(self, dtype=None, copy=None):
        """The volume's values in physical units, (i, j, k) as nibabel's: the stored dtype
        when the file has no scaling, float32 otherwise."""
        data = _native.volume_data(self._native)
        return data if dtype is None else data.astype(dtype)

    def to_nifti(self, path, data=None, force=False) -> None:
        """Writes the volume, or `data` (an (i, j, k) array on the volume's grid, e.g. a map
        from derive()) with the volume's affine, as NIfTI-1 (.nii or .nii.gz). An existing file
        is replaced only with force=True; the input file never."""
        if data is not None:
            data = np.asanyarray(data)
            if data.dtype not in _NATIVE_DTYPES:
                data = data.astype(np.float32)
        _native.to_nifti(self._native, os.fspath(path), data=data, force=bool(force))

    def to_nibabel(self, data=None):
        """A nibabel Nifti1Image of the volume, or of `data` on its grid, with its affine
        (nibabel must be installed)."""
        import nibabel
        array = np.asarray(self) if data is None else np.asanyarray(data)
        if array.shape != self.shape:
            raise ValueError(f"data of shape {array.shape} is not on the volume's grid {self.shape}")
        return nibabel.Nifti1Image(array, self.affine)

    def render(self, scene=None, layers=None, **options) -> np.ndarray:
        """Renders one frame; returns an (H, W, 4) uint8 RGBA array (rows top to bottom).

        layers=["zstat.nii.gz:red-yellow:3.1:8:cluster=20"] (or one string) draws up to two
        intensity layers over the volume, each on its own grid, as `morphray render --layer`
        (FILE[:MAP[:LO:HI]][:thr=T][:neg=MAP|off][:cluster=N][:opacity=A]); a layer file is
        read once per volume.

        scene="view.json" renders a scene document's scene (written by save_scene(),
        `morphray render --save-scene` or the viewer's File > Save scene...) on this volume;
        only size= may be given with it.

        The options are `morphray render`'s scene options by the same names and units
        (underscores for dashes; `morphray.scene_options()` lists them, `morphray render
        --help` explains each): size=(W, H) or N (default 512x512), mode "dvr" | "mip" |
        "minip", tissues=["gm", "wm"] ("head" draws the head around an extracted brain),
        preset, brain "auto" | "on" | "off", windows "adaptive" | "paper", view "left" | ...,
        azimuth, elevation, zoom, pan=(right, up) mm, projection, step (voxels), curvature and
        shading (True/False or "on"/"off"; a still is shaded unless shading=False, as the
        command line's), gradient, derived_precision, background "#rrggbb" or (R, G, B) in
        0..255, no_jitter (or jitter=False), window={"wm": (0.7, 0.9)} (I_norm), opacity=
        {"csf": 0.1} (per mm), color={"wm": "#f0f0e0"}, crop=((0, 1), (0, 1), (0.5, 1)),
        clip_plane=[(1, 0, 0, 0)], colormap, denoise. A bad name raises TypeError, a bad value
        ValueError with the command line's message. A picture that shows only the background
        raises a warning (warnings.warn) saying why and what to try.
        """
        layer_specs = _layer_specs(layers)
        if scene is not None:
            size = options.pop("size", None)
            if options:
                raise TypeError(f"render(scene=...) takes only size= besides the document; got "
                                f"{', '.join(sorted(options))} (the document holds the whole scene)")
            # The command line's parser checks the size (1..16384 a side), as render(size=)'s.
            words = [] if size is None else _scene_words("render", {"size": size})
            image, note = self._native.render(words, document=os.fspath(scene),
                                              layers=layer_specs)
        else:
            image, note = self._native.render(_scene_words("render", options), layers=layer_specs)
        if note:
            warnings.warn(f"morphray: {note}", stacklevel=2)
        return image

    def save_scene(self, path, layers=None, **options) -> None:
        """Writes the scene the options describe (render()'s, by the same names) on this volume
        as a scene document: `morphray render --scene PATH`, `morphray view --scene PATH` and
        render(scene=PATH) show it again. The volume must have been opened from a file (the
        document names its scan by path, relative to the document's folder). layers= as
        render()'s: recorded with the style they are drawn with."""
        self._native.save_scene(os.fspath(path), _scene_words("save_scene", options),
                                layers=_layer_specs(layers))

    def derive(self, maps=("gradient", "curvature"), denoise="none", vessel_scales=None) -> dict:
        """The derived maps as (i, j, k) arrays on the input grid, computed on the GPU, by
        `morphray derive`'s names: "normalized" (I_norm), "gradient" (|grad I_norm| per mm, the
        paper's eq. 4 term), "curvature" (k = g^T H g, eq. 3), "vesselness" (Frangi, 0..1, at
        vessel_scales mm) as float32, "denoised" (with denoise="gaussian:1", "median" or
        "bilateral:1,0.1", as --denoise; the other maps are then computed from it); "brain" as
        uint8, 1 inside the extracted brain (as brain="on" masks; all 0 when no brain-like
        region was found, which `brain_report()` says). Save one with to_nifti(path, data=...)."""
        if isinstance(maps, str):
            maps = [maps]
        scales = [] if vessel_scales is None else [float(v) for v in vessel_scales]
        return self._native.derive([str(m) for m in maps], denoise=str(denoise),
                                   vessel_scales=scales)

    def brain_report(self) -> dict:
        """What brain extraction decided: {"decision": "head" | "skull_stripped" | "not_found"
        | "not_a_head_scan",
        "describe": the same in words, "masks_with_auto": whether brain="auto" masks this
        volume, "brain_cm3", "outside_fraction" (tissue-band cells outside the brain), "params"
        (band, radii in mm), "host_ms", "total_ms"}. The report of the mask the volume holds,
        or of a new extraction when it holds none."""
        return json.loads(self._native.brain_report_json())

    def _repr_png_(self) -> bytes:
        """A 256x256 DVR thumbnail for Jupyter."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return _png(self.render(size=(256, 256), azimuth=35.0, elevation=20.0))

    def __repr__(self) -> str:
        x, y, z = self.shape
        return f"<morphray.Volume {self.label!r} {x}x{y}x{z} ({self.layout})>"
