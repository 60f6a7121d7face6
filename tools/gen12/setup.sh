#!/usr/bin/env bash
# Builds Intel's Vulkan driver (ANV) and Mesa's no-op DRM shim from Debian's own Mesa source, so
# that Vulkan shows a stub Tiger Lake ("Intel(R) Xe Graphics (TGL GT2)", the paper's Iris Xe
# class) on a machine without Intel graphics. Pipelines compile with Intel's real backend
# compiler and the device reports TGL's real limits; dispatches do not execute.
#
# Idempotent and cached: everything lives under ${MORPHRAY_GEN12_DIR:-~/.cache/morphray/gen12}
# (outside any clone, so a second CI run reuses it); a finished build is only checked. Installs
# the build dependencies with apt-get (root or sudo). Takes about 8 minutes on 2 cores the first
# time. Ends by printing the environment lines that select the stub device; they are also
# written to $dir/env (tests and tools source it).
set -euo pipefail
dir="${MORPHRAY_GEN12_DIR:-${XDG_CACHE_HOME:-$HOME/.cache}/morphray/gen12}"
version="$(dpkg-query -W -f='${Version}' mesa-vulkan-drivers 2>/dev/null || true)"
version="${version:-22.3.6-1+deb12u2}"
upstream="${version%%-*}"
build="$dir/mesa-$upstream/build"
anv="$build/src/intel/vulkan/libvulkan_intel.so"
shim="$build/src/intel/tools/libintel_noop_drm_shim.so"
icd="$dir/intel_icd.json"

print_env() {
    {
        echo "LD_PRELOAD=$shim"
        echo "INTEL_STUB_GPU_PLATFORM=tgl"
        echo "VK_ICD_FILENAMES=$icd"
    } > "$dir/env"
    echo "gen12: the stub Tiger Lake is ready; select it with:"
    sed 's/^/export /' "$dir/env"
}

if [ -f "$anv" ] && [ -f "$shim" ] && [ -f "$icd" ]; then
    print_env
    exit 0
fi
mkdir -p "$dir"

sudo=""
if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || { echo "gen12: need root or sudo to install build dependencies" >&2; exit 1; }
    sudo="sudo"
fi
apt_env=(env DEBIAN_FRONTEND=noninteractive)
# Debian's source packages: a deb-src copy of the bookworm entry (only if none exists).
if ! grep -rqs '^Types:.*deb-src' /etc/apt/sources.list.d/ && ! grep -qs '^deb-src' /etc/apt/sources.list; then
    echo "gen12: enabling Debian source packages"
    sed 's/^Types: deb$/Types: deb-src/' /etc/apt/sources.list.d/debian.sources \
        | $sudo tee /etc/apt/sources.list.d/morphray-deb-src.sources >/dev/null
fi
deps=(meson ninja-build python3-mako libdrm-dev bison flex pkg-config libexpat1-dev zlib1g-dev
      libzstd-dev python3-ply dpkg-dev)
echo "gen12: installing build dependencies (${deps[*]})"
$sudo "${apt_env[@]}" apt-get update -qq
$sudo "${apt_env[@]}" apt-get install -y -qq --no-install-recommends "${deps[@]}" >/dev/null

cd "$dir"
if [ ! -d "mesa-$upstream" ]; then
    echo "gen12: fetching Debian's Mesa $version source"
    apt-get source -qq "mesa=$version" >/dev/null
fi
cd "mesa-$upstream"
# Meson runs Python generators that need mako: Debian's python3, not another one first on PATH.
export PATH="/usr/bin:$PATH"
if [ ! -f build/build.ninja ]; then
    echo "gen12: configuring (ANV and the drm shim only)"
    meson setup build -Dvulkan-drivers=intel -Dgallium-drivers= -Dplatforms= \
        -Dtools=drm-shim,intel -Dllvm=disabled -Dglx=disabled -Degl=disabled -Dgbm=disabled \
        -Dgles1=disabled -Dgles2=disabled -Dopengl=false -Dbuildtype=release \
        -Dshared-glapi=disabled -Dvalgrind=disabled -Dlibunwind=disabled >/dev/null
fi
echo "gen12: building (about 8 minutes on 2 cores)"
ninja -C build src/intel/vulkan/libvulkan_intel.so src/intel/tools/libintel_noop_drm_shim.so >/dev/null
cat > "$icd" <<JSON
{
    "file_format_version": "1.0.0",
    "ICD": {
        "library_path": "$anv",
        "api_version": "1.3.230"
    }
}
JSON
print_env
