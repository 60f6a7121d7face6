#!/usr/bin/env python3
"""VTK peer: vtkGPUVolumeRayCastMapper (OpenGL, offscreen EGL) over morphray's orbit.

Measures, in this one process: time to first pixel (phases from the process start: interpreter,
imports, volume load, transfer function, renderer/window setup, first frame synced on the GPU),
then frame times over an orbit with a GPU sync per frame. Writes one JSON object (--json) and
prints a one-line summary. See tools/peers/README.md for the fairness settings and why.

Composite (default): scalar opacity + colour in tissue bands (CSF, GM, WM placed from the volume's
bright-tissue level), gradient-opacity ramp (linear in |grad I|, the closest VTK has to morphray's
eq. 4 opacity = window(I) * |grad I| / max|grad I|), ShadeOn, linear interpolation.
MIP (--blend mip): maximum intensity, grey ramp over the data range, no shading.
"""

import time

T_SCRIPT_NS = time.monotonic_ns()  # first thing: the script's own start

import os  # noqa: E402
import sys  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402

PEER = "vtk"

# morphray's default tissue styles (src/scene/classification.rs): colour, opacity per mm.
STYLES = {
    "csf": ((0.30, 0.55, 1.00), 0.20),
    "gm": ((1.00, 0.55, 0.35), 0.30),
    "wm": ((0.96, 0.94, 0.82), 0.90),
}
# Band boundaries as fractions of the bright-tissue level B (95th percentile of the voxels above
# 10 % of the maximum, i.e. the upper side of the white-matter mode of a T1 scan). On the phantom
# (CSF 250, GM 600, WM 850, B ~ 883) they fall in the histogram valleys; WM is open above, as in
# morphray's windows, so vessels and the lesion stay visible. Background and the dark skull shell
# stay transparent.
CSF_LO, CSF_GM, GM_WM, EDGE = 0.18, 0.50, 0.82, 0.03


def parse_args():
    p = common.base_parser(__doc__)
    p.add_argument(
        "--blend",
        choices=("composite", "mip"),
        default="composite",
        help="composite = DVR with gradient opacity and shading (default); mip = maximum intensity projection",
    )
    p.add_argument(
        "--no-shade",
        action="store_true",
        help="composite without shading (the unshaded DVR morphray's default scene draws)",
    )
    p.add_argument(
        "--grad-max",
        type=float,
        default=None,
        metavar="G",
        help="max |grad I| in intensity units per mm for the gradient-opacity ramp; default: estimated "
        "from the volume (central differences on every 2nd voxel per axis, timed as the "
        "transfer_function phase)",
    )
    return p.parse_args()


def bright_level(np, data):
    """95th percentile of the voxels above 10 % of the maximum, on a 1-in-7 sample."""
    s = data.reshape(-1)[::7].astype(np.float32)
    mx = float(s.max())
    fg = s[s > 0.1 * mx] if mx > 0 else s
    if fg.size == 0:
        fg = s
    return float(np.percentile(fg, 95))


def grad_max_estimate(np, data, spacing):
    """max |grad I| (per mm) by central differences at every 2nd voxel of the interior per axis.

    Exact central differences at those voxels (1/8 of the volume): a sharp boundary is a surface, so
    the sample's maximum is close to the whole volume's at an eighth of the cost.
    """
    nz, ny, nx = data.shape
    if min(nx, ny, nz) < 3:
        return None

    def m(n):  # number of interior sample points 1, 3, 5, ... <= n - 2
        return len(range(1, n - 1, 2))

    mz, my, mx = m(nz), m(ny), m(nx)
    core = (slice(1, 1 + 2 * mz, 2), slice(1, 1 + 2 * my, 2), slice(1, 1 + 2 * mx, 2))
    sx, sy, sz = spacing
    acc = None
    for axis, h in ((0, sz), (1, sy), (2, sx)):
        n = (mz, my, mx)[axis]
        plus = list(core)
        minus = list(core)
        plus[axis] = slice(2, 2 + 2 * n, 2)
        minus[axis] = slice(0, 2 * n, 2)
        g = (data[tuple(plus)].astype(np.float32) - data[tuple(minus)].astype(np.float32)) * np.float32(0.5 / h)
        g *= g
        acc = g if acc is None else acc + g
    return float(np.sqrt(acc.max()))


def build_transfer_functions(np, vtk, data, spacing, blend, grad_max):
    """Returns (colour TF, scalar opacity TF, gradient opacity TF or None, description dict)."""
    dmin, dmax = float(data.min()), float(data.max())
    if dmax <= dmin:
        dmax = dmin + 1.0
    ctf = vtk["vtkColorTransferFunction"]()
    otf = vtk["vtkPiecewiseFunction"]()
    if blend == "mip":
        ctf.AddRGBPoint(dmin, 0.0, 0.0, 0.0)
        ctf.AddRGBPoint(dmax, 1.0, 1.0, 1.0)
        otf.AddPoint(dmin, 1.0)
        otf.AddPoint(dmax, 1.0)
        return ctf, otf, None, {"grey_ramp": [dmin, dmax], "opacity": 1.0}

    b = bright_level(np, data)
    e = EDGE * b
    knots = [dmin]
    points = []  # (intensity, (r, g, b), opacity per mm)
    bands = [(CSF_LO * b, "csf"), (CSF_GM * b, "gm"), (GM_WM * b, "wm")]
    prev_style = ((0.0, 0.0, 0.0), 0.0)
    points.append((dmin, prev_style))
    for x, name in bands:
        style = STYLES[name]
        lo, hi = x - e, x + e
        if lo > knots[-1] and hi < dmax:
            points.append((lo, prev_style))
            points.append((hi, style))
            knots.append(hi)
        prev_style = style
    points.append((dmax, prev_style))
    for x, (rgb, a) in points:
        ctf.AddRGBPoint(x, *rgb)
        otf.AddPoint(x, a)

    # Gradient opacity. VTK normalises |grad| by 0.25 * (scalar range) and looks the function up
    # over [0, 0.25 * range] (vtkOpenGLVolumeGradientOpacityTable), with |grad| in intensity per
    # average spacing; morphray's eq. 4 factor is |grad| / max|grad|. So: a line through 0 with
    # slope 1 / max|grad|, evaluated at the table's end (values beyond it clamp there).
    gtf = vtk["vtkPiecewiseFunction"]()
    avg_spacing = sum(spacing) / 3.0
    gmax_vtk = grad_max * avg_spacing
    table_end = 0.25 * (dmax - dmin)
    gtf.AddPoint(0.0, 0.0)
    if gmax_vtk <= table_end:
        gtf.AddPoint(gmax_vtk, 1.0)
        gtf.AddPoint(table_end, 1.0)
    else:
        gtf.AddPoint(table_end, table_end / gmax_vtk)
    desc = {
        "bright_level_B": round(b, 3),
        "bands": {"csf": [CSF_LO * b, CSF_GM * b], "gm": [CSF_GM * b, GM_WM * b], "wm": [GM_WM * b, dmax]},
        "edge_half_width": e,
        "opacity_per_mm": {k: v[1] for k, v in STYLES.items()},
        "grad_max_per_mm": grad_max,
        "gradient_opacity": "linear |grad|/grad_max, clamped by VTK at 0.25 * scalar range = %.1f per voxel (= %.3f of grad_max)"
        % (table_end, min(1.0, table_end / max(gmax_vtk, 1e-12))),
    }
    return ctf, otf, gtf, desc


def gl_renderer(ren_win):
    info = {}
    try:
        for line in ren_win.ReportCapabilities().splitlines():
            for key, name in (
                ("OpenGL renderer string:", "GL_RENDERER"),
                ("OpenGL vendor string:", "GL_VENDOR"),
                ("OpenGL version string:", "GL_VERSION"),
                ("EGL vendor string:", "EGL_VENDOR"),
            ):
                if line.startswith(key):
                    info[name] = line[len(key) :].strip()
    except Exception as e:  # diagnostics only
        info["error"] = str(e)
    return info


def main():
    args = parse_args()
    ph = common.Phases(T_SCRIPT_NS)
    if args.frames < 0:
        common.fail(PEER, args, "--frames must be >= 0")

    # Offscreen EGL unless the caller chose a window class (e.g. vtkOSOpenGLRenderWindow).
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    try:
        import numpy as np
        from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
        from vtkmodules.vtkCommonCore import vtkVersion
        from vtkmodules.vtkCommonDataModel import vtkImageData, vtkPiecewiseFunction
        from vtkmodules.vtkRenderingCore import (
            vtkColorTransferFunction,
            vtkRenderer,
            vtkRenderWindow,
            vtkVolume,
            vtkVolumeProperty,
            vtkWindowToImageFilter,
        )
        import vtkmodules.vtkRenderingOpenGL2  # noqa: F401  (registers the OpenGL/EGL classes)
        from vtkmodules.vtkRenderingVolume import vtkGPUVolumeRayCastMapper
        import vtkmodules.vtkRenderingVolumeOpenGL2  # noqa: F401  (registers the OpenGL mapper)
    except ImportError as e:
        common.fail(PEER, args, f"cannot import VTK ({e}); put vtkmodules on PYTHONPATH (tools/peers/README.md)")
    import nifti1

    ph.mark("imports")

    try:
        volume = nifti1.load(args.volume)
    except nifti1.NiftiError as e:
        common.fail(PEER, args, str(e))
    ph.mark("load")

    data = volume.data
    # GPU texture formats VTK handles natively; wider types go to float32.
    if data.dtype not in (np.uint8, np.int8, np.int16, np.uint16, np.float32):
        data = data.astype(np.float32)
    spacing = volume.spacing
    vtk = {"vtkColorTransferFunction": vtkColorTransferFunction, "vtkPiecewiseFunction": vtkPiecewiseFunction}
    grad_max = args.grad_max
    if args.blend == "composite" and grad_max is None:
        grad_max = grad_max_estimate(np, data, spacing) or float(data.max() - data.min())
    ctf, otf, gtf, tf_desc = build_transfer_functions(np, vtk, data, spacing, args.blend, grad_max)
    ph.mark("transfer_function")

    w, h = args.size
    image = vtkImageData()
    image.SetDimensions(*volume.dims)
    image.SetSpacing(*spacing)
    image.SetOrigin(0.0, 0.0, 0.0)  # voxel (i, j, k) at (i, j, k) * spacing, as in common.eye_position
    flat = np.ascontiguousarray(data).reshape(-1)  # x fastest: VTK's point order
    scalars = numpy_to_vtk(flat, deep=False)  # no copy; `flat` must outlive the render
    scalars.SetName("I")
    image.GetPointData().SetScalars(scalars)

    mapper = vtkGPUVolumeRayCastMapper()
    mapper.SetInputData(image)
    if args.blend == "mip":
        mapper.SetBlendModeToMaximumIntensity()
    else:
        mapper.SetBlendModeToComposite()
    # Fairness: fixed 0.5-voxel steps, full-resolution image, no interactive
    # down-sampling, no jitter.
    sample_mm = 0.5 * min(spacing)
    mapper.SetAutoAdjustSampleDistances(0)
    mapper.SetLockSampleDistanceToInputSpacing(0)
    mapper.SetSampleDistance(sample_mm)
    mapper.SetImageSampleDistance(1.0)
    mapper.SetUseJittering(0)

    prop = vtkVolumeProperty()
    prop.SetColor(ctf)
    prop.SetScalarOpacity(otf)
    prop.SetScalarOpacityUnitDistance(1.0)  # opacities are per mm, as morphray's
    prop.SetInterpolationTypeToLinear()
    if args.blend == "composite" and args.no_shade:
        prop.SetGradientOpacity(gtf)
        prop.ShadeOff()
    elif args.blend == "composite":
        prop.SetGradientOpacity(gtf)
        prop.ShadeOn()
        # morphray's headlight Phong (shaders/raymarch.comp shade()): 0.35 ambient + 0.65 diffuse on
        # |n.l| (two-sided) + 0.25 white highlight with exponent 24. VTK lights with the renderer's
        # headlight and two-sided lighting by default, so its Phong terms can be set to the same.
        prop.SetAmbient(0.35)
        prop.SetDiffuse(0.65)
        prop.SetSpecular(0.25)
        prop.SetSpecularPower(24.0)
    else:
        prop.ShadeOff()

    actor = vtkVolume()
    actor.SetMapper(mapper)
    actor.SetProperty(prop)

    renderer = vtkRenderer()
    renderer.SetBackground(0.0, 0.0, 0.0)
    renderer.AddVolume(actor)
    ren_win = vtkRenderWindow()
    wanted = os.environ.get("VTK_DEFAULT_OPENGL_WINDOW")
    if wanted and ren_win.GetClassName() != wanted:
        # VTK falls back (e.g. to OSMesa) when EGL finds no device, and the fallback may crash in
        # Render(): stop here with the reason instead.
        common.fail(
            PEER,
            args,
            f"VTK could not create a {wanted} (got {ren_win.GetClassName()}): EGL found no usable "
            "device; check __EGL_VENDOR_LIBRARY_FILENAMES / libEGL_nvidia (tools/peers/probe.py)",
        )
    ren_win.SetOffScreenRendering(1)
    ren_win.SetSize(w, h)
    ren_win.AddRenderer(renderer)
    ren_win.SetMultiSamples(0)

    cam = renderer.GetActiveCamera()
    cam.SetViewAngle(30.0)  # VTK's view angle is vertical (UseHorizontalViewAngle off), as morphray's fov_y

    def set_camera(azimuth):
        eye, centre, up, dist, radius = common.eye_position(volume.dims, spacing, w, h, azimuth)
        cam.SetFocalPoint(*centre)
        cam.SetPosition(*eye)
        cam.SetViewUp(*up)
        # The whole box lies within 2 radii of the centre (half-diagonal <= sqrt(3) r).
        cam.SetClippingRange(max(dist - 2.0 * radius, 1e-3 * dist), dist + 2.0 * radius)

    def render_frame(azimuth):
        set_camera(azimuth)
        ren_win.Render()
        ren_win.WaitForCompletion()  # glFinish: the frame is done on the GPU

    set_camera(args.azimuth)
    ph.mark("setup")

    try:
        render_frame(args.azimuth)
    except Exception as e:
        common.fail(PEER, args, f"first frame failed: {e}")
    ph.mark("first_frame")
    ttfp_ms = ph.total_ms()

    ms, warm = common.run_orbit(
        render_frame, args.frames, args.warmup_frames, args.warmup_s, args.azimuth, args.budget_s
    )

    gl = gl_renderer(ren_win)
    png = None
    if args.png:
        grab = vtkWindowToImageFilter()
        grab.SetInput(ren_win)
        grab.SetInputBufferTypeToRGBA()
        grab.ReadFrontBufferOff()
        grab.Update()
        rgba = vtk_to_numpy(grab.GetOutput().GetPointData().GetScalars()).reshape(h, w, 4)[::-1].copy()
        rgba[..., 3] = 255  # composite over the black background
        common.write_png(args.png, rgba.tobytes(), w, h)
        png = os.path.abspath(args.png)
        # Guard against a meaningless comparison: a blank frame means the renderer drew nothing.
        if int(rgba[..., :3].max()) == 0:
            print(f"{PEER}: warning: the saved frame is entirely black", file=sys.stderr)

    stats = common.frame_stats(ms)
    result = common.result_skeleton(PEER, args, volume)
    result.update(
        {
            "peer": f"vtk-{args.blend}",
            "peer_version": vtkVersion.GetVTKVersion(),
            "renderer": gl.get("GL_RENDERER"),
            "gl": gl,
            "window_class": ren_win.GetClassName(),
            "mapper_class": mapper.GetClassName(),
            "blend_mode": "composite" if args.blend == "composite" else "mip",
            "sample_distance_mm": sample_mm,
            "sample_distance_voxels": sample_mm / min(spacing),
            "settings": {
                "AutoAdjustSampleDistances": mapper.GetAutoAdjustSampleDistances(),
                "LockSampleDistanceToInputSpacing": mapper.GetLockSampleDistanceToInputSpacing(),
                "ImageSampleDistance": mapper.GetImageSampleDistance(),
                "UseJittering": mapper.GetUseJittering(),
                "interpolation": prop.GetInterpolationTypeAsString(),
                "shade": bool(prop.GetShade()),
                "phong": {
                    "ambient": prop.GetAmbient(),
                    "diffuse": prop.GetDiffuse(),
                    "specular": prop.GetSpecular(),
                    "specular_power": prop.GetSpecularPower(),
                },
                "gradient_opacity": args.blend == "composite",
                "ScalarOpacityUnitDistance": prop.GetScalarOpacityUnitDistance(),
                "sync": "vtkRenderWindow.Render() + WaitForCompletion() (glFinish) per frame",
                "texture_dtype": str(data.dtype),
            },
            "transfer_function": tf_desc,
            **common.timing_fields(ttfp_ms, ph, ms, stats, warm, args, png),
        }
    )
    summary = (
        f"{result['peer']} {result['peer_version']} on {result['renderer']}: {w}x{h}, "
        f"ttfp {ttfp_ms:.0f} ms ({', '.join(f'{k} {v:.0f}' for k, v in ph.ms.items())})"
    )
    summary += common.orbit_summary(ms, stats)
    common.finish(result, args, summary)


if __name__ == "__main__":
    main()
