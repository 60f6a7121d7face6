#!/bin/sh
# The README's "every real scan at default settings" row (issue 28, item 4): each scan in
# ../shared/data/real rendered with no option but the size, so the picture is what a user gets
# first: the T1 head's brain, the clinical T2's brain, the CT angiogram's vessels, the TOF
# angiogram's vessels. Prints each render's decision lines (modality, preset, brain) into
# tools/figures/real-scans.txt beside the pictures.
# The scans are niivue-demo-images (chris_t1 and chris_MRA C. Rorden, CC BY-NC 4.0); they are
# not part of the repository.
# Usage: tools/figures/real-scans.sh REAL_DIR [MORPHRAY]
set -eu
real=${1:?usage: $0 REAL_DIR [morphray binary]}
morphray=${2:-morphray}
out=$(dirname "$0")
: > "$out/real-scans.txt"
for scan in chris_t1 T2w CT_AVM chris_MRA; do
    echo "== morphray render $scan.nii.gz -o real-$scan.png --size 384x384" >> "$out/real-scans.txt"
    rm -f "$out/real-$scan.png"
    "$morphray" render "$real/$scan.nii.gz" -o "$out/real-$scan.png" --size 384x384 \
        2>&1 | grep -v '^wrote' >> "$out/real-scans.txt"
done
cat "$out/real-scans.txt"
