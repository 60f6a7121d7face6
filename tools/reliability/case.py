"""What one probe run is (`Case`) and where its files live (`Workspace`).

Decisions:
- A case is plain data: the class it counts under (a row of the table), a variant name, the
  arguments after the binary, what a correct program does with it (`expect`), and the paths
  whose bytes must survive. Expectations are deliberately coarse: "error" (a clean error or a
  usage error is right; success is wrong), "ok", "nonzero" (any non-zero exit, for the viewer)
  and "any" (either answer is defensible; only crashes, hangs, silent blanks count against it).
- GPU runs use the Khronos validation layer (`--validation`, unless the probe is told not to)
  and the probe's own pipeline cache directory, never the user's.
- `setup` runs just before the case (for inputs that depend on an earlier run, like the
  pipeline-cache file name) and may raise `NotRun` to skip it with a reason.
"""

import os
from dataclasses import dataclass, field
from typing import Callable, Optional

RENDER_SIZE = "64x64"


class NotRun(Exception):
    """A case whose precondition could not be set up (the reason is reported)."""


@dataclass
class Case:
    cls: str
    name: str
    argv: list
    expect: str = "any"
    quick: bool = False
    gpu: bool = False
    protect: list = field(default_factory=list)
    protect_on_failure: list = field(default_factory=list)
    absent_on_failure: list = field(default_factory=list)
    devices: list = field(default_factory=list)
    png: Optional[str] = None
    lit: bool = False
    background: tuple = (0, 0, 0)
    fsize: Optional[int] = None
    setup: Optional[Callable] = None
    cwd: Optional[str] = None
    same_image_as: Optional[str] = None
    # Regular expressions (case-insensitive) over stdout + stderr: what the output must say (a
    # repair, a frame choice, the real cause) and must not say (a wrong cause, usize::MAX).
    says: Optional[str] = None
    never_says: Optional[str] = None
    # The exact exit status due (None: any that `expect` allows), e.g. batch's 3 for failed scans.
    code: Optional[int] = None
    # Paths that must not exist after the run (stale temporary files the run must remove).
    gone: list = field(default_factory=list)
    # Environment variables set for this run (after the probe's own XDG_CACHE_HOME and HOME).
    env: dict = field(default_factory=dict)


class Workspace:
    """The probe's temporary directory and the global options of GPU runs."""

    def __init__(self, root, validation=True):
        self.root = root
        self.validation = validation
        self.cache = self.path("pipeline-cache")
        os.makedirs(self.cache, exist_ok=True)
        self._seq = 0

    def path(self, *parts):
        return os.path.join(self.root, *parts)

    def write(self, name, data):
        path = self.path(name)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path, "wb") as f:
            f.write(data)
        return path

    def fresh(self, stem):
        """A new, unused path in the workspace (for outputs)."""
        self._seq += 1
        return self.path(f"out-{self._seq:03d}-{stem}")

    def gpu(self, *args, cache=None):
        """Arguments of a GPU command: validation, the probe's pipeline cache, then `args`."""
        head = ["--validation"] if self.validation else []
        return head + ["--pipeline-cache", cache or self.cache] + list(args)

    def render(self, source, *extra, out=None, size=RENDER_SIZE, cache=None):
        """(argv, output path) of a small render of `source` (None: the built-in phantom)."""
        out = out or self.fresh("render.png")
        args = ["render"] + ([source] if source else []) + ["-o", out, "--size", size]
        return self.gpu(*args, *extra, cache=cache), out


def info(path, *extra):
    return ["info", path, *extra]


def render_case(ws, cls, name, source, *extra, expect="ok", lit=False, quick=False,
                size=RENDER_SIZE, **kw):
    """A render of `source` whose PNG is inspected when it succeeds."""
    argv, out = ws.render(source, *extra, size=size)
    return Case(cls, name, argv, expect=expect, gpu=True, png=out, lit=lit, quick=quick, **kw)
