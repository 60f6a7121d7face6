"""Issue 30's cases: hostile and unusual input that used to end in exit 0 with something wrong
(a raw dataset overwritten by `batch`, a resume that trusted a damaged output, a failed batch
exiting 0, ...). Each class is one item of the issue; every case says what it must say.

Decisions:
- The batch cases work on tiny BIDS datasets (16^3 blobs) written by the probe, with
  `--no-thumbnails` (peaks only) so each run is a device start and a few milliseconds of work.
- Resume cases depend on the case before them (a finished run whose output the setup then
  damages); when that case did not run (`--only`, `--quick`), the setup raises `NotRun`.
"""

import glob
import json
import os

import nifti as nf
from case import Case, NotRun

DIMS = (16, 16, 16)
BROKEN_GZIP = bytes([0x1F, 0x8B, 8, 0, 0, 0, 0, 0, 0, 3, 1, 2, 3])


def _dataset(ws, name, subjects=2, broken=False, description=None):
    """A BIDS dataset under the workspace; returns (root, scan paths)."""
    root = ws.path(name)
    text = description or {"Name": "probe cohort", "BIDSVersion": "1.10.0"}
    ws.write(f"{name}/dataset_description.json", json.dumps(text).encode())
    scans = []
    for s in range(1, subjects + 1):
        rel = f"{name}/sub-{s:02}/anat/sub-{s:02}_T1w.nii.gz"
        body = BROKEN_GZIP if broken and s == subjects else nf.gz(nf.nifti1(DIMS))
        scans.append(ws.write(rel, body))
    return root, scans


def batch(ws):
    cls = "batch"
    bids, _ = _dataset(ws, "batch/bids")
    own_description = os.path.join(bids, "dataset_description.json")
    other, _ = _dataset(ws, "batch/other-dataset", subjects=1)
    raw_description = os.path.join(other, "dataset_description.json")
    theirs = ws.path("batch/fmriprep")
    theirs_description = ws.write("batch/fmriprep/dataset_description.json", json.dumps(
        {"DatasetType": "derivative", "GeneratedBy": [{"Name": "fMRIPrep"}]}).encode())
    broken, _ = _dataset(ws, "batch/broken", broken=True)
    resume, resume_scans = _dataset(ws, "batch/resume")
    resume_out = ws.path("batch/resume-out")

    def run(source, out, *extra):
        return ws.gpu("batch", source, out, "participant", "--no-thumbnails", *extra)

    def summary(out, subject):
        path = os.path.join(out, f"sub-{subject}/anat/sub-{subject}_desc-peaks_T1w.json")
        if not os.path.isfile(path):
            raise NotRun("the resume case before this one did not run")
        return path

    def truncate_summary():
        path = summary(resume_out, "01")
        with open(path, "rb") as f:
            text = f.read()
        with open(path, "wb") as f:
            f.write(text[: len(text) // 2])

    def replace_input():
        summary(resume_out, "02")
        with open(resume_scans[1], "wb") as f:
            f.write(nf.gz(nf.nifti1(DIMS, data=nf.pack_voxels(nf.blob(DIMS, seed=99), "int16"))))

    def c(name, argv, **kw):
        return Case(cls, name, argv, gpu=True, **kw)

    return [
        c("onto its own input", run(bids, bids), expect="error", protect=[own_description],
          says="is the input dataset itself", quick=True),
        c("onto its own input via sub-01/..", run(bids, os.path.join(bids, "sub-01", "..")),
          expect="error", protect=[own_description], says="is the input dataset itself"),
        c("into another raw dataset", run(bids, other), expect="error", protect=[raw_description],
          says="raw"),
        c("into another pipeline's derivatives", run(bids, theirs), expect="error",
          protect=[theirs_description], says="fMRIPrep"),
        c("a failed scan exits 3", run(broken, ws.fresh("batch-broken")), expect="nonzero",
          code=3, says="1 of 2 scans failed"),
        c("a failed scan, --allow-failures", run(broken, ws.fresh("batch-allowed"),
                                                  "--allow-failures"), expect="ok"),
        c("resume: first run (control)", run(resume, resume_out), expect="ok",
          says="2 done, 0 skipped"),
        c("resume: truncated summary is redone", run(resume, resume_out), expect="ok",
          setup=truncate_summary, says="1 done, 1 skipped"),
        c("resume: replaced input is redone", run(resume, resume_out), expect="ok",
          setup=replace_input, says="1 done, 1 skipped"),
    ]


# A PID above any kernel's pid_max (at most 2^22): never a running process.
DEAD_PID = 4194400


def interrupted_writes(ws):
    cls = "interrupted writes"
    folder = ws.path("stale")
    stale = os.path.join(folder, f".old.nii.{DEAD_PID}.3.tmp")
    kept = os.path.join(folder, ".notes.tmp")

    def leave_stale():
        os.makedirs(folder, exist_ok=True)
        for path in (stale, kept):
            with open(path, "wb") as f:
                f.write(b"half of a volume" * 1000)

    out = os.path.join(folder, "phantom.nii")
    return [
        Case(cls, "a killed writer's temporary file, next write", ["phantom", "--dims",
             "16x16x12", "-o", out], expect="ok", setup=leave_stale, gone=[stale],
             protect=[kept], quick=True),
    ]


def cache_folders(ws):
    """XDG_CACHE_HOME that cannot take files: Mesa's shader cache and the pipeline cache must be
    turned off with one line each (a full file system killed every GPU command with SIGBUS
    through Mesa's cache; it needs a mount, so it is checked by hand: RELIABILITY.md)."""
    cls = "cache folders"
    file = ws.write("cache-home-file", b"not a folder")
    out = []
    for name, home, why in [("a file", file, "is a file, not a folder"),
                            ("/proc/self/none", "/proc/self/none", "no file can be created")]:
        argv, png = ws.render(None)
        # Without the probe's --pipeline-cache: the default folder under XDG_CACHE_HOME.
        argv = [a for a in argv if a not in ("--pipeline-cache", ws.cache)]
        out.append(Case(cls, f"XDG_CACHE_HOME is {name}", argv, expect="ok", gpu=True, png=png,
                        lit=True, env={"XDG_CACHE_HOME": home}, quick=name == "a file",
                        says=f"shader cache is off.*{why}.*\\n.*pipeline cache is kept in memory",
                        never_says=r"os error 17|cannot write the pipeline cache"))
    return out


BUILDERS = (batch, interrupted_writes, cache_folders)
