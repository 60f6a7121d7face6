#!/usr/bin/env bash
# Stages what the device run of the peers needs into .peers/ at the repository root (git-ignored),
# for the device tool's `carry`. Run here, before the device call:
#
#   tools/peers/stage.sh [SOURCE_DIR]      # SOURCE_DIR defaults to ../shared/peers beside the checkout
#
# .peers/ holds ONLY what the device lacks (its image has Python 3.12, numpy, jinja2, markupsafe;
# ../.library/device/KINDS.md lists them):
#   - the pygfx 0.17 stack, every Requires-Dist of pygfx / wgpu / rendercanvas / cffi except numpy
#     and jinja2 (pygfx imports freetype, uharfbuzz and hsluv at import time, and wgpu's cffi needs
#     pycparser to parse its header, so none of them is optional);
#   - the trimmed VTK 9.7.1 (cp312, volume rendering + EGL), kept .tar.xz (38 MiB): unpacked on the
#     device into /tmp by device-peers.sh, since unpacked it would not fit the 64 MiB carry.
# Not staged: nibabel (the scripts read NIfTI themselves), vispy, pyopengl.
# Also writes .peers/SHA256SUMS, which device-peers.sh checks (a truncated carry fails loudly).
set -euo pipefail

root=$(git -C "$(dirname "$0")" rev-parse --show-toplevel)
src=${1:-$root/../shared/peers}
dst=$root/.peers
[ -d "$src" ] || { echo "stage.sh: error: $src: no such folder (give the folder holding the peer wheels)" >&2; exit 2; }

# Ignore .peers/ in the repository (worktrees share the main repository's info/exclude).
exclude="$(git -C "$root" rev-parse --path-format=absolute --git-common-dir)/info/exclude"
mkdir -p "$(dirname "$exclude")"
grep -qxF '/.peers/' "$exclude" 2>/dev/null || echo '/.peers/' >>"$exclude"

wanted=(
    'pygfx-0.17.0-*.whl'
    'wgpu-0.32.0-*.whl'
    'rendercanvas-*.whl'
    'pylinalg-*.whl'
    'hsluv-*.whl'
    'freetype_py-*.whl'
    'uharfbuzz-*.whl'
    'cffi-*cp312*.whl'
    'pycparser-*.whl'
    'vtk-9.7.1-cp312-trim-volume.tar.xz'
)
rm -rf "$dst"
mkdir -p "$dst"
for pattern in "${wanted[@]}"; do
    # shellcheck disable=SC2206  # the pattern is meant to glob
    matches=($src/$pattern)
    if [ ! -e "${matches[0]}" ]; then
        echo "stage.sh: error: nothing matches $src/$pattern" >&2
        exit 2
    fi
    if [ "${#matches[@]}" -ne 1 ]; then
        echo "stage.sh: error: several files match $src/$pattern (pip refuses two versions): ${matches[*]}" >&2
        exit 2
    fi
    cp "${matches[0]}" "$dst/"
done
(cd "$dst" && sha256sum -- * >SHA256SUMS)

total=$(du -sb "$dst" | cut -f1)
awk -v d="$dst" -v n="$(ls "$dst" | wc -l)" -v t="$total" 'BEGIN { printf "stage.sh: %s: %d files, %.1f MiB\n", d, n, t / 1048576 }'
limit=$((48 * 1024 * 1024))
if [ "$total" -gt "$limit" ]; then
    echo "stage.sh: warning: .peers/ is over 48 MiB; with ~12 MiB of other files the 64 MiB carry may overflow" >&2
fi
