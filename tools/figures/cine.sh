#!/bin/sh
# The README's 4-D figure (viewer-cine.png) and the frame-change timing: an EPI-like 4-D file
# (cine_phantom.py), played in the viewer under Xvfb with the crosshair on the "activation".
# Usage: tools/figures/cine.sh [MORPHRAY]   (default: morphray on PATH)
set -eu
morphray=${1:-morphray}
here=$(dirname "$0")
work=$(mktemp -d)
python3 "$here/cine_phantom.py" "$work/epi.nii"
xvfb-run -a -s "-screen 0 1280x1024x24" "$morphray" view "$work/epi.nii" \
    --mode mip --play --fps 4 --size 1100x700 --frames 2 \
    --script "$here/cine-script.txt" --screenshot "$here/viewer-cine.png"
rm -rf "$work"
