"""A synthetic two-sided z-map in MNI space for layer figures and manual checks (issue 31 item 4).

Writes a 2 mm grid (91 x 109 x 91, the FSL MNI152 2 mm grid, an affine of its own) holding
smoothed Gaussian noise (|z| mostly below 2) plus positive blobs over the left motor cortex and
both visual cortices and a negative one over the posterior cingulate, as a task fMRI z-map looks.
Not a real result: a picture of the layer machinery on a known pattern.

The noise is kept inside the brain (where the MNI152 T1 given is above a fifth of its maximum,
resampled onto the 2 mm grid), as an analysis masks it.

usage: python synthetic_zmap.py MNI152_T1.nii.gz OUT.nii.gz  (numpy, scipy, nibabel)
"""
import sys

import nibabel as nib
import numpy as np
from scipy.ndimage import gaussian_filter, map_coordinates


def main(template, out):
    shape = (91, 109, 91)
    affine = np.array([[-2.0, 0, 0, 90], [0, 2, 0, -126], [0, 0, 2, -72], [0, 0, 0, 1]])
    rng = np.random.default_rng(31)
    noise = gaussian_filter(rng.standard_normal(shape), 1.5)
    noise *= 1.0 / noise.std()
    ijk = np.indices(shape).reshape(3, -1).T
    xyz = (ijk @ affine[:3, :3].T + affine[:3, 3]).reshape(shape + (3,))
    t1 = nib.load(template)
    to_t1 = np.linalg.inv(t1.affine)
    t1_ijk = xyz.reshape(-1, 3) @ to_t1[:3, :3].T + to_t1[:3, 3]
    data = np.asarray(t1.dataobj, dtype=np.float32)
    inside = map_coordinates(data, t1_ijk.T, order=1).reshape(shape) > 0.2 * data.max()
    z = noise * inside
    # (centre mm, peak z, radius mm): left M1, visual cortex left and right, posterior cingulate.
    for centre, peak, radius in [((-38, -22, 56), 7.5, 9), ((-14, -92, 4), 6.0, 8),
                                 ((16, -90, 6), 5.5, 8), ((2, -52, 30), -5.5, 10)]:
        d2 = ((xyz - np.array(centre)) ** 2).sum(-1)
        z = z + peak * np.exp(-d2 / (2 * radius ** 2))
    img = nib.Nifti1Image(z.astype(np.float32), affine)
    img.header.set_qform(affine, 1)
    img.header.set_sform(affine, 4)
    nib.save(img, out)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
