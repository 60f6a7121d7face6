#!/usr/bin/env bash
# Fetches the MNI152 2009a T1 template and its GM and WM probability maps from the nilearn wheel
# on PyPI (nilearn ships them under nilearn/datasets/data/; it ships no brain mask), for the
# perturbation study (tools/examples/perturbation_study.rs, ACCURACY.md).
#
# Usage: tools/perturbation/fetch-templates.sh [DIR]   (default ~/.cache/morphray/nilearn)
# Prints the three paths. Idempotent: the wheel and the extracted files are reused when present.
#
# Why a pinned wheel and `--no-deps`: only three data files are needed, not nilearn's Python
# stack (numpy, scipy, ...), and the pinned version keeps the study's numbers reproducible.
set -euo pipefail

VERSION=0.14.1
DIR=${1:-"$HOME/.cache/morphray/nilearn"}
WHEEL="$DIR/nilearn-$VERSION-py3-none-any.whl"
FILES=(
  mni_icbm152_t1_tal_nlin_sym_09a_converted.nii.gz
  mni_icbm152_gm_tal_nlin_sym_09a_converted.nii.gz
  mni_icbm152_wm_tal_nlin_sym_09a_converted.nii.gz
)

mkdir -p "$DIR"
if [ ! -s "$WHEEL" ]; then
  command -v pip >/dev/null || { echo "fetch-templates: pip is needed (python3 -m ensurepip)" >&2; exit 1; }
  pip download "nilearn==$VERSION" --no-deps --only-binary=:all: -d "$DIR" >&2
fi
command -v unzip >/dev/null || { echo "fetch-templates: unzip is needed (apt-get install unzip)" >&2; exit 1; }
for f in "${FILES[@]}"; do
  if [ ! -s "$DIR/$f" ]; then
    # Extract to a temporary name first, so an interrupted run never leaves a truncated file.
    unzip -p "$WHEEL" "nilearn/datasets/data/$f" > "$DIR/$f.part"
    mv "$DIR/$f.part" "$DIR/$f"
  fi
  echo "$DIR/$f"
done
