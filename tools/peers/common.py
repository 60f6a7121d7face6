"""What every peer script shares: the clock, the orbit camera, statistics, JSON/PNG output, CLI.

Kept to the standard library at import time (numpy is imported by the callers inside their timed
"imports" phase), so that importing this module costs next to nothing before the clock starts.
"""

import argparse
import json
import math
import os
import platform
import struct
import sys
import time
import zlib

# Environment variable the runner sets to time.monotonic_ns() just before it spawns a peer.
SPAWN_ENV = "PEERS_SPAWN_MONOTONIC_NS"


def process_start_ns(script_start_ns):
    """CLOCK_MONOTONIC time (ns) at which this process started, and how it was found.

    Preferred: the runner's wall-clock reading just before spawning the process (env
    PEERS_SPAWN_MONOTONIC_NS, CLOCK_MONOTONIC is system-wide on Linux, so it compares across
    processes); it includes fork/exec and the interpreter's own start-up.
    Fallback (a peer started by hand): /proc/self/stat field 22 (start time in clock ticks since
    boot, 10 ms resolution at CLK_TCK = 100) against CLOCK_BOOTTIME, converted to the monotonic
    clock. If neither works, the script's first line is used (interpreter start-up then missing).
    """
    env = os.environ.get(SPAWN_ENV)
    if env:
        try:
            t = int(env)
            if 0 < t <= script_start_ns:
                return t, "runner spawn time (env %s, CLOCK_MONOTONIC)" % SPAWN_ENV
        except ValueError:
            pass
    try:
        with open("/proc/self/stat") as f:
            stat = f.read()
        # The command name (field 2) may contain spaces: split after its closing parenthesis.
        fields = stat[stat.rindex(")") + 2 :].split()
        start_ticks = int(fields[22 - 3])
        tck = os.sysconf("SC_CLK_TCK")
        now_boot = time.clock_gettime_ns(time.CLOCK_BOOTTIME)
        now_mono = time.monotonic_ns()
        age_ns = now_boot - start_ticks * 1_000_000_000 // tck
        if 0 <= age_ns < 3600 * 1_000_000_000:
            return now_mono - age_ns, "/proc/self/stat starttime vs CLOCK_BOOTTIME (1/%d s resolution)" % tck
    except (OSError, ValueError, IndexError, AttributeError):
        pass
    return script_start_ns, "script start (interpreter start-up not counted)"


class Phases:
    """Consecutive phases of time to first pixel, in ms, from the process start."""

    def __init__(self, script_start_ns):
        self.origin_ns, self.clock = process_start_ns(script_start_ns)
        self.last_ns = self.origin_ns
        self.ms = {}
        self.mark("interpreter", script_start_ns)

    def mark(self, name, now_ns=None):
        now_ns = time.monotonic_ns() if now_ns is None else now_ns
        self.ms[name] = (now_ns - self.last_ns) / 1e6
        self.last_ns = now_ns

    def total_ms(self):
        return (self.last_ns - self.origin_ns) / 1e6


def eye_position(dims, spacing, width, height, azimuth_deg, fov_y_deg=30.0):
    """morphray's orbit camera (src/scene/camera.rs) for voxel centres at index * spacing (mm).

    The voxel box spans [-0.5, n - 0.5] * spacing per axis; its centre is (n - 1) / 2 * spacing.
    Radius = half the largest world extent (n * spacing); the eye sits where that sphere fills the
    smaller image dimension: distance = r / sin(atan(min(tan(fov/2), tan(fov/2) * aspect))).
    Azimuth 0 = anterior view (eye on +y looking posterior), 90 = from the patient's right (+x);
    elevation 0; superior (+z) is up. Returns (eye, centre, up, distance, radius).
    """
    extent = [n * s for n, s in zip(dims, spacing)]
    radius = max(0.5 * max(extent), 1e-6)
    half = math.tan(math.radians(fov_y_deg) * 0.5)
    aspect = width / max(height, 1)
    distance = radius / math.sin(math.atan(min(half, half * aspect)))
    a = math.radians(azimuth_deg)
    to_cam = (math.sin(a), math.cos(a), 0.0)
    centre = tuple((n - 1) * 0.5 * s for n, s in zip(dims, spacing))
    eye = tuple(c + t * distance for c, t in zip(centre, to_cam))
    return eye, centre, (0.0, 0.0, 1.0), distance, radius


def percentile(sorted_values, p):
    """Linear-interpolated percentile (numpy's default) of an already sorted list."""
    if not sorted_values:
        return None
    k = (len(sorted_values) - 1) * p / 100.0
    lo = math.floor(k)
    hi = min(lo + 1, len(sorted_values) - 1)
    return sorted_values[lo] + (sorted_values[hi] - sorted_values[lo]) * (k - lo)


def frame_stats(ms):
    s = sorted(ms)
    if not s:
        return {"n": 0}
    med = percentile(s, 50)
    return {
        "median": round(med, 3),
        "p5": round(percentile(s, 5), 3),
        "p95": round(percentile(s, 95), 3),
        "min": round(s[0], 3),
        "max": round(s[-1], 3),
        "mean": round(sum(s) / len(s), 3),
        "n": len(s),
    }


def write_png(path, rgba_rows, width, height):
    """Writes 8-bit RGBA bytes (top row first) as a PNG with the standard library only."""
    raw = b"".join(b"\x00" + rgba_rows[y * width * 4 : (y + 1) * width * 4] for y in range(height))

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b"")
    with open(path, "wb") as f:
        f.write(png)


def parse_size(text):
    try:
        w, h = text.lower().split("x")
        w, h = int(w), int(h)
        if w < 1 or h < 1 or w > 16384 or h > 16384:
            raise ValueError
        return w, h
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must be WIDTHxHEIGHT (e.g. 1920x1080), not {text!r}") from None


def base_parser(description):
    p = argparse.ArgumentParser(description=description, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("volume", help="NIfTI-1 volume (.nii or .nii.gz), e.g. the output of `morphray phantom`")
    p.add_argument("--size", type=parse_size, default=(1920, 1080), help="image size WIDTHxHEIGHT (default 1920x1080)")
    p.add_argument(
        "--frames",
        type=int,
        default=200,
        help="timed frames of the orbit, frame i at azimuth 360*i/N (default 200); 0 = time to first pixel only",
    )
    p.add_argument(
        "--warmup-frames",
        type=int,
        default=5,
        help="untimed frames after the first one before timing starts (default 5); warm-up also lasts "
        "at least --warmup-s",
    )
    p.add_argument("--warmup-s", type=float, default=0.5, help="minimum warm-up duration in seconds (default 0.5)")
    p.add_argument(
        "--budget-s",
        type=float,
        default=0.0,
        help="if > 0, fewer orbit frames (at least 20, still a full turn) when the warm-up predicts the "
        "orbit would take longer than this many seconds (default 0 = off)",
    )
    p.add_argument("--json", metavar="FILE", help="write the result as one JSON object to FILE")
    p.add_argument("--png", metavar="FILE", help="save the last rendered frame as a PNG (read back after timing)")
    p.add_argument(
        "--azimuth", type=float, default=0.0, help="azimuth of the first frame in degrees (default 0 = anterior)"
    )
    return p


def run_orbit(render_frame, frames, warmup_frames, warmup_s, azimuth0, budget_s=0.0):
    """Warm-up then timed orbit. `render_frame(azimuth_deg)` renders one frame and waits for the GPU.

    Warm-up frames walk the orbit too (so they touch the same views) and are discarded; timing then
    starts at azimuth0 and covers frames 0..N-1 at azimuth0 + 360 * i / N. With budget_s > 0, N is
    lowered (to no fewer than 20) when the warm-up's median frame time says N frames would take
    longer than budget_s: the orbit stays complete, with fewer, wider steps (device time is scarce).
    Returns (ms list, info dict).
    """
    if frames <= 0:
        return [], {"frames": 0, "ms": 0.0}
    t0 = time.perf_counter()
    w = 0
    warm_ms = []
    while w < warmup_frames or (time.perf_counter() - t0) < warmup_s:
        t = time.perf_counter()
        render_frame(azimuth0 + 360.0 * (w % frames) / frames)
        warm_ms.append((time.perf_counter() - t) * 1e3)
        w += 1
        if w >= max(warmup_frames, 1) * 50:  # a safety cap for absurd --warmup-s
            break
    info = {"frames": w, "ms": round((time.perf_counter() - t0) * 1e3, 1), "frames_requested": frames}
    if budget_s > 0 and warm_ms:
        est = sorted(warm_ms)[len(warm_ms) // 2]
        fit = int(budget_s * 1e3 / max(est, 1e-3))
        if fit < frames:
            frames = max(min(frames, 20), fit)
            info["budget_s"] = budget_s
            info["frames_reduced_to"] = frames
    ms = []
    for i in range(frames):
        t = time.perf_counter()
        render_frame(azimuth0 + 360.0 * i / frames)
        ms.append((time.perf_counter() - t) * 1e3)
    return ms, info


def result_skeleton(peer, args, volume):
    w, h = args.size
    return {
        "peer": peer,
        "python": platform.python_version(),
        "pid": os.getpid(),
        "input": volume.describe() if volume is not None else {"path": os.path.abspath(args.volume)},
        "image": [w, h],
        "frames": args.frames,
        "camera": {
            "projection": "perspective",
            "fov_y_deg": 30.0,
            "elevation_deg": 0.0,
            "azimuth0_deg": args.azimuth,
            "fit": "bounding sphere (radius = half the largest extent) fills the smaller image dimension",
        },
    }


def timing_fields(ttfp_ms, phases, ms, stats, warm, args, png):
    """The measurement fields every peer's JSON carries: time to first pixel with its phases, the
    orbit's frame times and FPS, the warm-up, and where the last frame went."""
    return {
        "ttfp_ms": {
            "total": round(ttfp_ms, 3),
            "phases": {k: round(v, 3) for k, v in phases.ms.items()},
            "clock": phases.clock,
        },
        "frames": len(ms),
        "frames_requested": args.frames,
        "warmup": warm,
        "frame_ms": stats,
        "fps": round(1e3 / stats["median"], 3) if ms else None,
        "fps_mean": round(1e3 * len(ms) / sum(ms), 3) if ms else None,
        "png": png,
    }


def orbit_summary(ms, stats):
    """The frame-time part of a peer's one-line summary ('' when no orbit was rendered)."""
    if not ms:
        return ""
    return (
        f"; {stats['n']} frames median {stats['median']:.2f} ms (p5 {stats['p5']:.2f}, "
        f"p95 {stats['p95']:.2f}), {1e3 / stats['median']:.1f} FPS"
    )


def finish(result, args, summary):
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)
            f.write("\n")
    print(summary, flush=True)


def fail(peer, args, message, code=2):
    """One-line error on stderr, and a JSON with the error so a runner can record it."""
    print(f"{peer}: error: {message}", file=sys.stderr, flush=True)
    if args is not None and getattr(args, "json", None):
        try:
            with open(args.json, "w") as f:
                json.dump({"peer": peer, "error": message}, f)
                f.write("\n")
        except OSError:
            pass
    sys.exit(code)
