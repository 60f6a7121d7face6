#!/usr/bin/env python3
"""Histograms of the perturbation study's volumes over the foreground and over its interior.

The interior keeps only voxels whose six face neighbours are all foreground, so the partial
volume that skull-stripping leaves at the brain's edge (brain averaged with exact zeros, worst on
thick slices) drops out. Prints, per volume and mask, the first occupied value, the bin width
and the first 36 of 64 bins from the minimum to the foreground's 99.5th percentile.

Usage (volumes from `perturbation_study ... --write-volumes`):
    python3 tools/perturbation/interior_histogram.py target/perturbation/*.nii.gz
Needs numpy, scipy, nibabel.
"""
import sys

import nibabel as nib
import numpy as np
from scipy import ndimage as ndi


def main(paths):
    for path in paths:
        data = np.asarray(nib.load(path).dataobj, dtype=np.float64)
        lo = np.nanmin(data)
        shifted = data - lo
        foreground = shifted > np.nanpercentile(shifted, 99.5) * 0.08
        top = np.percentile(shifted[foreground], 99.5)
        for name, mask in [("foreground", foreground),
                           ("interior", ndi.binary_erosion(foreground))]:
            counts, edges = np.histogram(shifted[mask], bins=64, range=(0, top))
            first = int(np.argmax(counts > 0))
            print(f"{path} {name}: first occupied value {edges[first] + lo:.1f}; "
                  f"bin width {edges[1] - edges[0]:.2f}; bins "
                  + " ".join(str(c) for c in counts[:36]))


if __name__ == "__main__":
    main(sys.argv[1:])
