"""Dice of two brain masks (NIfTI, same grid) and their volumes: the ACCURACY.md table's
numbers (issue 27). Usage: python3 brain_dice.py MASK REFERENCE [LABEL] [BRAIN_LABELS]
BRAIN_LABELS (e.g. 2,3,4,5,6,7: the head phantom's CSF, GM, WM, lesion, vessels and edema from
`morphray phantom --head --labels`) reads REFERENCE as a label map whose brain is those labels.
Needs numpy and nibabel (the tests' venv, tools/pyenv.sh, has both)."""
import sys

import nibabel as nib
import numpy as np


def main():
    mask_path, ref_path = sys.argv[1], sys.argv[2]
    label = sys.argv[3] if len(sys.argv) > 3 else mask_path
    mask_img, ref_img = nib.load(mask_path), nib.load(ref_path)
    mask = np.asanyarray(mask_img.dataobj) > 0
    ref = np.asanyarray(ref_img.dataobj)
    if len(sys.argv) > 4:
        ref = np.isin(ref, [int(v) for v in sys.argv[4].split(",")])
    else:
        ref = ref > 0
    if mask.shape != ref.shape:
        sys.exit(f"{label}: grids differ: {mask.shape} vs {ref.shape}")
    voxel_ml = float(np.prod(mask_img.header.get_zooms()[:3])) / 1000.0
    both = np.logical_and(mask, ref).sum()
    dice = 2.0 * both / (mask.sum() + ref.sum())
    print(f"{label}\tDice {dice:.4f}\tmask {mask.sum() * voxel_ml:.0f} cm3"
          f"\treference {ref.sum() * voxel_ml:.0f} cm3")


if __name__ == "__main__":
    main()
