#!/usr/bin/env bash
# Issue 34 on the lent H200, one call: are the depth cues free when switched off, and what do the
# stills' lighting settings cost in the accuracy study.
# 1. `morphray bench` of MNI152 and the built-in phantom at 1920x1080 (DVR, shaded), alternated
#    in one order per round, 3 rounds: the binary from before the lighting (b5fab24^, its only
#    look: the headlight) against this one with `--lighting headlight --depth-cues off` (the same
#    picture; the cue code is compiled out by specialization constant), `--lighting studio
#    --depth-cues off` and the stills' studio + cues.
# 2. `morphray accuracy` of MNI152, errors at 256x256, times at 1920x1080, 3 views, 15 frames:
#    every knob with its group; the lighting group ("studio + cues") is issue 34's.
# Build here: cargo build --release; cp target/release/morphray .gpu/; strip .gpu/morphray;
#   git worktree add /tmp/pre34 b5fab24^ && (cd /tmp/pre34 && cargo build --release) and copy
#   its stripped binary to .gpu/morphray-pre34; cp ../shared/data/mni152_t1_2009a.nii.gz
#   .gpu/mni152.nii.gz; then run(command="bash benches/device-cues-off.sh", carry=[".gl", ".gpu"]).
set -uo pipefail
# shellcheck source=benches/device-gpu-env.sh
source benches/device-gpu-env.sh
LOG="$OUT/cues-off.txt"
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee "$LOG"
$M phantom -o "$V/phantom.nii.gz" > /dev/null
T=$(mktemp -d)
looks=(
    "before-lighting|.gpu/morphray-pre34|"
    "headlight|$M|--lighting headlight --depth-cues off"
    "studio|$M|--lighting studio --depth-cues off"
    "studio+cues|$M|--lighting studio --depth-cues on"
)
for round in 1 2 3; do
    for file in .gpu/mni152.nii.gz "$V/phantom.nii.gz"; do
        for look in "${looks[@]}"; do
            IFS='|' read -r name binary flags <<< "$look"
            # shellcheck disable=SC2086 # the flags are words
            $binary bench "$file" --size 1920x1080 --frames 50 --repeat 1 --trials 0 --shading on \
                $flags > "$T/run.txt" 2>&1
            echo "$(basename "$file") $name r$round: $(grep -E '^raymarch:' "$T/run.txt" | head -1 | cut -c1-160)" | tee -a "$LOG"
        done
    done
done
$M accuracy .gpu/mni152.nii.gz --size 256x256 --time-size 1920x1080 --views 3 --frames 15 \
    --json "$OUT/accuracy-mni152.json" > "$OUT/accuracy-mni152.txt" 2>&1
tail -45 "$OUT/accuracy-mni152.txt"
