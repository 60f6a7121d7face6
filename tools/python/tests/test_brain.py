"""Brain extraction from Python (issue 27): render(brain="auto"|"on"|"off"), the head layer
through the command line's names (tissues=[..., "head"], opacity={"head": ...}, color={"head": ...}),
derive("brain") as a uint8 mask on the input grid, and brain_report()."""

import numpy as np
import pytest

import morphray

# The smallest head phantom found here whose brain extraction takes for a head: coarser grids
# lose the thin scalp layers to their one-voxel floors (809 cm^3 of brain on lavapipe).
HEAD_SHAPE = (96, 108, 90)
HEAD_SPACING = 2.0


@pytest.fixture(scope="module")
def head():
    return morphray.phantom(HEAD_SHAPE, head=True, spacing=HEAD_SPACING)


def lit(image):
    """Pixels off the black background."""
    return int((image[..., :3] > 24).any(axis=2).sum())


def stripped_brain(spacing=2.0, seed=5):
    """A brain alone on a dark background (skull-stripped): a bright ellipsoid (about
    850 cm^3) with a darker rim and a dark ventricle, noise; int16, indexed (i, j, k)."""
    n = int(np.ceil(160.0 / spacing)) | 1
    axis = (np.arange(n) - (n - 1) / 2.0) * spacing
    x, y, z = np.meshgrid(axis, axis, axis, indexing="ij")
    r = np.sqrt(x**2 / 0.9 + y**2 + z**2 / 0.8)
    ventricle = (x / 8.0) ** 2 + (y / 20.0) ** 2 + (z / 8.0) ** 2 < 1.0
    signal = np.select([ventricle, r <= 54.0, r <= 60.0], [300.0, 850.0, 600.0], 0.0)
    rng = np.random.default_rng(seed)
    noise = (rng.random(r.shape) + rng.random(r.shape) + rng.random(r.shape) - 1.5) * 40.0
    data = np.clip(signal + noise, 0, 4095).astype(np.int16)
    affine = np.diag([spacing, spacing, spacing, 1.0])
    affine[:3, 3] = -axis[-1]
    return data, affine


def test_a_head_is_decided_a_head_and_masked_by_default(head):
    report = head.brain_report()
    assert report["decision"] == "head"
    assert report["masks_with_auto"] is True
    assert report["describe"].startswith("head: the brain is extracted")
    assert 500 <= report["brain_cm3"] <= 3000
    assert 0.25 <= report["outside_fraction"] <= 1.0


def test_the_brain_switch_and_the_head_layer_change_the_picture(head):
    size = (96, 96)
    auto = head.render(size=size, jitter=False)
    # A head: On masks it as Auto does.
    np.testing.assert_array_equal(head.render(size=size, jitter=False, brain="on"), auto)
    # Off classifies the scalp and the face too; the head layer draws them around the brain.
    off = head.render(size=size, jitter=False, brain="off")
    with_head = head.render(size=size, jitter=False, tissues=["csf", "gm", "wm", "head"])
    assert lit(auto) > 500, lit(auto)
    assert lit(off) > 1.3 * lit(auto), (lit(off), lit(auto))
    assert lit(with_head) > 1.3 * lit(auto), (lit(with_head), lit(auto))
    # Back to Auto after Off (the mask is computed again): the same picture as before.
    np.testing.assert_array_equal(head.render(size=size, jitter=False), auto)
    # The head layer alone, styled by hand: opaque red.
    red = head.render(size=size, jitter=False, tissues=["head"], color={"head": "#ff0000"},
                      opacity={"head": 1.0}).astype(int)
    shown = (red[..., :3] > 24).any(axis=2)
    assert shown.sum() > lit(auto)
    assert (red[..., 0][shown] > 2 * red[..., 1][shown] + 10).mean() > 0.9


def test_bad_brain_and_head_arguments_are_value_errors(head):
    with pytest.raises(ValueError, match="brain"):
        head.render(size=(8, 8), brain="maybe")
    with pytest.raises(ValueError, match="opacity"):
        head.render(size=(8, 8), opacity={"head": 2.0})
    with pytest.raises(ValueError, match="color"):
        head.render(size=(8, 8), color={"head": (float("nan"), 0, 0)})
    with pytest.raises(ValueError, match="head"):
        head.render(size=(8, 8), tissues=["scalp"])
    with pytest.raises(ValueError, match="brain"):
        head.derive("skull")


def test_derive_brain_is_a_uint8_mask_on_the_input_grid(head):
    report = head.brain_report()
    mask = head.derive("brain")["brain"]
    assert mask.shape == HEAD_SHAPE and mask.dtype == np.uint8
    assert set(np.unique(mask).tolist()) == {0, 1}
    # Its volume is the report's (the report counts coarse cells of the working grid: the two
    # agree to a few per cent on the phantom).
    cm3 = mask.sum() * HEAD_SPACING**3 / 1000.0
    assert cm3 == pytest.approx(report["brain_cm3"], rel=0.25)
    # One blob away from the volume's faces (the neck leaves through the bottom, the cord is
    # cut at the foramen): nothing on the top, front, back or side faces.
    for face in (mask[0], mask[-1], mask[:, 0], mask[:, -1], mask[:, :, -1]):
        assert face.sum() == 0
    # The mask's centre is inside it.
    centre = tuple(int(round(c)) for c in np.argwhere(mask).mean(axis=0))
    assert mask[centre] == 1
    # With other maps in one call.
    both = head.derive(["gradient", "brain"])
    assert set(both) == {"gradient", "brain"}
    np.testing.assert_array_equal(both["brain"], mask)


def test_a_skull_stripped_brain_is_left_alone_by_auto_and_masked_by_on():
    vol = morphray.open(stripped_brain())
    report = vol.brain_report()
    assert report["decision"] == "skull_stripped", report
    assert report["masks_with_auto"] is False
    size = (64, 64)
    auto = vol.render(size=size, jitter=False)
    np.testing.assert_array_equal(auto, vol.render(size=size, jitter=False, brain="off"))
    # On masks it: the picture changes, and derive still exports the mask (as brain="on").
    assert not np.array_equal(auto, vol.render(size=size, jitter=False, brain="on"))
    mask = vol.derive("brain")["brain"]
    assert 0 < mask.mean() < 0.6
