#!/usr/bin/env bash
# morphray and NiiVue side by side, one sheet per volume (issue 34 item 4), and the surface
# metrics of every picture (tools/figures/surface_metrics.py) with a comparison line per volume.
#
#   tools/figures/side-by-side.sh [OUT_DIR]      (default tools/figures/side-by-side)
#
# Volumes: the built-in phantom, MNI152 ($MNI) and the real scans in $REAL (chris_t1, T2w,
# CT_AVM, chris_MRA; a missing one is skipped with a note). Each at $SIZE (512x512), anterior view,
# three columns:
#   morphray default   `morphray render VOL --size SIZE` (no scene flag: its default view is
#                      anterior, azimuth 0 elevation 0, perspective 30 degrees)
#   morphray best      the same plus $BEST_FLAGS (default --step 0.25 --derived-precision f16)
#   morphray matcap    the default plus $MATCAP_FLAGS (default --lighting matcap: the built-in
#                      clay matcap, the lighting NiiVue and MRIcroGL offer; README "Lighting")
#   NiiVue defaults    its default 3D render (benches/niivue/page.html: sliceType RENDER, default
#                      volume shader, orthographic camera), camera at NiiVue's azimuth 180
#                      elevation 0, which is its anterior view (its azimuth 0 is posterior)
# Writes OUT_DIR/sheet-VOL.png (< 400 KB each) and OUT_DIR/metrics.txt (command line, machine,
# versions, the metrics of each picture, a comparison line per volume). The single pictures are
# kept in OUT_DIR/pictures/ (not committed: .gitignore) so the metrics can be re-run on them.
# Idempotent: every output is rewritten. Needs MORPHRAY (default: the release binary of
# /work/main, else `morphray` on PATH), node/npm and chromium (installed as
# benches/niivue/common.sh does), and a Python with numpy and pillow ($PY, default /tmp/proto).
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
ROOT=$(cd "$HERE/../.." && pwd)
OUT=${1:-$HERE/side-by-side}
SIZE=${SIZE:-512x512}
BEST_FLAGS=${BEST_FLAGS:---step 0.25 --derived-precision f16}
MATCAP_FLAGS=${MATCAP_FLAGS:---lighting matcap}
MNI=${MNI:-/work/shared/data/mni152_t1_2009a.nii.gz}
REAL=${REAL:-/work/shared/data/real}
PY=${PY:-/tmp/proto/bin/python}
if [ -z "${MORPHRAY:-}" ]; then
  MORPHRAY=/work/main/target/release/morphray
  [ -x "$MORPHRAY" ] || MORPHRAY=$(command -v morphray || true)
fi
NV_AZ=180 NV_EL=0 NV_FRAMES=1
export NV_PROBE=frame   # page.html waits for any drawn pixel (an angiogram's centre stays black)

die() { echo "error: $*" >&2; exit 2; }
[ -n "$MORPHRAY" ] && [ -x "$MORPHRAY" ] \
  || die "no morphray binary (set MORPHRAY=path, or cargo build --release and put target/release on PATH)"
"$PY" -c 'import numpy, PIL' 2>/dev/null \
  || die "$PY lacks numpy or pillow (set PY to a python with both: python3 -m venv v && v/bin/pip install numpy pillow)"
mkdir -p "$OUT/pictures"
OUT=$(cd "$OUT" && pwd)
NV_LOG=$OUT/pictures/niivue-console.log
: > "$NV_LOG"
# shellcheck source=benches/niivue/common.sh
. "$ROOT/benches/niivue/common.sh"
niivue_install
niivue_serve

"$MORPHRAY" phantom -o "$NV_WORK/phantom.nii.gz" >/dev/null
niivue_single_gzip "$NV_WORK/phantom.nii.gz"
NAMES=(phantom mni152) FILES=("$NV_WORK/phantom.nii.gz" "$MNI")
for scan in chris_t1 T2w CT_AVM chris_MRA; do
  if [ -f "$REAL/$scan.nii.gz" ]; then NAMES+=("$scan"); FILES+=("$REAL/$scan.nii.gz")
  else echo "note: $REAL/$scan.nii.gz not found, skipped" >&2; fi
done
[ -f "$MNI" ] || die "$MNI not found (set MNI=path to the MNI152 T1 2009a NIfTI)"

METRICS=$OUT/metrics.txt
read -r -a best <<< "$BEST_FLAGS"
read -r -a matcap <<< "$MATCAP_FLAGS"
{
  echo "command: BEST_FLAGS='$BEST_FLAGS' MATCAP_FLAGS='$MATCAP_FLAGS' SIZE=$SIZE tools/figures/side-by-side.sh ${1:-}"
  echo "machine: $(uname -n), $(nproc) cores, $(date -u +%FT%TZ)"
  echo "morphray: $("$MORPHRAY" --version) ($MORPHRAY, built $(date -u -r "$MORPHRAY" +%FT%TZ)); $("$MORPHRAY" devices 2>&1 | head -1)"
  echo "niivue: $(niivue_versions)"
} > "$METRICS"
# The device's name for the labels: "llvmpipe" from "#0 llvmpipe (LLVM 15.0.6, 256 bits) (cpu, ...".
DEVICE=$("$MORPHRAY" devices 2>/dev/null | sed -n 's/^#[0-9]* \([^ (]*\).*usable.*/\1/p' | head -1)
DONE=()
for i in "${!NAMES[@]}"; do
  v=${NAMES[$i]} f=${FILES[$i]} p=$OUT/pictures/$v
  echo "== $v" >&2
  "$MORPHRAY" render "$f" -o "$p-morphray-default.png" --size "$SIZE" 2>&1 | sed 's/^/  default: /' >&2
  "$MORPHRAY" render "$f" -o "$p-morphray-best.png" --size "$SIZE" "${best[@]}" 2>&1 | sed 's/^/  best: /' >&2
  "$MORPHRAY" render "$f" -o "$p-morphray-matcap.png" --size "$SIZE" "${matcap[@]}" 2>&1 | sed 's/^/  matcap: /' >&2
  niivue_add "$v" "$f"
  rm -f "$p-niivue.png"
  niivue_run "$v" "$SIZE" "$p-niivue.png" "$NV_AZ" "$NV_EL" > "$p-niivue.json"
  if [ ! -f "$p-niivue.png" ]; then
    rm -f "$OUT/sheet-$v.png"
    echo "NiiVue could not show $v (no sheet, no metrics): $(cut -c1-300 "$p-niivue.json")" | tee -a "$METRICS" >&2
    continue
  fi
  DONE+=("$v")
  "$PY" "$ROOT/benches/niivue/sheet.py" "$OUT/sheet-$v.png" \
    "$p-morphray-default.png" "morphray default: render --size $SIZE (Vulkan, ${DEVICE:-?})" \
    "$p-morphray-best.png" "morphray best: render --size $SIZE $BEST_FLAGS" \
    "$p-morphray-matcap.png" "morphray matcap: render --size $SIZE $MATCAP_FLAGS" \
    "$p-niivue.png" "NiiVue $NIIVUE_VERSION defaults, azimuth $NV_AZ elevation $NV_EL (WebGL2, ANGLE llvmpipe)" >&2
done
[ ${#DONE[@]} -gt 0 ] || die "NiiVue showed no volume (see $NV_LOG)"
"$PY" "$HERE/side_by_side_metrics.py" "$OUT/pictures" "${DONE[@]}" >> "$METRICS"
cat "$METRICS"
