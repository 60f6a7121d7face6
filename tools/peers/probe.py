#!/usr/bin/env python3
"""Prints what the peers will run on, so that a failed device run can be understood.

Each check is independent and never raises: Python and numpy, the EGL vendor files glvnd will
see, VTK's render window class and GL_RENDERER (EGL, the device from VTK_DEFAULT_EGL_DEVICE_INDEX),
and every wgpu adapter (Vulkan ICDs from VK_DRIVER_FILES). Run with `--only vtk` or `--only wgpu`
to isolate one (a crash in a driver takes the whole process down, so device-peers.sh runs each in
its own process).
"""

import argparse
import glob
import os
import platform
import sys


def say(key, value):
    print(f"probe: {key}: {value}", flush=True)


def check_python():
    say("python", f"{platform.python_version()} at {sys.executable}")
    try:
        import numpy

        say("numpy", numpy.__version__)
    except ImportError as e:
        say("numpy", f"MISSING ({e})")
    for var in (
        "PYTHONPATH",
        "VK_DRIVER_FILES",
        "VK_ICD_FILENAMES",
        "__EGL_VENDOR_LIBRARY_FILENAMES",
        "__EGL_VENDOR_LIBRARY_DIRS",
        "VTK_DEFAULT_OPENGL_WINDOW",
        "VTK_DEFAULT_EGL_DEVICE_INDEX",
        "LD_LIBRARY_PATH",
    ):
        say(f"env {var}", os.environ.get(var, "(unset)"))
    dirs = ["/usr/share/glvnd/egl_vendor.d", "/etc/glvnd/egl_vendor.d", "/usr/local/nvidia/share/glvnd/egl_vendor.d"]
    for d in dirs:
        files = sorted(glob.glob(os.path.join(d, "*.json")))
        say(f"egl vendor files in {d}", ", ".join(os.path.basename(f) for f in files) or "none")
    libs = sorted(
        set(glob.glob("/usr/lib/x86_64-linux-gnu/libEGL*.so*") + glob.glob("/usr/local/nvidia/lib*/libEGL*.so*"))
    )
    say("libEGL files", ", ".join(libs) or "none")


def check_vtk():
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    try:
        from vtkmodules.vtkCommonCore import vtkVersion
        from vtkmodules.vtkRenderingCore import vtkRenderer, vtkRenderWindow
        import vtkmodules.vtkRenderingOpenGL2  # noqa: F401
        import vtkmodules.vtkRenderingVolumeOpenGL2  # noqa: F401
    except Exception as e:
        say("vtk", f"IMPORT FAILED: {type(e).__name__}: {e}")
        return
    say("vtk", f"{vtkVersion.GetVTKVersion()} from {os.path.dirname(vtkmodules.vtkRenderingOpenGL2.__file__)}")
    try:
        win = vtkRenderWindow()
        win.SetOffScreenRendering(1)
        win.SetSize(16, 16)
        win.AddRenderer(vtkRenderer())
        win.Render()
        win.WaitForCompletion()
        say("vtk window class", win.GetClassName())
        if hasattr(win, "GetNumberOfDevices"):
            # EGL devices VTK can pick with VTK_DEFAULT_EGL_DEVICE_INDEX (default 0).
            say("vtk EGL devices", win.GetNumberOfDevices())
        lines = [
            ln.strip()
            for ln in win.ReportCapabilities().splitlines()
            if ln.startswith(("OpenGL renderer", "OpenGL vendor", "OpenGL version", "EGL vendor", "EGL version"))
        ]
        for ln in lines:
            say("vtk", ln)
        if not lines:
            say("vtk", "no OpenGL context (ReportCapabilities is empty): EGL found no usable device")
    except Exception as e:
        say("vtk", f"RENDER FAILED: {type(e).__name__}: {e}")


def check_wgpu():
    try:
        import wgpu
    except Exception as e:
        say("wgpu", f"IMPORT FAILED: {type(e).__name__}: {e}")
        return
    try:
        import wgpu.backends.wgpu_native as native

        say("wgpu", f"wgpu-py {wgpu.__version__}, wgpu-native {native.__version__} ({native.lib_path})")
    except Exception as e:
        say("wgpu", f"wgpu-py {wgpu.__version__}, wgpu-native backend FAILED: {type(e).__name__}: {e}")
    try:
        adapters = wgpu.gpu.enumerate_adapters_sync()
        if not adapters:
            say("wgpu adapters", "NONE (no Vulkan ICD found: check VK_DRIVER_FILES)")
        for a in adapters:
            say("wgpu adapter", a.summary)
        chosen = wgpu.gpu.request_adapter_sync(power_preference="high-performance")
        say("wgpu adapter pygfx would get", chosen.summary if chosen else "none")
    except Exception as e:
        say("wgpu", f"ADAPTER QUERY FAILED: {type(e).__name__}: {e}")
    try:
        import pygfx

        say("pygfx", pygfx.__version__)
    except Exception as e:
        say("pygfx", f"IMPORT FAILED: {type(e).__name__}: {e}")


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--only", choices=("python", "vtk", "wgpu"), help="run one check only")
    args = p.parse_args()
    for name, fn in (("python", check_python), ("vtk", check_vtk), ("wgpu", check_wgpu)):
        if args.only in (None, name):
            fn()


if __name__ == "__main__":
    main()
