#!/bin/sh
# Upper bound of what `tools/setup.sh` (or `--dev`) downloads on a fresh Debian 12 machine: the
# recursive dependency closure of its packages (no recommends), summed from `apt-cache show`
# sizes, leaving out required and important packages (on every Debian install). Packages a
# machine already has are counted too, so a real download is smaller.
# Usage: tools/setup_download_size.sh [--dev]
set -eu
packages="mesa-vulkan-drivers libvulkan1 glslang-tools libx11-xcb1 libxcursor1 libxrandr2 libxi6 libxkbcommon-x11-0"
if [ "${1:-}" = "--dev" ]; then
    packages="$packages vulkan-validationlayers vulkan-tools spirv-tools xvfb xauth python3-venv"
fi
# shellcheck disable=SC2086
apt-cache depends --recurse --no-recommends --no-suggests --no-conflicts --no-breaks \
    --no-replaces --no-enhances $packages 2>/dev/null | grep -v '^[ <]' | sort -u |
    while read -r p; do
        apt-cache show --no-all-versions "$p" 2>/dev/null |
            awk -v p="$p" '/^Priority:/ {prio=$2} /^Size:/ && !s {s=$2} END {if (prio != "required" && prio != "important" && s) print p, s}'
    done | awk '{n++; t+=$2} END {printf "%d packages, %.1f MB\n", n, t/1e6}'
