#!/bin/sh
# The README's 3D label overlay (issue 16 item 3): the phantom's lesion and vessels from its
# ground-truth labels, drawn in the raymarch through faint tissue.
# Usage: tools/figures/overlay-3d.sh [MORPHRAY]
set -eu
morphray=${1:-morphray}
out=$(dirname "$0")
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$morphray" phantom -o "$tmp/phantom.nii.gz" --labels "$tmp/labels.nii.gz"
# The lesion (5), its edema (7, faint) and the vessels (6): the other labels fully transparent
# (A = 255).
cat > "$tmp/lut.txt" <<'LUT'
1 Skull 0 0 0 255
2 CSF 0 0 0 255
3 GM 0 0 0 255
4 WM 0 0 0 255
5 Lesion 255 220 0 0
6 Vessel 230 30 40 0
7 Edema 80 160 255 190
LUT
"$morphray" render "$tmp/phantom.nii.gz" -o "$out/phantom-overlay-3d.png" --size 512x512 \
    --view left --overlay "$tmp/labels.nii.gz" --overlay-lut "$tmp/lut.txt" --overlay-opacity 0.8 \
    --opacity csf=0.02 --opacity gm=0.08 --opacity wm=0.05
