#!/bin/sh
# The README's intensity-layer figures and timing (issue 31 item 4): a synthetic two-sided
# z-map on its own 2 mm grid (synthetic_zmap.py) over the MNI152 T1 (1 mm): from above with the
# default look, cut away through the motor blob, and an axial slice; then the layer's cost,
# medians of 3 alternated rounds of a 512x512 still with and without it.
# Usage: tools/figures/layers.sh MNI152.nii.gz PYTHON [MORPHRAY]
#   (PYTHON with numpy, scipy and nibabel)
set -eu
mni=$1
python=$2
morphray=${3:-morphray}
out=$(dirname "$0")
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$python" "$out/synthetic_zmap.py" "$mni" "$tmp/zmap.nii.gz"
layer="$tmp/zmap.nii.gz:red-yellow:3.1:8:cluster=20"
"$morphray" render "$mni" --size 512x512 --view superior --layer "$layer" -o "$out/layer-superior.png"
"$morphray" render "$mni" --size 512x512 --view left --cutaway=-38,-22,56 --layer "$layer" \
    -o "$out/layer-cutaway.png"
"$morphray" slice "$mni" --plane axial --mm 30 --layer "$layer" -o "$out/layer-slice.png"
ms() { sed -n 's/.*raymarch \([0-9.]*\) ms GPU.*/\1/p'; }
for round in 1 2 3; do
    "$morphray" render "$mni" --size 512x512 --view superior -o "$tmp/plain.png" | ms >> "$tmp/plain.txt"
    "$morphray" render "$mni" --size 512x512 --view superior --layer "$layer" -o "$tmp/layer.png" \
        | ms >> "$tmp/layer.txt"
done
median() { sort -n "$1" | sed -n 2p; }
echo "raymarch 512x512, superior, medians of 3 (ms): without layer $(median "$tmp/plain.txt"), with layer $(median "$tmp/layer.txt")"
