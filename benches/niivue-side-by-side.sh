#!/usr/bin/env bash
# morphray and NiiVue side by side on this machine's CPU devices (issue 33 item 4, issue 34 item 4).
#
#   benches/niivue-side-by-side.sh MORPHRAY_BINARY [ROUNDS] [OUT_DIR]
#
# Installs what it needs, idempotently, outside the repository (~/.cache/morphray/niivue):
# Debian's chromium (apt-get), @niivue/niivue, playwright-core (drives /usr/bin/chromium; no
# browser download) and esbuild (bundles NiiVue's ES modules for a plain static page) from npm,
# versions pinned below. Serves benches/niivue/page.html on 127.0.0.1 (python3 -m http.server).
#
# NiiVue: WebGL2 build, 3D render tile alone (sliceType RENDER), its default volume shader and
# camera (orthographic, azimuth 110, elevation 10), orientation cube, colorbar and 3D crosshair
# hidden. Chromium runs headless with ANGLE on Mesa llvmpipe (--use-angle=gl-egl; $NV_ANGLE to
# change: swiftshader works too, vulkan did not initialise WebGL2 here).
# morphray: `bench` on lavapipe, shading on (its `render` default), step 0.5 (default).
# Timing rounds alternate NiiVue and morphray for each volume and size.
#   frame: NiiVue = median of FRAMES redraws over an orbit, each ended by a 1-pixel readPixels;
#          morphray = `bench --frames FRAMES` raymarch GPU median ms/frame.
#   first frame, cold: NiiVue = navigation start -> first frame whose centre pixel is not background
#          (fresh browser, fresh profile, no shader disk cache); browser launch reported apart.
#          morphray = `bench --trials 1` cold "first pixel" (fresh process, empty pipeline cache,
#          process start -> first frame's fence).
# LEAN_FLAGS (e.g. "--classification volume"): morphray's frame also with these flags, right
#   after its default one in each round (file morphray-lean-*; a "lean" row in the table).
# Pictures (500x500, both renderers' defaults): NiiVue canvas screenshot at its default view;
# morphray render --projection orthographic --azimuth 250 --elevation 10 (morphray's azimuth 270
# is the patient's left; NiiVue's 110 shows the left hemisphere turned 20 degrees to anterior).
set -euo pipefail
MORPHRAY=${1:?usage: $0 MORPHRAY_BINARY [ROUNDS] [OUT_DIR]}
ROUNDS=${2:-3}
HERE=$(cd "$(dirname "$0")" && pwd)
OUT=${3:-$HERE/results/lavapipe-$(date -u +%F)-niivue}
FRAMES=${FRAMES:-6}
NV_FRAMES=$FRAMES NV_LOG=$OUT/raw/niivue-console.log
# shellcheck source=benches/niivue/common.sh
. "$HERE/niivue/common.sh"
# Timed VOLUME:SIZE pairs; morphray's cold first pixel (bench --trials 1: three fresh processes)
# only at COLD_SIZE, to keep a round within a few minutes on 2 shared cores.
PAIRS=${PAIRS:-mni152:500x500 mni152:960x540 phantom:500x500 phantom:960x540}
COLD_SIZE=${COLD_SIZE:-500x500}
MNI=${MNI:-/work/shared/data/mni152_t1_2009a.nii.gz}
REAL=${REAL:-/work/shared/data/real}
PY=${PY:-/tmp/proto/bin/python}   # needs pillow

[ -x "$MORPHRAY" ] || { echo "error: $MORPHRAY is not an executable morphray binary (build with cargo build --release)" >&2; exit 2; }
mkdir -p "$OUT/raw"
niivue_install
niivue_serve
WORK=$NV_WORK
"$MORPHRAY" phantom -o "$WORK/phantom.nii.gz" >/dev/null
niivue_single_gzip "$WORK/phantom.nii.gz"
declare -A VOL=([mni152]=$MNI [phantom]=$WORK/phantom.nii.gz)
[ -f "$REAL/chris_t1.nii.gz" ] && VOL[chris_t1]=$REAL/chris_t1.nii.gz
[ -f "$REAL/T2w.nii.gz" ] && VOL[T2w]=$REAL/T2w.nii.gz
for v in "${!VOL[@]}"; do niivue_add "$v" "${VOL[$v]}"; done
echo "machine: $(uname -n), $(nproc) cores, $(date -u +%FT%TZ); chromium $(chromium --version | tail -1)" | tee "$OUT/raw/machine.txt"
# APPEND=1 adds rounds to an earlier run's raw output (ROUNDS=0: only the pictures and the table).
[ "${APPEND:-0}" = 1 ] || : > "$OUT/raw/niivue.jsonl"
FIRST_ROUND=${FIRST_ROUND:-1}   # with APPEND=1: number the added rounds after the earlier ones
for r in $(seq "$FIRST_ROUND" $((FIRST_ROUND + ROUNDS - 1))); do
  for pair in $PAIRS; do
      v=${pair%%:*} s=${pair#*:}
      trials=0; [ "$s" = "$COLD_SIZE" ] && trials=1
      echo "round $r: $v $s" >&2
      niivue_run "$v" "$s" "$WORK/nv.png" | sed "s/^{/{\"round\":$r,\"name\":\"$v\",/" | tee -a "$OUT/raw/niivue.jsonl" | cut -c1-160
      "$MORPHRAY" bench "${VOL[$v]}" --size "$s" --frames "$FRAMES" --repeat 1 --trials $trials \
        --shading on > "$OUT/raw/morphray-$v-$s-r$r.txt" 2>&1
      grep -E "^raymarch:|total \(spawn" "$OUT/raw/morphray-$v-$s-r$r.txt" | cut -c1-100
      if [ -n "${LEAN_FLAGS:-}" ]; then
          # shellcheck disable=SC2086 # the flags are words
          "$MORPHRAY" bench "${VOL[$v]}" --size "$s" --frames "$FRAMES" --repeat 1 --trials 0 \
            --shading on $LEAN_FLAGS > "$OUT/raw/morphray-lean-$v-$s-r$r.txt" 2>&1
          grep -E "^raymarch:" "$OUT/raw/morphray-lean-$v-$s-r$r.txt" | cut -c1-100
      fi
  done
done

for v in ${PICTURES-mni152 phantom chris_t1 T2w}; do
  [ -n "${VOL[$v]:-}" ] || continue
  echo "pictures: $v" >&2
  niivue_run "$v" 500x500 "$WORK/$v-niivue.png" > "$OUT/raw/niivue-picture-$v.json"
  [ -f "$WORK/$v-niivue.png" ] || { echo "NiiVue could not show $v: $(cut -c1-200 "$OUT/raw/niivue-picture-$v.json")" >&2; continue; }
  "$MORPHRAY" render "${VOL[$v]}" -o "$WORK/$v-morphray.png" --size 500x500 \
    --projection orthographic --azimuth 250 --elevation 10 >/dev/null
  "$PY" "$HERE/niivue/sheet.py" "$OUT/sheet-$v.png" \
    "$WORK/$v-niivue.png" "NiiVue $NIIVUE_VERSION (WebGL2, llvmpipe)" \
    "$WORK/$v-morphray.png" "morphray (Vulkan, lavapipe)"
done
"$PY" "$HERE/niivue/report.py" "$OUT/raw" | tee "$OUT/table.md"
