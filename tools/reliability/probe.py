#!/usr/bin/env python3
"""Feeds the morphray binary bad inputs and prints what each class of them gets (issue 12).

    python3 tools/reliability/probe.py [--binary PATH] [--quick] [--json OUT] [--only TEXT]

Generates every input in a temporary directory (NIfTI headers, gzip streams, odd voxel data,
special files, outputs that must not be overwritten, a damaged pipeline cache, bricked against
whole renders, bad arguments, the viewer), runs the binary on each, one at a time, under a
wall-clock timeout and a 4 GiB address-space limit, and prints a markdown table (class, inputs
tried, count per outcome) followed by every run that was not clean, with its command line.

Exit status: 0 when no run panicked, hung, was killed, took more than 1 GiB of memory or
destroyed a file; 1 when one did; 3 when the binary is missing or finds no usable Vulkan device
(GPU cases could not mean anything, so the probe refuses to report them as passing).
Python 3.11 standard library only.

Decisions (the rest are in the module docs of runner.py, case.py and the two case files):
- Cases run sequentially: the probe measures the program, and lavapipe already uses every core.
- `--quick` keeps 41 cases (38 before issue 30's batch, temporary-file and cache cases), the ones that show a crash, hang, kill, memory blow-up or lost file,
  so a cargo test can run it in under two minutes (79 s on main at 5573ea9, which hangs on three
  of them; 2-core Debian 12, lavapipe); the full run took 456 s there (RELIABILITY.md).
- Paths in the report are written relative to the temporary directory (`$T`) so two runs of the
  same binary print the same text.
"""

import argparse
import hashlib
import json
import os
import platform
import shlex
import shutil
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import cases_input  # noqa: E402
import cases_issue30  # noqa: E402
import cases_issue30_dicom  # noqa: E402
import cases_issue30_misc  # noqa: E402
import cases_run  # noqa: E402
import runner  # noqa: E402
from case import NotRun, Workspace  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
ADDRESS_SPACE = 4 << 30
COLUMNS = (
    ("clean-error", "clean error"),
    ("usage", "usage error"),
    ("ok", "ok"),
    ("ok-blank-noted", "ok, blank, noted"),
    ("ok-blank-silent", "ok, blank, silent"),
    ("unclean-error", "unclean error"),
    ("validation", "validation"),
    ("timeout", "timeout"),
    ("killed", "killed"),
    ("memory", "peak RSS > 1 GiB"),
    ("panic", "panic"),
    ("destroyed", "destroyed"),
)
NOT_RUN = "not-run"


def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--binary", default=os.path.join(REPO, "target", "release", "morphray"))
    p.add_argument("--quick", action="store_true", help="the small subset (under 2 minutes)")
    p.add_argument("--json", metavar="OUT", help="also write every result as JSON")
    p.add_argument("--only", metavar="TEXT", help="only classes whose name contains TEXT")
    p.add_argument("--timeout", type=float, help="seconds per run (default 60 GPU, 30 CPU)")
    p.add_argument("--no-validation", action="store_true", help="GPU runs without the layer")
    p.add_argument("--keep", action="store_true", help="keep the temporary directory")
    return p.parse_args(argv)


def preflight(binary):
    """None when the binary runs and sees a usable Vulkan device, else the reason."""
    if not (os.path.isfile(binary) and os.access(binary, os.X_OK)):
        return f"{binary} is not an executable file (build it, or pass --binary)"
    try:
        done = subprocess.run([binary, "devices"], capture_output=True, text=True, timeout=120)
    except subprocess.TimeoutExpired:
        return f"`{binary} devices` did not answer in 120 s"
    if done.returncode != 0 or "usable" not in done.stdout:
        return f"no usable Vulkan device: {(done.stdout + done.stderr).strip()[:300]}"
    return None


def validation_available(binary):
    done = subprocess.run(
        [binary, "--validation", "devices"], capture_output=True, text=True, timeout=120
    )
    return done.returncode == 0


def build_cases(ws, quick, only):
    cases = []
    for builder in (cases_input.BUILDERS + cases_run.BUILDERS + cases_issue30.BUILDERS
                    + cases_issue30_dicom.BUILDERS + cases_issue30_misc.BUILDERS):
        cases += builder(ws)
    if only:
        cases = [c for c in cases if only in c.cls]
    if quick:
        cases = [c for c in cases if c.quick]
    return cases


def run_all(binary, ws, cases, timeout, quick):
    results, by_name = [], {}
    for i, case in enumerate(cases, 1):
        # A hang shows within seconds; the full run waits longer so a slow machine's honest
        # GPU work is not mistaken for one.
        limit = timeout or {(False, False): 30.0, (False, True): 60.0, (True, False): 10.0,
                            (True, True): 30.0}[(quick, case.gpu)]
        try:
            result = runner.execute(binary, case, ws.root, limit, ADDRESS_SPACE)
        except NotRun as why:
            result = not_run(binary, case, str(why))
        compare_images(case, result, by_name)
        by_name[(case.cls, case.name)] = result
        results.append(result)
        print(
            f"[{i}/{len(cases)}] {case.cls} / {case.name}: {result['outcome']}"
            f" ({result.get('wall_s', 0):.1f} s)",
            file=sys.stderr,
            flush=True,
        )
    return results


def not_run(binary, case, why):
    return {
        "class": case.cls,
        "name": case.name,
        "argv": [binary] + case.argv,
        "expect": case.expect,
        "outcome": NOT_RUN,
        "flags": [NOT_RUN],
        "unexpected": f"not run: {why}",
    }


def compare_images(case, result, by_name):
    """A bricked render must light the same pixels as its whole twin (within 2 %)."""
    if not case.same_image_as:
        return
    twin = by_name.get((case.cls, case.same_image_as))
    a = (twin or {}).get("png", {}).get("lit")
    b = result.get("png", {}).get("lit")
    if a is None or b is None:
        return
    result["compared_with"] = {"case": case.same_image_as, "lit": a}
    if abs(a - b) > max(16, 0.02 * max(a, b)):
        result["mismatch"] = f"{b} lit pixels against {a} without --bricked"
        if result["unexpected"] is None:
            result["unexpected"] = result["mismatch"]


def relative(text, ws):
    return text.replace(ws.root, "$T")


def _relative_all(value, ws):
    """`value` with the temporary directory written as `$T` in every string inside it."""
    if isinstance(value, str):
        return relative(value, ws)
    if isinstance(value, list):
        return [_relative_all(v, ws) for v in value]
    if isinstance(value, dict):
        return {k: _relative_all(v, ws) for k, v in value.items()}
    return value


def command_line(result, ws):
    return relative(shlex.join(["morphray"] + result["argv"][1:]), ws)


def table(results):
    classes = []
    for r in results:
        if r["class"] not in classes:
            classes.append(r["class"])
    head = ["class", "tried"] + [label for _, label in COLUMNS] + ["not as expected"]
    lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    totals = [0] * (len(head) - 1)
    for cls in classes:
        rows = [r for r in results if r["class"] == cls]
        counts = [len(rows)] + [sum(r["outcome"] == key for r in rows) for key, _ in COLUMNS]
        counts.append(sum(r["unexpected"] is not None for r in rows))
        totals = [t + c for t, c in zip(totals, counts)]
        lines.append("| " + " | ".join([cls] + [_cell(c) for c in counts]) + " |")
    lines.append("| **all** | " + " | ".join(f"**{t}**" for t in totals) + " |")
    return "\n".join(lines)


def _cell(n):
    return str(n) if n else "."


def not_clean(results, ws):
    """Every run that crashed, hung, destroyed, left a silent blank, or did not do what its
    input calls for, as markdown list items."""
    clean = {"clean-error", "usage", "ok", "ok-blank-noted"}
    lines = []
    for r in results:
        if r["outcome"] in clean and r["unexpected"] is None:
            continue
        why = _first_line(r.get("stderr", ""))
        if r.get("changed") and "destroyed" in r["flags"]:
            why = f"modified {', '.join(r['changed'])}; stderr: {why}"
        if r["unexpected"]:
            why = f"{r['unexpected']}; stderr: {why}"
        extra = [f for f in r["flags"] if f in runner.FATAL and f != r["outcome"]]
        tag = r["outcome"] + (f" (+{', '.join(extra)})" if extra else "")
        lines.append(
            f"- **{tag}** {r['class']} / {r['name']}: `{command_line(r, ws)}`"
            f" (exit {r.get('exit')}): {relative(why, ws)}"
        )
    return "\n".join(lines) if lines else "(none)"


def _first_line(text):
    """The error line of stderr, else its first note or warning."""
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    for line in lines:
        if not line.startswith(("morphray: warning:", "morphray: note:")):
            return line[:300]
    return lines[0][:300] if lines else "(no message)"


def fatal(results):
    return [r for r in results if set(r["flags"]) & set(runner.FATAL)]


def describe_binary(binary):
    with open(binary, "rb") as f:
        digest = hashlib.sha256(f.read()).hexdigest()
    return {"path": binary, "sha256": digest}


def main(argv=None):
    args = parse_args(argv)
    binary = os.path.abspath(args.binary)
    problem = preflight(binary)
    if problem:
        print(f"probe: {problem}", file=sys.stderr)
        return 3
    validation = not args.no_validation and validation_available(binary)
    if not validation and not args.no_validation:
        print("probe: note: the validation layer is not available; GPU runs go without it",
              file=sys.stderr)
    root = tempfile.mkdtemp(prefix="morphray-probe-")
    started = time.time()
    try:
        ws = Workspace(root, validation=validation)
        cases = build_cases(ws, args.quick, args.only)
        results = run_all(binary, ws, cases, args.timeout, args.quick)
        report(args, binary, ws, results, time.time() - started, validation)
    finally:
        if args.keep:
            print(f"probe: kept {root}", file=sys.stderr)
        else:
            shutil.rmtree(root, ignore_errors=True)
    bad = fatal(results)
    if bad:
        print(f"probe: {len(bad)} run(s) panicked, hung, were killed, took over 1 GiB or"
              " destroyed a file",
              file=sys.stderr)
        return 1
    return 0


def report(args, binary, ws, results, seconds, validation):
    print(f"## morphray under bad input ({'quick' if args.quick else 'full'} probe)\n")
    print(f"binary sha256 {describe_binary(binary)['sha256'][:16]}, {len(results)} runs,"
          f" {seconds:.0f} s, validation layer {'on' if validation else 'off'}\n")
    print(table(results))
    print("\n### Runs that were not clean\n")
    print(not_clean(results, ws))
    if args.json:
        doc = {
            "binary": describe_binary(binary),
            "machine": {"platform": platform.platform(), "cpus": os.cpu_count()},
            "quick": args.quick,
            "validation": validation,
            "seconds": round(seconds, 1),
            "results": [_relative_all(r, ws) for r in results],
        }
        with open(args.json, "w") as f:
            json.dump(doc, f, indent=1)


if __name__ == "__main__":
    sys.exit(main())
