#!/usr/bin/env bash
# The README's lighting figures (issue 34): MNI152 with the interactive look (headlight), the
# stills' default (studio lighting with depth cues), the cut-away and the built-in matcap (clay,
# with depth cues), at 384x384.
# Usage: tools/figures/lighting.sh MORPHRAY MNI152.nii.gz [OUT_DIR]
set -euo pipefail
M=${1:?usage: $0 MORPHRAY MNI152.nii.gz [OUT_DIR]}
MNI=${2:?usage: $0 MORPHRAY MNI152.nii.gz [OUT_DIR]}
OUT=${3:-tools/figures}
"$M" render "$MNI" --size 384x384 --force --lighting headlight --depth-cues off -o "$OUT/mni152-headlight.png"
"$M" render "$MNI" --size 384x384 --force -o "$OUT/mni152-studio.png"
"$M" render "$MNI" --size 384x384 --force --cutaway -o "$OUT/mni152-cutaway.png"
"$M" render "$MNI" --size 384x384 --force --lighting matcap -o "$OUT/mni152-matcap.png"
