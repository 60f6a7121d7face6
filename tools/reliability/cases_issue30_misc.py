"""Issue 30's non-DICOM cases beyond batch, interrupted writes and caches (cases_issue30.py):
values that would collapse in float32 (a float64 voxel at 1e300), integer minima, arguments
out of range, outputs that would collide, and the messages the issue named (an image too large
for the budget, an unusable voxel spacing, a decimal `--memory-budget`, a cache path that is a
file). Each case says what the output must say, so a wrong cause fails it too. The classes
start with `i30` (`probe.py --only i30` runs them all).

Decisions:
- Volumes are the probe's 16^3 blob (nifti.py) re-encoded: float64 with one voxel at 1e300,
  int32 with one voxel at -2^31 + 1, int16 with pixdim 1e-30. The 1e300 render must light
  pixels (before: blank) and say the voxel was clamped; its `convert` must say so too.
- View cases run without a window: they are refused while parsing the script or the options,
  before any window or device exists.
"""

import os

import nifti as nf
from case import Case, info, render_case

DIMS = (16, 16, 16)


def _blob_as(dtype, first):
    """The blob in `dtype` with voxel 0 replaced by `first`."""
    values = nf.blob(DIMS)
    values[0] = first
    return nf.nifti1(DIMS, dtype, data=nf.pack_voxels(values, dtype))


def collapsing_values(ws):
    cls = "i30 collapsing values"
    hot = ws.write("values/hot-1e300.nii", _blob_as("float64", 1e300))
    wide = ws.write("values/int32-min.nii", _blob_as("int32", -2147483647))
    converted = ws.fresh("converted.nii.gz")
    clamped = "1 of 4096 float64 voxels lie beyond.*the largest 1e300.*clamped"
    return [
        render_case(ws, cls, "float64 voxel at 1e300 renders", hot, lit=True, quick=True,
                    says=clamped, never_says="do not change"),
        Case(cls, "float64 voxel at 1e300 converts, saying what changed",
             ["convert", hot, "-o", converted], expect="ok", says=clamped),
        Case(cls, "int32 minimum is a value of the data", info(wide), expect="ok",
             says=r"intensity\s+-2147483647 \.\. \d+ "),
    ]


def argument_bounds(ws):
    cls = "i30 argument bounds"
    vol = ws.write("bounds/blob.nii", nf.nifti1(DIMS))
    png = ws.fresh("slice.png")
    script = ws.path("bounds/script.txt")

    def write_script(text):
        def setup():
            os.makedirs(os.path.dirname(script), exist_ok=True)
            with open(script, "w") as f:
                f.write(text)
        return setup

    view = ["view", "--offscreen", "--script", script]
    out = [
        Case(cls, "slice --mm outside the volume", ws.gpu("slice", vol, "--plane", "axial",
             "--mm", "500", "-o", png), expect="error", gpu=True, absent_on_failure=[png],
             says=r"--mm 500 is outside the volume.*spans", quick=True),
        render_case(ws, cls, "--step 1e-9", vol, "--step", "1e-9", expect="error",
                    says="finer than 0.015625 voxel"),
        Case(cls, "view --frames 4000000000", ["view", "--offscreen", "--frames",
             "4000000000"], expect="error", says="give 1 to 10000 frames"),
    ]
    for name, text, says in [
        ("script wait 99999999", "wait 99999999\n", "0..10000"),
        ("script idle 99999999", "idle 99999999\n", "0..10000"),
        ("script screenshot into a missing folder",
         f"screenshot {ws.path('bounds/missing/shot.png')}\n", "does not exist"),
    ]:
        out.append(Case(cls, name, view, expect="error", setup=write_script(text), says=says))
    return out


def colliding_outputs(ws):
    cls = "i30 colliding outputs"
    folder = ws.path("collide")
    target = os.path.join(folder, "p.nii.gz")

    def make_folder():
        os.makedirs(folder, exist_ok=True)

    return [
        Case(cls, "phantom --labels onto -o", ["phantom", "--dims", "16x16x12", "-o", target,
             "--labels", os.path.join(folder, ".", "p.nii.gz")], expect="error",
             setup=make_folder, absent_on_failure=[target],
             says="names the same file as --output", never_says="wrote", quick=True),
        Case(cls, "phantom --labels onto -o, --force", ["phantom", "--dims", "16x16x12", "-o",
             target, "--labels", target, "--force"], expect="error", setup=make_folder,
             absent_on_failure=[target], says="names the same file as --output"),
    ]


def messages(ws):
    cls = "i30 messages"
    vol = ws.write("messages/blob.nii", nf.nifti1(DIMS))
    tiny = ws.write("messages/pixdim-1e-30.nii", nf.nifti1(
        DIMS, pixdim=[1.0, 1e-30, 1e-30, 1e-30], qform_code=0, sform_code=0))
    cache_file = ws.write("messages/cache-file", b"not a folder")
    cache_argv, cache_png = ws.render(vol, cache=cache_file)
    return [
        render_case(ws, cls, "image too large for the budget", vol, "--memory-budget", "64M",
                    size="4096x4096", expect="error",
                    says="4096x4096 image is too large, not the volume.*fits is \\d+x\\d+",
                    never_says="bricked", quick=True),
        render_case(ws, cls, "pixdim 1e-30", tiny, expect="error",
                    says="voxel spacing .* is unusable.*pixdim",
                    never_says="invalid GPU request"),
        render_case(ws, cls, "pixdim 1e-30, MIP", tiny, "--mode", "mip", expect="error",
                    says="voxel spacing .* is unusable.*pixdim",
                    never_says="invalid GPU request"),
        Case(cls, "--memory-budget 1.5G", info(vol, "--memory-budget", "1.5G"), expect="ok"),
        Case(cls, "--memory-budget 1.5T", info(vol, "--memory-budget", "1.5T"),
             expect="error", says="512M, 1.5G"),
        Case(cls, "--pipeline-cache is a file", cache_argv, expect="ok", gpu=True,
             png=cache_png, lit=True, says="is a file, not a folder.*--pipeline-cache",
             never_says="os error 17"),
    ]


BUILDERS = (collapsing_values, argument_bounds, colliding_outputs, messages)
