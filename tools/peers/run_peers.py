#!/usr/bin/env python3
"""Runs the peer renderers side by side: K fresh processes each for time to first pixel, one orbit.

For every peer and trial t = 1..K a new Python process is started (the runner writes
time.monotonic_ns() into PEERS_SPAWN_MONOTONIC_NS just before spawning it, so time to first pixel
includes interpreter start-up). Trial 1 also renders the timed orbit (--frames); trials 2..K stop
after the first frame. Trials are interleaved across peers (t=1 of every peer, then t=2, ...) so a
slow drift or a cold page cache does not land on one peer only; the median over the K trials is
the reported time to first pixel.

A peer that fails or times out is recorded with its error and the run goes on.
Writes DIR/peers.json (everything, including each process's own JSON) and DIR/peers.txt (a table).
"""

import argparse
import json
import os
import platform
import re
import signal
import subprocess
import sys
import tempfile
import time

ANSI = re.compile(r"\x1b\[[0-9;]*m")
HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import common  # noqa: E402

# name -> (script, extra arguments)
PEERS = {
    "vtk-composite": ("peer_vtk.py", ["--blend", "composite"]),
    "vtk-composite-plain": ("peer_vtk.py", ["--blend", "composite", "--no-shade"]),
    "vtk-mip": ("peer_vtk.py", ["--blend", "mip"]),
    "pygfx-mip": ("peer_pygfx.py", ["--step", "0.5"]),
    "pygfx-mip-stockstep": ("peer_pygfx.py", ["--step", "stock"]),
}
DEFAULT_PEERS = "vtk-composite,vtk-mip,pygfx-mip,pygfx-mip-stockstep"


def parse_args():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("volume", help="NIfTI-1 volume (.nii/.nii.gz), e.g. `morphray phantom -o phantom.nii.gz`")
    p.add_argument(
        "--size", type=common.parse_size, default=(1920, 1080), help="image size WIDTHxHEIGHT (default 1920x1080)"
    )
    p.add_argument("--frames", type=int, default=200, help="timed orbit frames in trial 1 (default 200)")
    p.add_argument(
        "--trials", "-k", type=int, default=5, help="fresh processes per peer for time to first pixel (default 5)"
    )
    p.add_argument(
        "--peers", default=DEFAULT_PEERS, help=f"comma-separated subset of {', '.join(PEERS)} (default: all)"
    )
    p.add_argument(
        "--out",
        default="peers-out",
        help="output folder for peers.json, peers.txt and the PNGs (at most 2 + number of peers files: the "
        "device tool returns few files)",
    )
    p.add_argument(
        "--work",
        default=None,
        help="folder for each process's own JSON (default: a temporary folder; all of it is also inside peers.json)",
    )
    p.add_argument("--png", action="store_true", help="save the last orbit frame of each peer as OUT/NAME.png")
    p.add_argument("--warmup-frames", type=int, default=5, help="untimed frames before the orbit (default 5)")
    p.add_argument("--warmup-s", type=float, default=0.5, help="minimum warm-up seconds (default 0.5)")
    p.add_argument(
        "--orbit-budget-s",
        type=float,
        default=120.0,
        help="per peer: if the warm-up predicts the orbit takes longer, render fewer frames (>= 20, still "
        "a full turn; recorded in the JSON); 0 = always --frames (default 120)",
    )
    p.add_argument("--timeout", type=float, default=300.0, help="seconds before a peer process is killed (default 300)")
    p.add_argument("--python", default=sys.executable, help="interpreter for the peers (default: this one)")
    args = p.parse_args()
    names = [n.strip() for n in args.peers.split(",") if n.strip()]
    unknown = [n for n in names if n not in PEERS]
    if unknown:
        p.error(f"unknown peer(s) {', '.join(unknown)}; choose from {', '.join(PEERS)}")
    if args.trials < 1 or args.frames < 0:
        p.error("--trials must be >= 1 and --frames >= 0")
    args.peer_names = names
    return args


def run_one(args, name, trial):
    script, extra = PEERS[name]
    w, h = args.size
    json_path = os.path.join(args.work, f"{name}-t{trial}.json")
    if os.path.exists(json_path):
        os.remove(json_path)
    frames = args.frames if trial == 1 else 0
    cmd = [
        args.python,
        os.path.join(HERE, script),
        args.volume,
        "--size",
        f"{w}x{h}",
        "--frames",
        str(frames),
        "--warmup-frames",
        str(args.warmup_frames),
        "--warmup-s",
        str(args.warmup_s),
        "--budget-s",
        str(args.orbit_budget_s),
        "--json",
        json_path,
    ] + extra
    if args.png and trial == 1:
        cmd += ["--png", os.path.join(args.out, f"{name}.png")]
    env = dict(os.environ)
    env["PYTHONUNBUFFERED"] = "1"
    rec = {"trial": trial, "frames": frames, "command": " ".join(cmd)}
    t_wall = time.perf_counter()
    env[common.SPAWN_ENV] = str(time.monotonic_ns())
    # A new session, so a timeout can end the peer and anything it started, and nothing else.
    proc = subprocess.Popen(
        cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True
    )
    try:
        out, err = proc.communicate(timeout=args.timeout)
    except subprocess.TimeoutExpired:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        out, err = proc.communicate()
        rec["error"] = f"timed out after {args.timeout:g} s"
    rec["wall_s"] = round(time.perf_counter() - t_wall, 3)
    rec["returncode"] = proc.returncode
    rec["stdout_tail"] = out.strip().splitlines()[-3:]
    # Drop known harmless noise (the Vulkan loader's XDG_RUNTIME_DIR complaint on headless hosts)
    # and VTK's terminal colour codes.
    err_lines = [
        ANSI.sub("", line).strip() for line in err.splitlines() if line.strip() and "XDG_RUNTIME_DIR" not in line
    ]
    rec["stderr_tail"] = err_lines[-8:]
    result = None
    if os.path.exists(json_path):
        try:
            with open(json_path) as f:
                result = json.load(f)
        except (OSError, json.JSONDecodeError) as e:
            rec.setdefault("error", f"unreadable JSON {json_path}: {e}")
    if result is not None and "error" in result:
        rec.setdefault("error", result["error"])
    if "error" not in rec and (proc.returncode != 0 or result is None):
        last = err_lines[-1] if err_lines else "no output"
        status = f"exit status {proc.returncode}"
        if proc.returncode < 0:
            status = f"killed by {signal.Signals(-proc.returncode).name}"
        rec["error"] = f"{status}; last stderr line: {last}"
    rec["result"] = result
    return rec


def summarize(name, recs):
    ok = [r for r in recs if "error" not in r and r["result"]]
    ttfp = sorted(r["result"]["ttfp_ms"]["total"] for r in ok)
    phases = {}
    for r in ok:
        for k, v in r["result"]["ttfp_ms"]["phases"].items():
            phases.setdefault(k, []).append(v)
    s = {"peer": name, "trials_ok": len(ok), "trials": len(recs), "errors": [r["error"] for r in recs if "error" in r]}
    if ttfp:
        s["ttfp_ms"] = {
            "median": round(common.percentile(ttfp, 50), 1),
            "min": round(ttfp[0], 1),
            "max": round(ttfp[-1], 1),
            "all": [round(t, 1) for t in (r["result"]["ttfp_ms"]["total"] for r in ok)],
            "phases_median": {k: round(common.percentile(sorted(v), 50), 1) for k, v in phases.items()},
            "clock": ok[0]["result"]["ttfp_ms"]["clock"],
        }
    orbit = next((r for r in ok if r["trial"] == 1 and r["result"].get("frame_ms", {}).get("n")), None)
    if orbit:
        res = orbit["result"]
        s["frame_ms"] = res["frame_ms"]
        s["fps"] = res["fps"]
        s["warmup"] = res.get("warmup")
    first = ok[0]["result"] if ok else None
    if first:
        for k in ("peer_version", "renderer", "blend_mode", "sample_distance_voxels", "png"):
            s[k] = first.get(k)
        if orbit:
            s["png"] = orbit["result"].get("png")
    return s


def table(summaries, args):
    w, h = args.size
    lines = [
        f"peers on {os.path.basename(args.volume)}, {w}x{h}, orbit {args.frames} frames, K = {args.trials} "
        f"processes per peer for time to first pixel (median [min-max])",
        f"{'peer':22} {'version':8} {'blend':9} {'step':>5} {'ttfp ms':>22} {'n':>4} {'frame ms med':>12} {'p5':>8} {'p95':>8} {'FPS':>7}  renderer",
    ]
    for s in summaries:
        if "ttfp_ms" not in s:
            lines.append(f"{s['peer']:22} FAILED: {s['errors'][0] if s['errors'] else 'no result'}")
            continue
        t = s["ttfp_ms"]
        ttfp = f"{t['median']:.0f} [{t['min']:.0f}-{t['max']:.0f}]"
        fm = s.get("frame_ms") or {}
        fmt = lambda v: f"{v:.2f}" if isinstance(v, (int, float)) else "-"  # noqa: E731
        step = s.get("sample_distance_voxels")
        lines.append(
            f"{s['peer']:22} {str(s.get('peer_version')):8} {str(s.get('blend_mode')):9} "
            f"{(f'{step:g}' if step else '-'):>5} {ttfp:>22} {fm.get('n', 0):>4} {fmt(fm.get('median')):>12} {fmt(fm.get('p5')):>8} "
            f"{fmt(fm.get('p95')):>8} {fmt(s.get('fps')):>7}  {s.get('renderer')}"
        )
        if s["errors"]:
            lines.append(f"{'':22} ({len(s['errors'])} failed trial(s): {s['errors'][0]})")
    return "\n".join(lines)


def main():
    args = parse_args()
    os.makedirs(args.out, exist_ok=True)
    if args.work is None:
        args.work = tempfile.mkdtemp(prefix="peers-")
    os.makedirs(args.work, exist_ok=True)
    if not os.path.exists(args.volume):
        print(f"run_peers: error: {args.volume}: no such file", file=sys.stderr)
        sys.exit(2)
    started = time.time()
    runs = {n: [] for n in args.peer_names}
    for trial in range(1, args.trials + 1):
        for name in args.peer_names:
            rec = run_one(args, name, trial)
            runs[name].append(rec)
            res = rec.get("result") or {}
            if "error" in rec:
                print(f"[{name} t{trial}] FAILED: {rec['error']}", flush=True)
            else:
                extra = ""
                if res.get("frame_ms", {}).get("n"):
                    extra = f", frames median {res['frame_ms']['median']:.2f} ms"
                print(
                    f"[{name} t{trial}] ttfp {res['ttfp_ms']['total']:.0f} ms{extra} ({rec['wall_s']:.1f} s)",
                    flush=True,
                )
    summaries = [summarize(n, runs[n]) for n in args.peer_names]
    combined = {
        "tool": "tools/peers/run_peers.py",
        "started_unix": round(started, 3),
        "host": {"python": platform.python_version(), "machine": platform.machine(), "node": platform.node()},
        "input": os.path.abspath(args.volume),
        "image": list(args.size),
        "frames": args.frames,
        "trials": args.trials,
        "warmup": {"frames": args.warmup_frames, "min_s": args.warmup_s},
        "summary": summaries,
        "runs": runs,
    }
    with open(os.path.join(args.out, "peers.json"), "w") as f:
        json.dump(combined, f, indent=1)
        f.write("\n")
    text = table(summaries, args)
    with open(os.path.join(args.out, "peers.txt"), "w") as f:
        f.write(text + "\n")
    print(text, flush=True)
    # Non-zero only if every peer failed: partial results are still results.
    sys.exit(0 if any("ttfp_ms" in s for s in summaries) else 1)


if __name__ == "__main__":
    main()
