"""Python parity with the command line (issue 32 item 3): render() and open() take the CLI's
scene options by the same names and units (one option model: the library's clap definition);
the volume's affine, spacing, header and data; NIfTI export of any map; every derive() map;
open()'s identity options; a warning for an empty picture."""

import warnings

import numpy as np
import pytest

import morphray
from conftest import head_array

# One Python value per scene option of the command line. A new CLI option makes
# test_every_cli_scene_option_works fail until it has an example here (and so a test).
EXAMPLES = {
    "size": (24, 16),
    "azimuth": -30,
    "elevation": 20.5,
    "zoom": 1.5,
    "pan": (2, -1),
    "projection": "orthographic",
    "mode": "mip",
    "tissues": ["gm", "wm"],
    "preset": "mr",
    "brain": "off",
    "windows": "paper",
    "step": 0.75,
    "curvature": True,
    "shading": False,
    "lighting": "headlight",
    "matcap": "shiny",
    "depth_cues": False,
    "cue_strength": "0.5,0.3,0.2",
    "cutaway": "centre",
    "gradient": "on-the-fly",
    "derived_precision": "f16",
    "classification": "exact",
    "background": (10, 20, 30),
    "no_jitter": True,
    "window": {"wm": (0.7, 0.9)},
    "opacity": {"csf": 0.1},
    "color": {"wm": "#f0f0e0"},
    "crop": ((0, 1), (0, 1), (0.5, 1)),
    "clip_plane": [(1, 0, 0, 0)],
    "colormap": "hot",
    "view": "left",
    "denoise": "gaussian:1",
}


def test_every_cli_scene_option_works(phantom):
    names = {name for name, *_ in morphray.scene_options()}
    assert names == set(EXAMPLES), (
        f"options the CLI has and this test lacks: {sorted(names - set(EXAMPLES))}; "
        f"examples of options the CLI no longer has: {sorted(set(EXAMPLES) - names)}")
    for name, value in EXAMPLES.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            options = {"size": (24, 16)} if name != "size" else {}
            image = phantom.render(**options, **{name: value})
        assert image.shape == (16, 24, 4), name


def test_python_values_mean_what_the_command_line_words_mean(phantom):
    def same(a, b):
        np.testing.assert_array_equal(phantom.render(size=32, no_jitter=True, **a),
                                      phantom.render(size=32, no_jitter=True, **b))
    same({"window": {"wm": (0.6, 0.95)}}, {"window": "wm=0.6:0.95"})
    same({"background": (255, 255, 255)}, {"background": "#ffffff"})
    same({"color": {"gm": (255, 0, 0)}}, {"color": ["gm=#ff0000"]})
    same({"clip_plane": (1, 0, 0, 0)}, {"clip_plane": ["1,0,0,0"]})
    same({"curvature": True}, {"curvature": "on"})
    np.testing.assert_array_equal(phantom.render(size=32, jitter=False),
                                  phantom.render(size=32, no_jitter=True))
    same({"view": "left"}, {"azimuth": -90})
    assert not np.array_equal(phantom.render(size=32, no_jitter=True),
                              phantom.render(size=32, no_jitter=True, shading=False)), \
        "a still is shaded by default, as `morphray render`'s"


def test_bad_names_and_values_say_which(phantom):
    with pytest.raises(TypeError, match="colour_map"):
        phantom.render(size=8, colour_map="hot")
    with pytest.raises(ValueError, match="--mode"):
        phantom.render(size=8, mode="sideways")
    with pytest.raises(ValueError, match="--view"):
        phantom.render(size=8, view="left", azimuth=10)
    with pytest.raises(ValueError, match="preset"):
        phantom.render(size=8, preset="xray")
    with pytest.raises(ValueError, match="normalize"):
        morphray.phantom((24, 24, 24), normalize="sideways")


def test_an_empty_picture_warns_with_the_reason(phantom):
    with pytest.warns(UserWarning, match="only the background.*opacity"):
        phantom.render(size=16, opacity={"csf": 0, "gm": 0, "wm": 0})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        phantom.render(size=16)


def test_geometry_header_and_data_come_back_as_given():
    data, affine = head_array((20, 24, 16))
    affine[0, 1] = 0.5  # sheared: nothing assumes a diagonal affine
    vol = morphray.open((data, affine))
    np.testing.assert_array_equal(vol.affine, affine)
    np.testing.assert_array_equal(np.asarray(vol), data)
    assert np.asarray(vol).dtype == np.int16
    assert vol.shape == (20, 24, 16)
    header = vol.header
    assert header["dim"] == [20, 24, 16]
    assert header["datatype"] == "int16"
    np.testing.assert_allclose(vol.spacing, [2.0, np.hypot(2.0, 0.5), 2.0])


def test_maps_are_written_with_the_volume_affine(tmp_path):
    nib = pytest.importorskip("nibabel")
    data, affine = head_array((24, 24, 24))
    vol = morphray.open((data, affine))
    maps = vol.derive(["normalized", "gradient", "brain"], denoise="gaussian:1")
    assert set(maps) == {"normalized", "gradient", "brain", "denoised"}
    assert maps["normalized"].dtype == np.float32 and maps["brain"].dtype == np.uint8
    assert 0 <= maps["normalized"].min() and maps["normalized"].max() <= 1
    assert not np.array_equal(maps["normalized"], maps["denoised"])
    out = tmp_path / "gradient.nii.gz"
    vol.to_nifti(out, data=maps["gradient"])
    back = nib.load(out)
    np.testing.assert_allclose(back.affine, affine, atol=1e-6)
    np.testing.assert_array_equal(back.get_fdata(dtype=np.float32), maps["gradient"])
    with pytest.raises(ValueError, match="exists|force"):
        vol.to_nifti(out, data=maps["gradient"])
    vol.to_nifti(out, force=True)
    np.testing.assert_array_equal(np.asanyarray(nib.load(out).dataobj), data)
    with pytest.raises(ValueError, match="grid"):
        vol.to_nifti(tmp_path / "x.nii", data=np.zeros((3, 3, 3), np.float32))
    assert vol.to_nibabel(maps["brain"]).shape == (24, 24, 24)


def test_open_takes_the_identity_options():
    data, affine = head_array((32, 32, 32))
    assert morphray.open((data, affine))._native is not None
    t2 = morphray.open((data, affine), contrast="t2")
    assert t2.peaks()["contrast"]["contrast"] == "t2"
    robust = morphray.open((data, affine)).peaks()["table1"]
    minmax = morphray.open((data, affine), normalize="minmax").peaks()["table1"]
    assert robust != minmax


def test_the_type_hints_name_every_scene_option():
    from pathlib import Path
    stub = (Path(morphray.__file__).parent / "__init__.pyi").read_text()
    render = stub[stub.index("def render("):stub.index("def derive(")]
    missing = [name for name, *_ in morphray.scene_options() if f"        {name}:" not in render]
    assert not missing, f"__init__.pyi's render() lacks {missing}"


def _grey_png(path, side, left, right):
    """A side x side 8-bit grey PNG, `left` in its left half and `right` in its right half."""
    import struct
    import zlib

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    row = bytes([0] + [left] * (side // 2) + [right] * (side - side // 2))
    header = struct.pack(">IIBBBBB", side, side, 8, 0, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
                     + chunk(b"IDAT", zlib.compress(row * side)) + chunk(b"IEND", b""))
    return path


def test_a_matcap_file_by_path_or_str_lights_the_picture(phantom, tmp_path):
    png = _grey_png(tmp_path / "left-lit.png", 32, 240, 60)
    by_path = phantom.render(size=32, no_jitter=True, matcap=png)
    np.testing.assert_array_equal(by_path, phantom.render(size=32, no_jitter=True, matcap=str(png)))
    assert not np.array_equal(by_path, phantom.render(size=32, no_jitter=True, lighting="matcap")), \
        "the file's matcap is not the built-in clay"
    with pytest.raises(ValueError, match="2 to 4096 pixels"):
        phantom.render(size=8, matcap=_grey_png(tmp_path / "dot.png", 1, 0, 0))
