#!/usr/bin/env bash
# The side-by-side benchmark on this machine (CPU: lavapipe for morphray and pygfx, llvmpipe for
# VTK), at a size a 2-core machine renders in minutes: the phantom as .nii.gz, `morphray bench`
# of the full plan, DVR with shading and MIP, then the peers on the same file, size and orbit.
#
#   bash benches/lavapipe-run.sh OUT_DIR [WxH] [FRAMES] [TRIALS]      (default 320x180, 20, 3)
#
# Needs a release build (cargo build --release) and a Python with VTK 9.7.1 and pygfx 0.17
# (tools/peers/README.md, "Running here"): PYTHON=/path/to/python (default python3).
set -uo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: bash benches/lavapipe-run.sh OUT_DIR [WxH] [FRAMES] [TRIALS]}
size=${2:-320x180}
frames=${3:-20}
trials=${4:-3}
py=${PYTHON:-python3}
bin=target/release/morphray
[ -x "$bin" ] || { echo "lavapipe-run: build first: cargo build --release" >&2; exit 2; }
mkdir -p "$out"
log="$out/run-log.txt"
: > "$log"
run() { echo "== morphray $*" | tee -a "$log"; "$bin" "$@" 2>&1 | tee -a "$log"; }
"$bin" phantom -o "$out/phantom.nii.gz" >/dev/null
common=(--size "$size" --tissues csf,gm,wm,pathology --frames "$frames" --repeat 3 --trials "$trials")
run bench "$out/phantom.nii.gz" "${common[@]}" --curvature on --shading on --json "$out/side-full.json"
run bench "$out/phantom.nii.gz" "${common[@]}" --shading on --json "$out/side-dvr-shaded.json"
run bench "$out/phantom.nii.gz" "${common[@]}" --mode mip --json "$out/side-mip.json"
"$py" tools/peers/run_peers.py "$out/phantom.nii.gz" --size "$size" --frames "$frames" \
    --trials "$trials" --png --out "$out/peers" 2>&1 | tee -a "$log"
rm -f "$out/phantom.nii.gz"
