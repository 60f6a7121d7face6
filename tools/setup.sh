#!/usr/bin/env bash
# Installs what morphray needs on Debian 12 / Ubuntu, idempotently:
#   - a Vulkan loader and a Vulkan driver (lavapipe, Mesa's CPU device, when there is no GPU);
#   - the Khronos validation layers (tests run with them as an oracle);
#   - glslangValidator (build.rs compiles the GLSL shaders with it) and spirv-val (tests);
#   - xvfb and xauth (the viewer's scripted test runs under a virtual X server), and the X11
#     client libraries winit opens at run time (libX11-xcb, libXcursor, libXrandr, libXi,
#     libxkbcommon-x11); runtime packages only, no -dev packages are needed to build;
#   - python3-venv, then the tests' Python environment (tools/pyenv.sh: a cached venv);
#   - the stub Tiger Lake (tools/gen12/setup.sh: Intel's ANV and Mesa's no-op DRM shim built
#     from Debian's Mesa source, about 8 minutes on 2 cores the first time, cached under
#     ~/.cache/morphray/gen12), for tests/gen12.rs and `morphray kernels` on Gen12.
# Rust itself is expected to be installed (rustup); this script does not touch it.
set -euo pipefail

packages=(mesa-vulkan-drivers libvulkan1 vulkan-validationlayers vulkan-tools glslang-tools spirv-tools xvfb xauth
          libx11-xcb1 libxcursor1 libxrandr2 libxi6 libxkbcommon-x11-0 python3-venv)
missing=()
for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
install_missing() {
    if [ ${#missing[@]} -eq 0 ]; then
        echo "setup: all packages present (${packages[*]})"
        return
    fi
    sudo=""
    if [ "$(id -u)" -ne 0 ]; then
        command -v sudo >/dev/null || { echo "setup: need root or sudo to install: ${missing[*]}" >&2; exit 1; }
        sudo="sudo"
    fi
    echo "setup: installing ${missing[*]}"
    $sudo env DEBIAN_FRONTEND=noninteractive apt-get update -qq
    $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
}
install_missing
"$(dirname "$0")/pyenv.sh"
"$(dirname "$0")/gen12/setup.sh"
echo "setup: done"
