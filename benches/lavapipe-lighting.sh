#!/usr/bin/env bash
# Issue 34 on this machine's lavapipe: what the lighting and depth cues cost on MNI152 at
# 500x500 (the paper's canvas), 3 alternated rounds (benches/lighting-rounds.sh).
# Usage: benches/lavapipe-lighting.sh MORPHRAY MNI152.nii.gz [OUT_DIR]
set -uo pipefail
M=${1:?usage: $0 MORPHRAY MNI152.nii.gz [OUT_DIR]}
MNI=${2:?usage: $0 MORPHRAY MNI152.nii.gz [OUT_DIR]}
OUT=${3:-benches/results/lavapipe-$(date +%F)-lighting}
mkdir -p "$OUT"
"$M" --version | tee "$OUT/lighting.txt"
SIZE=500x500 FRAMES=5 LOG="$OUT/lighting.txt" M=$M bash "$(dirname "$0")/lighting-rounds.sh" "$MNI"
