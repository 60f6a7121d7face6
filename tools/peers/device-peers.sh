#!/usr/bin/env bash
# On the device machine: installs the staged peers from .peers/, prints diagnostics, runs the runner.
#
#   tools/peers/device-peers.sh VOLUME [run_peers.py options...]
#   e.g. tools/peers/device-peers.sh /tmp/phantom.nii.gz --size 1920x1080 --frames 200 -k 5 --png --out $OUT/peers
#
# Before it: the caller has unpacked the Vulkan loader and libglvnd (dpkg -x .gl/*.deb /;
# ldconfig) and exported VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json.
# Carry .peers (tools/peers/stage.sh makes it). Environment knobs:
#   PYTHON                        interpreter (default python3, the device's 3.12 with numpy)
#   PEERS_SITE                    where the wheels and VTK are unpacked (default /tmp/site)
#   VTK_DEFAULT_EGL_DEVICE_INDEX  EGL device VTK renders on (default: VTK's choice, device 0)
#   __EGL_VENDOR_LIBRARY_FILENAMES  NVIDIA's EGL vendor file; found automatically when unset
#   PEERS_SKIP_PROBE=1            skip the diagnostics (saves ~2 s)
# Exit status: the runner's (0 if at least one peer produced a result).
set -uo pipefail

here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
stage=$root/.peers
site=${PEERS_SITE:-/tmp/site}
py=${PYTHON:-python3}
t0=$(date +%s.%N)

say() { echo "device-peers: $*"; }

if [ "$#" -lt 1 ]; then
    say "usage: $0 VOLUME [run_peers.py options...]"
    exit 2
fi
if [ ! -d "$stage" ]; then
    say "error: $stage missing: run tools/peers/stage.sh before the device call and carry .peers"
    exit 2
fi
if ! (cd "$stage" && sha256sum -c --quiet SHA256SUMS); then
    say "error: staged files in $stage do not match SHA256SUMS (incomplete carry?)"
    exit 2
fi

mkdir -p "$site"
# pip resolves nothing (--no-deps, --no-index): every wheel is in .peers, numpy/jinja2 are on the image.
if ! "$py" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target "$site" "$stage"/*.whl; then
    say "warning: pip install of the pygfx wheels failed: the pygfx peers will fail"
fi
# VTK stays compressed in the carry (38 MiB); unpacked it is about 300 MiB.
if ! tar -xJf "$stage"/vtk-*.tar.xz -C "$site" 2>/dev/null; then
    # No xz on the image? Python's lzma can do it.
    if ! "$py" -c 'import sys, tarfile; tarfile.open(sys.argv[1]).extractall(sys.argv[2])' "$stage"/vtk-*.tar.xz "$site"; then
        say "warning: unpacking VTK failed: the VTK peers will fail"
    fi
fi
# Byte-compile once, as an ordinary install would have: otherwise every fresh process of a
# time-to-first-pixel trial would pay for compiling pygfx's sources (or, read-only, every time).
"$py" -m compileall -q -j 0 "$site" >/dev/null 2>&1 || say "warning: compileall failed (imports will be slower)"
"$py" -m compileall -q "$here" >/dev/null 2>&1 || true
export PYTHONPATH="$site${PYTHONPATH:+:$PYTHONPATH}"
export PYTHONUNBUFFERED=1
export VTK_DEFAULT_OPENGL_WINDOW=${VTK_DEFAULT_OPENGL_WINDOW:-vtkEGLRenderWindow}
export WGPU_BACKEND_TYPE=${WGPU_BACKEND_TYPE:-Vulkan}

# NVIDIA's user-space libraries must be loadable for EGL (Vulkan finds its own through the ICD file).
nvidia_egl=""
if ldconfig -p 2>/dev/null | grep -q 'libEGL_nvidia.so.0'; then
    nvidia_egl=libEGL_nvidia.so.0
else
    for d in /usr/local/nvidia/lib64 /usr/local/nvidia/lib; do
        if [ -e "$d/libEGL_nvidia.so.0" ]; then
            export LD_LIBRARY_PATH="${LD_LIBRARY_PATH:+$LD_LIBRARY_PATH:}$d"
            nvidia_egl=$d/libEGL_nvidia.so.0
            say "libEGL_nvidia.so.0 not in ldconfig's cache; added $d to LD_LIBRARY_PATH"
            break
        fi
    done
fi
# EGL vendor: libglvnd reads /usr/share/glvnd/egl_vendor.d and /etc/glvnd/egl_vendor.d; the driver
# mount may keep NVIDIA's file under /usr/local/nvidia (the device README's hint). If the library
# exists but no vendor file names it, write a minimal one. Without NVIDIA's library (a machine
# without the GPU) EGL is left alone, so Mesa serves it.
if [ -n "$nvidia_egl" ] && [ -z "${__EGL_VENDOR_LIBRARY_FILENAMES:-}" ] && [ -z "${__EGL_VENDOR_LIBRARY_DIRS:-}" ] &&
    ! ls /usr/share/glvnd/egl_vendor.d/*nvidia*.json /etc/glvnd/egl_vendor.d/*nvidia*.json >/dev/null 2>&1; then
    for f in /usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json /usr/local/nvidia/glvnd/egl_vendor.d/10_nvidia.json; do
        if [ -f "$f" ]; then
            export __EGL_VENDOR_LIBRARY_FILENAMES=$f
            break
        fi
    done
    if [ -z "${__EGL_VENDOR_LIBRARY_FILENAMES:-}" ]; then
        mkdir -p /tmp/egl_vendor.d
        printf '{"file_format_version": "1.0.0", "ICD": {"library_path": "%s"}}\n' "$nvidia_egl" >/tmp/egl_vendor.d/10_nvidia.json
        export __EGL_VENDOR_LIBRARY_FILENAMES=/tmp/egl_vendor.d/10_nvidia.json
        say "no NVIDIA EGL vendor file found; wrote $__EGL_VENDOR_LIBRARY_FILENAMES for $nvidia_egl"
    fi
fi
[ -z "$nvidia_egl" ] && say "note: no libEGL_nvidia.so.0 found: VTK's EGL will use whatever vendor glvnd finds (Mesa?)"
say "installed into $site in $(echo "$(date +%s.%N) - $t0" | awk '{ printf "%.1f", $1 - $3 }') s"

if [ "${PEERS_SKIP_PROBE:-0}" != 1 ]; then
    # Each check in its own process: a driver crash in one must not hide the others.
    for what in python vtk wgpu; do
        timeout 120 "$py" "$here/probe.py" --only "$what" 2>&1 | grep -v XDG_RUNTIME_DIR || true
    done
    if command -v nvidia-smi >/dev/null; then
        nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.mem,temperature.gpu,utilization.gpu --format=csv 2>&1 | sed 's/^/device-peers: /'
    fi
fi

exec "$py" "$here/run_peers.py" "$@"
