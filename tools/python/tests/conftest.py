"""Shared fixtures: small volumes (the CI renders on lavapipe, a CPU Vulkan driver)."""

import numpy as np
import pytest

import morphray

# 48^3 is the smallest phantom whose three tissue modes the analysis separates.
PHANTOM_SHAPE = (48, 48, 48)


@pytest.fixture(scope="module")
def phantom():
    return morphray.phantom(PHANTOM_SHAPE)


def head_array(shape=PHANTOM_SHAPE):
    """A T1-like head (scalp, CSF, GM, WM) as int16, indexed (i, j, k), with 2 mm voxels."""
    i, j, k = np.meshgrid(*[np.linspace(-1, 1, n) for n in shape], indexing="ij")
    r = np.sqrt(i**2 + j**2 + k**2)
    rng = np.random.default_rng(7)
    data = np.select([r > 0.95, r > 0.85, r > 0.7, r > 0.25, r >= 0],
                     [0, 1000, 600, 850, 250]).astype(np.float64)
    data += rng.normal(0, 30, shape) * (r <= 0.95)
    data = np.clip(data, 0, 4095).astype(np.int16)
    affine = np.diag([2.0, 2.0, 2.0, 1.0])
    affine[:3, 3] = [-(n - 1) for n in shape]
    return data, affine
