#!/usr/bin/env bash
# Installs what morphray needs on Debian 12 / Ubuntu, idempotently, by need.
#
# `tools/setup.sh` (to build and run morphray; a minute or less):
#   - a Vulkan loader and a Vulkan driver (libvulkan1, mesa-vulkan-drivers: lavapipe, Mesa's CPU
#     device, when there is no GPU; a GPU's own driver is used when installed);
#   - glslangValidator (glslang-tools: build.rs compiles the GLSL shaders with it);
#   - the X11 client libraries winit opens at run time for the viewer (libx11-xcb1,
#     libxcursor1, libxrandr2, libxi6, libxkbcommon-x11-0); runtime packages only, no -dev
#     packages are needed to build. The default build is X11 only (Wayland desktops run it
#     through XWayland); a `--features wayland` build dlopens libwayland-client0,
#     libwayland-cursor0 and libxkbcommon0 at run time, which every Wayland desktop has already.
# `tools/setup.sh --dev` (to run the tests: `cargo test`), the above and:
#   - the Khronos validation layers (vulkan-validationlayers: tests run with them as an
#     oracle), vulkan-tools (vulkaninfo), spirv-tools (spirv-val in tests);
#   - xvfb and xauth (the viewer's scripted tests run under a virtual X server);
#   - python3-venv, then the tests' Python environment (tools/pyenv.sh: a cached venv);
#   - the stub Tiger Lake (tools/gen12/setup.sh: Intel's ANV and Mesa's no-op DRM shim built
#     from Debian's Mesa source, about 8 minutes on 2 cores the first time, cached under
#     ~/.cache/morphray/gen12), for tests/gen12.rs and `morphray kernels` on Gen12.
# Rust itself is expected to be installed (rustup, 1.95 or newer); this script does not touch it.
set -euo pipefail

dev=0
case "${1:-}" in
    "") ;;
    --dev) dev=1 ;;
    -h|--help)
        sed -n '2,21p' "$0" | sed 's/^# \{0,1\}//'
        exit 0
        ;;
    *)
        echo "setup: unknown option '$1' (use --dev for the tests' tools, or nothing)" >&2
        exit 2
        ;;
esac

packages=(mesa-vulkan-drivers libvulkan1 glslang-tools
          libx11-xcb1 libxcursor1 libxrandr2 libxi6 libxkbcommon-x11-0)
if [ "$dev" -eq 1 ]; then
    packages+=(vulkan-validationlayers vulkan-tools spirv-tools xvfb xauth python3-venv)
fi
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
if [ "$dev" -eq 1 ]; then
    "$(dirname "$0")/pyenv.sh"
    "$(dirname "$0")/gen12/setup.sh"
    echo "setup: done (build, run and tests)"
else
    echo "setup: done (build and run; \`tools/setup.sh --dev\` adds what the tests need)"
fi
