#!/bin/sh
# The README's brain extraction pictures (issue 27): a real T1 head with its skull rendered by
# default (the brain), with the head layer around it (`--tissues head,...`), and without
# extraction (`--brain off`: the face); the clinical T2 head (1x1x2 mm) by default and with
# `--brain off`; the same for the built-in head phantom.
# The real scans are chris_t1.nii.gz and T2w.nii.gz from ../shared/data/real
# (niivue-demo-images; chris_t1 C. Rorden, CC BY-NC 4.0); they are not part of the repository.
# Usage: tools/figures/brain.sh REAL_DIR [MORPHRAY]
set -eu
real=${1:?usage: $0 REAL_DIR [morphray binary]}
morphray=${2:-morphray}
out=$(dirname "$0")
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
t1="$real/chris_t1.nii.gz"
"$morphray" render "$t1" -o "$out/head-t1-brain.png" --size 512x512 --shading on
"$morphray" render "$t1" -o "$out/head-t1-head.png" --size 512x512 --shading on \
    --tissues head,csf,gm,wm --azimuth 60
"$morphray" render "$t1" -o "$out/head-t1-brain-off.png" --size 512x512 --shading on --brain off
t2="$real/T2w.nii.gz"
"$morphray" render "$t2" -o "$out/head-t2-brain.png" --size 512x512 --shading on
"$morphray" render "$t2" -o "$out/head-t2-brain-off.png" --size 512x512 --shading on --brain off
"$morphray" phantom --head -o "$tmp/head.nii.gz"
"$morphray" render "$tmp/head.nii.gz" -o "$out/phantom-head-brain.png" --size 512x512 --shading on
"$morphray" render "$tmp/head.nii.gz" -o "$out/phantom-head-off.png" --size 512x512 --shading on \
    --brain off
