#!/usr/bin/env python3
"""pygfx peer: volume MIP (wgpu-native, Vulkan) over morphray's orbit.

pygfx 0.17 has MIP, MinIP and isosurface volume modes but no composite DVR, so this is the MIP
comparison only. Measures, in this one process: time to first pixel (phases from the process start:
interpreter, imports, volume load, setup = float16 conversion + wgpu device + scene + renderer,
first frame synced on the GPU), then frame times over an orbit with a GPU sync per frame
(device._poll_wait(), i.e. wgpuDevicePoll(wait=True)). Writes one JSON object (--json) and prints a
one-line summary. See tools/peers/README.md for the fairness settings and why.

Sampling step: pygfx's volume_ray.wgsl hard-codes
    relative_step_size = clamp(sqrt(max(size.x, size.y, size.z)) / 20, 0.1, 0.8)   (voxels)
so a volume whose largest side is >= 256 voxels is sampled every 0.8 voxel, and no API changes it.
--step stock keeps that; --step 0.5 (default) swaps that one line of the shader source for a
constant 0.5 voxel (morphray's step) before the pipeline is built, so both sample alike.
"""

import time

T_SCRIPT_NS = time.monotonic_ns()  # first thing: the script's own start

import math  # noqa: E402
import os  # noqa: E402
import sys  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402

PEER = "pygfx"
STOCK_STEP_LINE = "let relative_step_size = clamp(sqrt(max(sizef.x, max(sizef.y, sizef.z))) / 20.0, 0.1, 0.8);"


def parse_args():
    p = common.base_parser(__doc__)
    p.add_argument(
        "--step",
        default="0.5",
        help="ray step in voxels: 'stock' = pygfx's own clamp(sqrt(max dim)/20, 0.1, 0.8), or a number "
        "(default 0.5, morphray's step; patched into the shader source)",
    )
    p.add_argument(
        "--dtype",
        choices=("float16", "native"),
        default="float16",
        help="texture type: float16 (default; hardware trilinear filtering) or the file's own type "
        "(int16/uint16 are filtered by hand in the shader, about 3.4x slower, measured)",
    )
    args = p.parse_args()
    if args.step != "stock":
        try:
            v = float(args.step)
            if not 0.01 <= v <= 4.0:
                raise ValueError
        except ValueError:
            p.error(f"--step must be 'stock' or a number of voxels in [0.01, 4], not {args.step!r}")
    return args


def stock_step(dims):
    return min(max(math.sqrt(max(dims)) / 20.0, 0.1), 0.8)


def patch_step(gfx_volumeshader, load_wgsl, step):
    """Makes VolumeRayShader use a constant ray step (voxels) instead of pygfx's size-based one."""
    code = load_wgsl("volume_ray.wgsl")
    if STOCK_STEP_LINE not in code:
        raise RuntimeError("pygfx's volume_ray.wgsl has no step line to patch (pygfx version changed?)")
    patched = code.replace(STOCK_STEP_LINE, f"let relative_step_size = {float(step)!r};")
    gfx_volumeshader.VolumeRayShader.get_code = lambda self: patched


def adapter_info(device):
    info = {}
    try:
        ai = device.adapter.info
        info = {k: ai[k] for k in ai.keys()} if hasattr(ai, "keys") else dict(ai)
    except Exception as e:  # diagnostics only
        info["error"] = str(e)
    try:
        info["summary"] = device.adapter.summary
    except Exception:
        pass
    return info


def main():
    args = parse_args()
    ph = common.Phases(T_SCRIPT_NS)
    if args.frames < 0:
        common.fail(PEER, args, "--frames must be >= 0")
    # wgpu-native also offers an OpenGL backend; the comparison is pygfx on Vulkan.
    os.environ.setdefault("WGPU_BACKEND_TYPE", "Vulkan")
    try:
        import numpy as np
        import wgpu
        import pygfx as gfx
        from pygfx.renderers.wgpu import load_wgsl
        from pygfx.renderers.wgpu.shaders import volumeshader
        from pygfx.renderers.wgpu.engine.update import ensure_wgpu_object
    except ImportError as e:
        common.fail(
            PEER, args, f"cannot import pygfx/wgpu ({e}); install the wheels from .peers (tools/peers/README.md)"
        )
    import nifti1

    ph.mark("imports")

    try:
        volume = nifti1.load(args.volume)
    except nifti1.NiftiError as e:
        common.fail(PEER, args, str(e))
    ph.mark("load")

    data = volume.data
    dmin, dmax = float(data.min()), float(data.max())
    clim = (dmin, dmax if dmax > dmin else dmin + 1.0)
    rescaled = False
    if args.dtype == "float16":
        if max(abs(dmin), abs(dmax)) <= 65504.0:
            tex_data = data.astype(np.float16)
        else:
            # Out of float16's range: map to [0, 1] (the grey ramp is linear, so the image is the same).
            tex_data = ((data.astype(np.float32) - clim[0]) / (clim[1] - clim[0])).astype(np.float16)
            clim = (0.0, 1.0)
            rescaled = True
    else:
        tex_data = data
        if data.dtype.itemsize > 4 or data.dtype == np.float64:
            tex_data = data.astype(np.float32)

    dims = volume.dims
    spacing = volume.spacing
    step = stock_step(dims) if args.step == "stock" else float(args.step)
    if args.step != "stock":
        try:
            patch_step(volumeshader, load_wgsl, step)
        except RuntimeError as e:
            common.fail(PEER, args, str(e))

    w, h = args.size
    try:
        device = gfx.renderers.wgpu.get_shared().device
    except Exception as e:
        common.fail(PEER, args, f"no wgpu device ({e}); is a Vulkan driver visible (VK_DRIVER_FILES)?")

    # Render into a texture (no canvas, no per-frame readback; --png reads the last frame back once).
    # rgba8unorm-srgb: the hardware encodes sRGB, as a swap chain would.
    # colorspace "physical": the texture is only a render target here (silences pygfx's srgb note).
    target = gfx.Texture(
        dim=2, size=(w, h, 1), format="rgba8unorm-srgb", colorspace="physical", usage=wgpu.TextureUsage.COPY_SRC
    )
    renderer = gfx.WgpuRenderer(target, pixel_scale=1, ppaa="none", pixel_filter="nearest", enable_events=False)
    scene = gfx.Scene()
    grid = gfx.Texture(tex_data, dim=3)  # data[z, y, x]: texture x = voxel i, as VTK's point order
    material = gfx.VolumeMipMaterial(clim=clim, interpolation="linear")
    vol = gfx.Volume(gfx.Geometry(grid=grid), material)
    vol.local.scale = spacing  # voxel (i, j, k) at (i, j, k) * spacing, as in common.eye_position
    scene.add(vol)

    # pygfx's fov spans the mean of width and height when the camera's aspect equals the view's;
    # this fov gives a vertical field of view of exactly 30 degrees (morphray's fov_y) at any aspect.
    aspect = w / h
    fov = 2.0 * math.degrees(math.atan((1.0 + aspect) / 2.0 * math.tan(math.radians(15.0))))
    camera = gfx.PerspectiveCamera(fov, aspect, maintain_aspect=False)
    camera.world.reference_up = (0.0, 0.0, 1.0)

    def set_camera(azimuth):
        eye, centre, up, dist, radius = common.eye_position(dims, spacing, w, h, azimuth)
        camera.local.position = eye
        camera.look_at(centre)
        camera.depth_range = (max(dist - 2.0 * radius, 1e-3 * dist), dist + 2.0 * radius)

    def render_frame(azimuth):
        set_camera(azimuth)
        renderer.render(scene, camera)  # records, submits, flushes into the target
        device._poll_wait()  # wgpuDevicePoll(wait=True): every submission done

    set_camera(args.azimuth)
    ph.mark("setup")

    try:
        render_frame(args.azimuth)
    except Exception as e:
        common.fail(PEER, args, f"first frame failed: {type(e).__name__}: {e}")
    ph.mark("first_frame")
    ttfp_ms = ph.total_ms()

    # The projection actually used (after the first render) must be morphray's: check it.
    p11 = float(camera.projection_matrix[1][1])
    fov_y_used = 2.0 * math.degrees(math.atan(1.0 / p11))

    ms, warm = common.run_orbit(
        render_frame, args.frames, args.warmup_frames, args.warmup_s, args.azimuth, args.budget_s
    )

    png = None
    if args.png:
        raw = device.queue.read_texture(
            {"texture": ensure_wgpu_object(target), "mip_level": 0, "origin": (0, 0, 0)},
            {"offset": 0, "bytes_per_row": 4 * w, "rows_per_image": h},
            (w, h, 1),
        )
        rgba = np.frombuffer(raw, np.uint8).reshape(h, w, 4).copy()
        rgba[..., 3] = 255
        common.write_png(args.png, rgba.tobytes(), w, h)
        png = os.path.abspath(args.png)
        if int(rgba[..., :3].max()) == 0:
            print(f"{PEER}: warning: the saved frame is entirely black", file=sys.stderr)

    info = adapter_info(device)
    try:
        import wgpu.backends.wgpu_native as wgpu_native

        native = wgpu_native.__version__
    except Exception:
        native = None
    stats = common.frame_stats(ms)
    result = common.result_skeleton(PEER, args, volume)
    result.update(
        {
            "peer": "pygfx-mip" + ("" if args.step != "stock" else "-stockstep"),
            "peer_version": gfx.__version__,
            "wgpu_py_version": wgpu.__version__,
            "wgpu_native_version": native,
            "renderer": info.get("device") or info.get("summary"),
            "adapter": info,
            "blend_mode": "mip",
            "sample_distance_voxels": step,
            "sample_distance_mode": "stock clamp(sqrt(max dim)/20, 0.1, 0.8)"
            if args.step == "stock"
            else "shader patched to a constant",
            "settings": {
                "pixel_scale": renderer.pixel_scale,
                "ppaa": "none",
                "pixel_filter": "nearest",
                "interpolation": material.interpolation,
                "texture_dtype": str(tex_data.dtype),
                "rescaled_to_unit": rescaled,
                "clim": list(clim),
                "fov_y_deg_used": round(fov_y_used, 6),
                "target": "rgba8unorm-srgb texture (no canvas, no per-frame readback)",
                "sync": "renderer.render() + device._poll_wait() per frame",
                "mip_refinement": "pygfx adds 4 bisection steps (8 samples) around the maximum per ray",
            },
            **common.timing_fields(ttfp_ms, ph, ms, stats, warm, args, png),
        }
    )
    summary = (
        f"{result['peer']} {result['peer_version']} (wgpu {wgpu.__version__}) on {result['renderer']}: {w}x{h}, "
        f"step {step:g} voxel, ttfp {ttfp_ms:.0f} ms ({', '.join(f'{k} {v:.0f}' for k, v in ph.ms.items())})"
    )
    summary += common.orbit_summary(ms, stats)
    common.finish(result, args, summary)


if __name__ == "__main__":
    main()
