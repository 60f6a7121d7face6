"""Bad runs: outputs, the pipeline cache, bricked MIP/MinIP, arguments and the viewer.

Decisions:
- Every output case protects what must survive: the input volume (always), an existing NIfTI
  (always: `phantom -o` must not replace a scan silently), an existing PNG (unless the run
  succeeded), and the device nodes /dev/full and /dev/zero (a writer that renames over a
  target must never replace one).
- A full disk is simulated with RLIMIT_FSIZE (writes past the limit fail with EFBIG), which
  needs no mount and no root.
- The pipeline-cache cases first let the binary write its cache in a fresh directory, then
  replace that file (whatever its name, `pipelines-*.bin`) by a FIFO, a link to /dev/zero,
  garbage, half of itself, a directory; the render must go on (the cache is only a speed-up).
- Bricked against whole: the same render twice, the second with `--bricked`; the lit-pixel
  counts must agree within 2 % (bricking is documented as lossless).
- Phantoms written by the probe are 16x16x12 so writing them costs nothing.
"""

import glob
import os

import nifti as nf
from case import Case, NotRun, render_case

DIMS = (16, 16, 16)
PHANTOM_DIMS = "16x16x12"
FULL_DISK = 2048
NO_PEAK = r"no \w+ peak"


def _volume(ws, name, gz=True):
    data = nf.nifti1(DIMS)
    return ws.write(name, nf.gz(data) if gz else data)


def outputs(ws):
    cls = "outputs"
    # Each case reads its own copy of the scan: a case that destroys its input must not turn
    # the next case's input into a PNG.
    scans = iter(_volume(ws, f"out{i}/scan.nii.gz") for i in range(100))
    scan_nii = _volume(ws, "out-sub/scan.nii", gz=False)
    os.makedirs(ws.path("out-sub/sub"), exist_ok=True)
    linked = next(scans)
    alias = ws.path("out-link/hardlink.png")
    os.makedirs(os.path.dirname(alias))
    os.link(linked, alias)
    own = next(scans)
    existing_gz = _volume(ws, "out-existing/existing.nii.gz")
    existing_nii = _volume(ws, "out-existing/existing.nii", gz=False)
    old_png = ws.write("out-old/old.png", b"\x89PNG\r\n\x1a\n" + b"an earlier picture" * 500)
    old_png2 = ws.write("out-old/old2.png", b"\x89PNG\r\n\x1a\n" + b"an earlier picture" * 500)
    bad = ws.write("out-old/bad.nii", nf.nifti1(DIMS)[:200])
    full_link = ws.path("out-old/full.png")
    os.symlink("/dev/full", full_link)
    jpg = ws.path("out-jpg/out.jpg")
    os.makedirs(os.path.dirname(jpg))
    new_nii = ws.path("out-full/new.nii")
    os.makedirs(os.path.dirname(new_nii))
    phantom = ["phantom", "--dims", PHANTOM_DIMS, "-o"]
    cases = [
        Case(cls, "render onto its own input", ws.render(own, out=own)[0], expect="error",
             gpu=True, protect=[own], quick=True),
        Case(cls, "render onto its input via sub/..", ws.render(scan_nii, out=ws.path(
            "out-sub/sub/../scan.nii"))[0], expect="error", gpu=True, protect=[scan_nii]),
        Case(cls, "render to a hard link of its input", ws.render(linked, out=alias)[0],
             expect="any", gpu=True, protect=[linked]),
        Case(cls, "phantom -o existing.nii.gz", phantom + [existing_gz], expect="error",
             protect=[existing_gz], quick=True),
        Case(cls, "phantom -o existing.nii", phantom + [existing_nii], expect="error",
             protect=[existing_nii]),
        Case(cls, "render -o out.jpg", ws.render(next(scans), out=jpg)[0], expect="error",
             gpu=True, absent_on_failure=[jpg], quick=True),
        Case(cls, "phantom -o out.png", phantom + [ws.path("out-jpg/phantom.png")],
             expect="error"),
        Case(cls, "render into a missing directory", ws.render(next(scans), out=ws.path(
            "out-missing/missing/out.png"))[0], expect="error", gpu=True),
        Case(cls, "render -o a directory", ws.render(next(scans), out=ws.path("out-sub/sub"))[0],
             expect="error", gpu=True),
        Case(cls, "render -o /dev/full", ws.render(next(scans), out="/dev/full")[0],
             expect="error", gpu=True, devices=["/dev/full"]),
        Case(cls, "render -o link to /dev/full", ws.render(next(scans), out=full_link)[0],
             expect="error", gpu=True, devices=["/dev/full"]),
        Case(cls, "failed render over an existing PNG", ws.render(bad, out=old_png)[0],
             expect="error", gpu=True, protect_on_failure=[old_png]),
        Case(cls, "disk full over an existing PNG", ws.render(next(scans), out=old_png2)[0],
             expect="error", gpu=True, protect_on_failure=[old_png2], fsize=FULL_DISK,
             quick=True),
        Case(cls, "phantom on a full disk", phantom + [new_nii], expect="error",
             absent_on_failure=[new_nii], fsize=FULL_DISK),
        Case(cls, "turntable into a missing directory", ws.render(next(scans), "--turntable", "2",
             out=ws.path("out-missing/missing2/t.png"))[0], expect="error", gpu=True),
        render_case(ws, cls, "render -o OUT.PNG (upper case)", next(scans), lit=True),
    ]
    upper = cases[-1]
    upper.png = upper.png[:-4] + ".PNG"
    upper.argv[upper.argv.index("-o") + 1] = upper.png
    return cases


def _cache_file(directory):
    found = glob.glob(os.path.join(directory, "pipelines-*.bin"))
    if not found:
        raise NotRun(f"the control run wrote no pipelines-*.bin into {directory}")
    return os.path.basename(found[0])


def pipeline_cache(ws):
    cls = "pipeline cache"
    scan = _volume(ws, "cache-scan.nii.gz")
    control = ws.path("cache/control")
    os.makedirs(control)

    def variant(name, damage, quick=False, devices=()):
        directory = ws.path(f"cache/{name}")

        def setup():
            os.makedirs(directory, exist_ok=True)
            damage(os.path.join(directory, _cache_file(control)))

        argv, out = ws.render(scan, cache=directory)
        return Case(cls, name, argv, expect="ok", gpu=True, png=out, lit=True, setup=setup,
                    quick=quick, devices=list(devices))

    def fifo(path):
        os.mkfifo(path)

    def zero(path):
        os.symlink("/dev/zero", path)

    def garbage(path):
        with open(path, "wb") as f:
            f.write(b"\xde\xad\xbe\xef" * 1024)

    def half(path):
        with open(os.path.join(control, os.path.basename(path)), "rb") as f:
            good = f.read()
        with open(path, "wb") as f:
            f.write(good[: len(good) // 2])

    def directory(path):
        os.makedirs(path)

    def dangling(path):
        os.symlink(path + ".missing", path)

    argv, out = ws.render(scan, cache=control)
    not_a_dir = ws.write("cache/plain-file", b"not a directory")
    argv2, out2 = ws.render(scan, cache=not_a_dir)
    return [
        Case(cls, "fresh directory (control)", argv, expect="ok", gpu=True, png=out, lit=True,
             quick=True),
        variant("fifo", fifo, quick=True),
        variant("symlink to /dev/zero", zero, quick=True, devices=["/dev/zero"]),
        variant("garbage", garbage),
        variant("half of a good file", half),
        variant("a directory", directory),
        variant("dangling symlink", dangling),
        Case(cls, "cache directory is a file", argv2, expect="ok", gpu=True, png=out2, lit=True,
             protect=[not_a_dir]),
    ]


def bricked(ws):
    cls = "bricked vs whole"
    ramp = ws.write("bricked/ramp.nii", nf.nifti1((32, 32, 32), "float32", nf.pack_voxels(
        [float(x + y + z) for z in range(32) for y in range(32) for x in range(32)], "float32")))
    out = []
    for source, label in ((None, "phantom"), (ramp, "ramp 32^3")):
        for mode in ("mip", "minip"):
            # Tissue peaks classify DVR only: MIP and MinIP print no "no csf peak" notes.
            whole = render_case(ws, cls, f"{label} {mode} whole", source, "--mode", mode, lit=True,
                                quick=label != "phantom" and mode == "mip", never_says=NO_PEAK)
            brick = render_case(ws, cls, f"{label} {mode} --bricked", source, "--mode", mode,
                                "--bricked", lit=True, quick=whole.quick, never_says=NO_PEAK)
            brick.same_image_as = whole.name
            out += [whole, brick]
    whole = render_case(ws, cls, "phantom dvr whole", None, lit=True)
    brick = render_case(ws, cls, "phantom dvr --bricked", None, "--bricked", lit=True)
    brick.same_image_as = whole.name
    return out + [whole, brick]


def arguments(ws):
    cls = "arguments"
    scan = _volume(ws, "args-scan.nii.gz")

    def r(name, *extra, expect="error", quick=False, size="64x64"):
        return render_case(ws, cls, name, scan, *extra, expect=expect, quick=quick, size=size)

    def phantom(dims, expect="error", quick=False):
        out = ws.fresh("phantom.nii")
        return Case(cls, f"phantom --dims {dims}", ["phantom", "--dims", dims, "-o", out],
                    expect=expect, quick=quick, absent_on_failure=[out])

    return [
        r("--azimuth NaN", "--azimuth", "NaN", quick=True),
        r("--azimuth inf", "--azimuth", "inf"),
        r("--elevation -inf", "--elevation=-inf"),
        r("--zoom NaN", "--zoom", "NaN"),
        r("--zoom 0", "--zoom", "0"),
        r("--zoom -1", "--zoom=-1"),
        r("--pan NaN,0", "--pan", "NaN,0"),
        r("--pan 1e300,0", "--pan", "1e300,0", expect="any"),
        r("--size 0x0", size="0x0", quick=True),
        r("--size 64x0", size="64x0"),
        r("--size 100000x100000", size="100000x100000", quick=True),
        r("--size 1x1", size="1x1", expect="any"),
        r("--step 0", "--step", "0", quick=True),
        r("--step -1", "--step=-1"),
        r("--step NaN", "--step", "NaN"),
        r("--step 1e-6", "--step", "1e-6", expect="any"),
        r("--step 1e30", "--step", "1e30", expect="any"),
        r("--memory-budget 0", "--memory-budget", "0"),
        r("--memory-budget 1e23 bytes", "--memory-budget", "99999999999999999999999"),
        r("--device 99", "--device", "99"),
        r("--turntable 0", "--turntable", "0"),
        r("--background #GGGGGG", "--background", "#GGGGGG"),
        r("--tissues bogus", "--tissues", "bogus"),
        r("--tissues ''", "--tissues", "", expect="any"),
        phantom("2048x2048x2048", quick=True),
        phantom("65536x65536x65536"),
        phantom("70000x1x1", expect="any"),
        phantom("0x0x0"),
        phantom("1x1x1", expect="any"),
    ]


def viewer(ws):
    cls = "viewer"
    scan = _volume(ws, "view-scan.nii.gz")
    trunc = ws.write("view/truncated.nii", nf.nifti1(DIMS)[:300])
    fifo = ws.path("view/fifo.nii")
    os.mkfifo(fifo)
    script = ws.write("view/garbage.txt", b"frobnicate 1 2 3\norbit NaN x\n")
    # 400x300: at 64x64 the tissue panel leaves the volume view no pixels and no frame is drawn.
    frames = ["--offscreen", "--frames", "3", "--size", "400x300"]

    def v(name, *args, expect="nonzero", quick=False):
        return Case(cls, name, ws.gpu("view", *args), expect=expect, gpu=True, quick=quick)

    return [
        v("missing file", ws.path("view/missing.nii"), *frames, quick=True),
        v("directory", ws.path("view"), *frames),
        v("truncated file", trunc, *frames),
        v("fifo", fifo, *frames),
        v("--offscreen without --frames", scan, "--offscreen", "--size", "400x300"),
        v("missing script", scan, *frames, "--script", ws.path("view/missing.txt")),
        v("garbage script", scan, *frames, "--script", script),
        v("screenshot into a missing directory", scan, *frames, "--screenshot",
          ws.path("view/missing/shot.png")),
        v("valid file (control)", scan, *frames, expect="ok"),
    ]


BUILDERS = (outputs, pipeline_cache, bricked, arguments, viewer)

