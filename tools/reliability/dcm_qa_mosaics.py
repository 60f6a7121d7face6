#!/usr/bin/env python3
"""Siemens mosaics of the public dcm_qa repository against its dcm2niix references (issue 30).

dcm_qa (github.com/neurolabusc/dcm_qa) holds Siemens B17 mosaic fMRI series in every slice
orientation and order (In/Orientation) with the NIfTI dcm2niix made of each (Ref). Its data are
not part of this repository: fetch it anywhere and point this script at it.

For every series folder: `morphray convert` writes the NIfTI morphray reads; its first volume
is compared with the reference's first volume through world space (each of morphray's voxels
is mapped by the two affines into the reference's grid: it must land on a voxel centre within
0.05 voxel and hold the same value). Prints one line per series and exits 1 on any mismatch.

    python3 tools/reliability/dcm_qa_mosaics.py DCM_QA_DIR [--morphray target/debug/morphray]

Needs numpy and nibabel (the tests' venv, tools/pyenv.sh, has both).
"""
import argparse
import json
import pathlib
import subprocess
import sys
import tempfile

import nibabel as nib
import numpy as np


def series_folders(root):
    """Folders under In/Orientation that hold DICOM files (not the JPEG-2000 ones)."""
    base = root / "In" / "Orientation"
    for folder in sorted(p for p in base.glob("*/*") if p.is_dir()):
        yield folder


def reference(root, info):
    """The reference NIfTI of a series: Ref/<description>_<number>.nii."""
    s = info["series"][info["chosen"]] if info.get("chosen") is not None else info["series"][0]
    path = root / "Ref" / f"{s['description']}_{s['number']}.nii"
    return path if path.is_file() else None


def compare(ours_path, ref_path):
    ours = nib.load(str(ours_path))
    ref = nib.load(str(ref_path))
    a = np.asarray(ours.dataobj, dtype=np.float64)
    b = np.asarray(ref.dataobj, dtype=np.float64)
    if b.ndim == 4:
        b = b[..., 0]
    if a.ndim == 4:
        a = a[..., 0]
    to_ref = np.linalg.inv(ref.affine) @ ours.affine
    ijk = np.indices(a.shape).reshape(3, -1)
    homog = np.vstack([ijk, np.ones(ijk.shape[1])])
    mapped = (to_ref @ homog)[:3]
    rounded = np.rint(mapped)
    off = np.abs(mapped - rounded).max()
    inside = np.all((rounded >= 0) & (rounded < np.array(b.shape)[:, None]), axis=0)
    r = rounded.astype(int)
    same = np.array_equal(a.reshape(-1)[inside], b[r[0, inside], r[1, inside], r[2, inside]])
    return {
        "shape": list(a.shape),
        "ref_shape": list(b.shape),
        "max_offset_voxels": float(off),
        "all_inside": bool(inside.all()),
        "values_equal": bool(same),
    }


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("dcm_qa", type=pathlib.Path)
    p.add_argument("--morphray", default="target/debug/morphray")
    args = p.parse_args()
    failures = 0
    with tempfile.TemporaryDirectory() as tmp:
        for folder in series_folders(args.dcm_qa):
            info_run = subprocess.run([args.morphray, "info", "--json", str(folder)],
                                      capture_output=True, text=True)
            if "JPEG 2000" in info_run.stderr:
                # Refused by design (no JPEG 2000 decoder), with a line naming dcm2niix.
                print(f"refused as promised {folder.name}: {info_run.stderr.strip()}")
                continue
            try:
                info = json.loads(info_run.stdout)
            except json.JSONDecodeError:
                print(f"FAIL {folder.name}: info printed no JSON: {info_run.stderr.strip()}")
                failures += 1
                continue
            ref = reference(args.dcm_qa, info)
            if ref is None:
                print(f"skip {folder.name}: no reference NIfTI")
                continue
            out = pathlib.Path(tmp) / f"{folder.name}.nii"
            conv = subprocess.run([args.morphray, "convert", str(folder), "-o", str(out)],
                                  capture_output=True, text=True)
            if conv.returncode != 0:
                print(f"FAIL {folder.name}: convert: {conv.stderr.strip()}")
                failures += 1
                continue
            r = compare(out, ref)
            ok = (r["shape"] == r["ref_shape"][:3] and r["max_offset_voxels"] < 0.05
                  and r["all_inside"] and r["values_equal"])
            failures += not ok
            print(f"{'ok  ' if ok else 'FAIL'} {folder.name}: {ref.name} {r}")
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
