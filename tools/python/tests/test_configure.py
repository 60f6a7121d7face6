"""configure(): the memory budget and the device are arguments; changing them replaces the
process's one engine, and volumes of the old engine say so instead of rendering wrongly."""

import pytest

import morphray


def test_a_memory_budget_bricks_and_configure_replaces_the_engine():
    before = morphray.phantom((24, 24, 24))
    name = morphray.device_name()
    assert isinstance(name, str) and name
    try:
        morphray.configure(memory_budget=1 << 20)
        with pytest.raises(morphray.MemoryBudgetError, match="memory budget"):
            morphray.phantom((64, 64, 64))
        # 128^3 fits whole in 24 MiB (with the 1024x1024 target it is planned for), not in 16.
        morphray.configure(memory_budget=16 << 20)
        small = morphray.phantom((128, 128, 128))
        assert small.layout == "bricked"
        image = small.render(size=(32, 32), jitter=False)
        assert (image[..., :3] > 0).any()
        # Other tissues change which bricks are resident: the volume is opened again for them.
        wm = small.render(size=(32, 32), tissues=["wm"], jitter=False)
        assert (wm[..., :3] > 0).any() and not (wm == image).all()
        with pytest.raises(morphray.MemoryBudgetError, match="bricked"):
            small.derive("gradient")
        # The session's volume lives on the engine that was replaced.
        with pytest.raises(morphray.Error, match="open it again"):
            before.render(size=(8, 8))
    finally:
        morphray.configure()
    with pytest.raises(ValueError, match="memory_budget"):
        morphray.configure(memory_budget=0)


def test_the_device_is_an_argument_and_a_wrong_one_is_a_device_error():
    try:
        morphray.configure(device="no such gpu")
        with pytest.raises(morphray.DeviceError, match="no such gpu"):
            morphray.phantom((24, 24, 24))
        # By index, as `morphray devices` numbers them.
        morphray.configure(device="0")
        assert morphray.phantom((24, 24, 24)).shape == (24, 24, 24)
    finally:
        morphray.configure()
