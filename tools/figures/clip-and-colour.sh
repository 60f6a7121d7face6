#!/bin/sh
# The README's clipped render and greyscale MIP (issue 16 items 2 and 4), from the MNI152 T1
# template (tools/perturbation/fetch-templates.sh, or /work/shared/data here).
# Usage: tools/figures/clip-and-colour.sh MNI152.nii.gz [MORPHRAY]
set -eu
mni=${1:?usage: $0 MNI152.nii.gz [morphray binary]}
morphray=${2:-morphray}
out=$(dirname "$0")
# The right hemisphere (x >= 0 mm: the plane x = 0 keeps the side its normal +x points to),
# seen from the patient's left: the cut face is the midsagittal plane.
"$morphray" render "$mni" -o "$out/mni152-clipped.png" --size 512x512 --shading on \
    --view left --clip-plane 1,0,0,0
# Maximum intensity projection from above in exact greyscale (R = G = B), anterior at the top.
"$morphray" render "$mni" -o "$out/mni152-mip-gray.png" --size 512x512 --mode mip \
    --colormap gray --view superior
