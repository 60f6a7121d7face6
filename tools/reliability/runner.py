"""Runs one probe case under limits and classifies what happened.

Decisions:
- Every run gets a wall-clock timeout, an address-space limit (RLIMIT_AS; lavapipe renders fit
  in 4 GiB), no core dumps, optionally a file-size limit (RLIMIT_FSIZE, with SIGXFSZ ignored so
  a write fails with EFBIG as on a full disk instead of killing the process), and its own
  session, so a timeout kills the whole process group.
- stdout and stderr go to files, not pipes: a run that floods them cannot block or fill the
  probe's memory; only the first 64 KiB of each are read back.
- One outcome per run, the most severe that applies: destroyed > panic > killed > timeout >
  memory (peak RSS over 1 GiB, read with os.wait4) > validation > what the exit status says.
  The other findings are kept as flags (a run can panic and also have destroyed a file).
  `FATAL` are the outcomes the probe exits non-zero on.
- A clean error is exit 1 (or 3, batch's failed scans) with exactly one `morphray: ...` line that is not a warning or note,
  and nothing else on stderr but warnings, notes and lavapipe's non-conformance banner.
- A render that succeeds is decoded (PNG, RGBA8, stdlib zlib) and counted: pixels that differ
  from the background. A blank image is reported as blank-with-a-note when stderr carried a
  `morphray: warning:` or `morphray: note:` line, else as silent.
"""

import hashlib
import os
import re
import resource
import signal
import stat
import struct
import subprocess
import time
import zlib

FATAL = ("destroyed", "panic", "killed", "timeout", "memory")
# Peak resident memory that counts as unbounded: every input is at most ~100 MB inflated, and a
# render of the 256x256x192 phantom on lavapipe peaks far below this. Under the probe's 4 GiB
# address-space limit an unbounded read ends in "out of memory" instead of the OOM killer;
# this flag keeps that from passing as a clean error.
MEMORY_KIB = 1 << 20
OUTCOMES = (
    "clean-error",
    "usage",
    "ok",
    "ok-blank-noted",
    "ok-blank-silent",
    "unclean-error",
    "validation",
    "timeout",
    "killed",
    "memory",
    "panic",
    "destroyed",
)
READ_BACK = 64 << 10
IGNORED_STDERR = ("WARNING: lavapipe is not a conformant vulkan implementation",)


def _limits(address_space, file_size):
    def apply():
        resource.setrlimit(resource.RLIMIT_AS, (address_space, address_space))
        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
        if file_size is not None:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (file_size, file_size))

    return apply


def fingerprint(path):
    """What 'unchanged' means for a protected path: its kind and, for a file, its SHA-256."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return ("missing",)
    if stat.S_ISREG(st.st_mode):
        with open(path, "rb") as f:
            return ("file", hashlib.sha256(f.read()).hexdigest())
    if stat.S_ISCHR(st.st_mode):
        return ("char", st.st_rdev)
    if stat.S_ISLNK(st.st_mode):
        return ("link", os.readlink(path))
    return ("other", stat.S_IFMT(st.st_mode))


def execute(binary, case, work, timeout, address_space):
    """Runs `case` and returns its result dict (outcome, flags, exit, timings, stderr tail)."""
    if case.setup is not None:
        case.setup()
    before = {p: fingerprint(p) for p in case.protect + case.protect_on_failure + case.devices}
    listings = {d: _listing(d) for d in {os.path.dirname(p) for p in case.absent_on_failure}}
    out_path = os.path.join(work, "last.stdout")
    err_path = os.path.join(work, "last.stderr")
    argv = [binary] + case.argv
    env = dict(os.environ, XDG_CACHE_HOME=os.path.join(work, "xdg-cache"), HOME=work)
    env.pop("MORPHRAY_CACHE_DIR", None)
    env.pop("MORPHRAY_VALIDATION", None)
    env.update(case.env)
    start = time.monotonic()
    with open(out_path, "wb") as out, open(err_path, "wb") as err:
        proc = subprocess.Popen(
            argv,
            stdin=subprocess.DEVNULL,
            stdout=out,
            stderr=err,
            cwd=case.cwd or work,
            env=env,
            preexec_fn=_limits(address_space, case.fsize),
            start_new_session=True,
        )
        code, timed_out, peak_rss = _wait(proc, timeout)
    wall = time.monotonic() - start
    stdout = _head(out_path)
    stderr = _head(err_path)
    after = {p: fingerprint(p) for p in before}
    result = {
        "class": case.cls,
        "name": case.name,
        "argv": argv,
        "expect": case.expect,
        "exit": code,
        "wall_s": round(wall, 3),
        "peak_rss_mib": round(peak_rss / 1024, 1),
        "stderr": stderr[-2000:],
        "stdout_head": stdout[:500],
    }
    flags = _flags(case, code, timed_out, stderr, before, after)
    leftovers = _leftovers(listings) if code != 0 and not timed_out else []
    if leftovers:
        flags.add("partial-output")
        result["leftovers"] = leftovers
    if peak_rss > MEMORY_KIB:
        flags.add("memory")
    result["changed"] = [p for p in before if before[p] != after[p]]
    if code == 0 and case.png and not flags & {"destroyed", "panic"}:
        _inspect_png(case, result, flags, stderr)
    result["flags"] = sorted(flags)
    result["outcome"] = _primary(flags)
    result["unexpected"] = _unexpected(case, result) or _wording(case, stdout + stderr, work)
    return result


def _wait(proc, timeout):
    """(exit code, timed out, peak RSS in KiB) of `proc`, killing its group after `timeout` s.
    os.wait4 gives this child's own rusage (RUSAGE_CHILDREN would be the maximum over every
    child the probe has waited for)."""
    deadline = time.monotonic() + timeout
    timed_out = False
    while True:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            break
        if time.monotonic() > deadline:
            timed_out = True
            os.killpg(proc.pid, signal.SIGKILL)
            pid, status, usage = os.wait4(proc.pid, 0)
            break
        time.sleep(0.02)
    code = os.waitstatus_to_exitcode(status)
    proc.returncode = code  # reaped here; keeps Popen from waiting again
    return code, timed_out, usage.ru_maxrss


def _listing(directory):
    try:
        return set(os.listdir(directory))
    except OSError:
        return set()


def _leftovers(listings):
    """Files that appeared next to an output of a failed run (a temporary file not removed)."""
    return sorted(
        os.path.join(d, name) for d, names in listings.items() for name in _listing(d) - names
    )


def _head(path):
    with open(path, "rb") as f:
        return f.read(READ_BACK).decode("utf-8", "replace")


def _flags(case, code, timed_out, stderr, before, after):
    flags = set()
    if timed_out:
        flags.add("timeout")
    elif code < 0:
        flags.add("killed")
    if "internal error" in stderr or "panicked at" in stderr or code == 101:
        flags.add("panic")
    if "validation layer reported" in stderr or "Validation Error" in stderr:
        flags.add("validation")
    changed = [p for p in before if before[p] != after[p]]
    for p in changed:
        if p in case.protect or p in case.devices:
            flags.add("destroyed")
        elif code != 0:
            flags.add("destroyed")  # protect_on_failure: only a success may replace it
    flags.add(_by_exit(code, stderr) if not timed_out and code >= 0 else "abnormal")
    return flags


def _by_exit(code, stderr):
    if code == 0:
        return "ok"
    if code == 2:
        return "usage"
    # 3 is `batch`'s "ran, but some scans failed": an error with its one line like 1.
    if code in (1, 3) and _one_error_line(stderr):
        return "clean-error"
    return "unclean-error"


def _one_error_line(stderr):
    errors = 0
    for line in stderr.splitlines():
        if not line.strip() or line.startswith(IGNORED_STDERR):
            continue
        # `morphray: batch:` lines are batch's progress (one per scan when stderr is no terminal).
        if line.startswith(("morphray: warning:", "morphray: note:", "morphray: batch:")):
            continue
        if not line.startswith("morphray: "):
            return False
        errors += 1
    return errors == 1


def _primary(flags):
    for outcome in ("destroyed", "panic", "killed", "timeout", "memory", "validation"):
        if outcome in flags:
            return outcome
    for outcome in ("ok-blank-silent", "ok-blank-noted", "ok", "usage", "clean-error"):
        if outcome in flags:
            return outcome
    return "unclean-error"


def _unexpected(case, result):
    """Why the outcome is wrong for this input even though nothing crashed; None if it is fine."""
    outcome, flags = result["outcome"], result["flags"]
    if outcome in FATAL:
        return None
    if "partial-output" in flags:
        return "a failed run left a partial output file"
    if result.get("mismatch"):
        return result["mismatch"]
    ok = outcome.startswith("ok")
    if case.expect == "error" and ok:
        return "succeeded where an error was due"
    if case.expect == "ok" and not ok:
        return "failed where success was due"
    if case.expect == "nonzero" and result["exit"] == 0:
        return "exit 0 where a non-zero exit was due"
    left = [p for p in case.gone if os.path.lexists(p)]
    if left:
        return f"left {', '.join(os.path.basename(p) for p in left)} in place"
    if case.code is not None and result["exit"] != case.code:
        return f"exit {result['exit']} where {case.code} was due"
    if outcome == "ok-blank-noted" and case.lit:
        return "blank image for a volume that has visible content"
    return None


def _wording(case, text, work):
    """Why the messages are wrong (a `says` pattern missing, a `never_says` one present). Paths
    and file names of the case are removed first: `pixdim-nan.nii` must not count as saying
    "pixdim"."""
    for arg in case.argv:
        if arg.startswith(work):
            text = text.replace(arg, " ").replace(os.path.basename(arg), " ")
    text = text.replace(work, " ")
    if case.says and not re.search(case.says, text, re.IGNORECASE):
        return f"the output does not say /{case.says}/"
    if case.never_says:
        found = re.search(case.never_says, text, re.IGNORECASE)
        if found:
            return f"the output says {found.group(0)!r}"
    return None


def _inspect_png(case, result, flags, stderr):
    try:
        width, height, pixels = decode_png(case.png)
    except (OSError, ValueError, zlib.error) as e:
        flags.discard("ok")
        flags.add("unclean-error")
        result["png_error"] = f"output is not a readable PNG: {e}"
        return
    lit = lit_pixels(pixels, case.background)
    result["png"] = {"width": width, "height": height, "lit": lit}
    if lit == 0:
        flags.discard("ok")
        noted = any(
            line.startswith(("morphray: warning:", "morphray: note:"))
            for line in stderr.splitlines()
        )
        flags.add("ok-blank-noted" if noted else "ok-blank-silent")


def decode_png(path):
    """(width, height, rows of RGBA bytes) of an 8-bit RGB or RGBA PNG, non-interlaced."""
    with open(path, "rb") as f:
        data = f.read(64 << 20)
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("no PNG signature")
    pos, idat, ihdr = 8, [], None
    while pos + 8 <= len(data):
        (n,) = struct.unpack(">I", data[pos : pos + 4])
        kind, body = data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + n]
        if kind == b"IHDR":
            ihdr = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            break
        pos += 12 + n
    if ihdr is None:
        raise ValueError("no IHDR chunk")
    width, height, depth, colour, _, _, interlace = ihdr
    if depth != 8 or colour not in (2, 6) or interlace != 0:
        raise ValueError(f"unsupported PNG (depth {depth}, colour type {colour})")
    channels = 4 if colour == 6 else 3
    raw = zlib.decompress(b"".join(idat))
    return width, height, _unfilter(raw, width, height, channels)


def _unfilter(raw, width, height, bpp):
    stride = width * bpp
    rows, prev = [], bytearray(stride)
    for y in range(height):
        base = y * (stride + 1)
        kind, line = raw[base], bytearray(raw[base + 1 : base + 1 + stride])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b, c = prev[i], prev[i - bpp] if i >= bpp else 0
            if kind == 1:
                line[i] = (line[i] + a) & 255
            elif kind == 2:
                line[i] = (line[i] + b) & 255
            elif kind == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif kind == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa <= pb and pa <= pc else b if pb <= pc else c
                line[i] = (line[i] + pred) & 255
        rows.append((bytes(line), bpp))
        prev = line
    return rows


def lit_pixels(rows, background=(0, 0, 0), tolerance=3):
    """Pixels whose RGB differs from the background by more than `tolerance` in some channel
    (the tolerance absorbs dithering; a real structure differs by far more)."""
    lit = 0
    for line, bpp in rows:
        for i in range(0, len(line), bpp):
            if any(abs(line[i + k] - background[k]) > tolerance for k in range(3)):
                lit += 1
    return lit
