#!/usr/bin/env python3
"""Surface metrics of a rendered PNG (issue 34 item 1), and colour separability of tissue colours.

    python tools/figures/surface_metrics.py IMAGE.png [IMAGE.png ...]
    python tools/figures/surface_metrics.py --colours '#rrggbb' '#rrggbb' '#rrggbb'   # CSF GM WM

Per image (luminance Y = 0.2126 R + 0.7152 G + 0.0722 B of sRGB values in 0..1, background dark):
- edge_px: width of the silhouette edge, the 10-90 % rise of luminance along rows, where the
  plateau is the 90th percentile of the first 16 pixels inside the silhouette; median over the
  left and right edges of the rows in the middle 60 % of the silhouette's height. Smaller = sharper.
- rms: RMS contrast (std / mean of Y) inside the silhouette eroded by 8 px (no edge in it).
- local: mean of local std / local mean of Y in 7x7 windows inside the same eroded silhouette:
  how strongly the folds (sulci against gyri) stand out. Larger = more sulcal contrast.
Colours: pairwise CIELAB distance (CIE76 delta E) of the three colours with normal vision and
after the Machado et al. 2009 simulation (severity 1.0) of protanopia, deuteranopia, tritanopia.
Needs numpy and pillow (e.g. the /tmp/proto venv).
"""
import sys

import numpy as np
from PIL import Image

MACHADO = {
    "protan": [[0.152286, 1.052583, -0.204868], [0.114503, 0.786281, 0.099216],
               [-0.003882, -0.048116, 1.051998]],
    "deutan": [[0.367322, 0.860646, -0.227968], [0.280085, 0.672501, 0.047413],
               [-0.011820, 0.042940, 0.968881]],
    "tritan": [[1.255528, -0.076749, -0.178779], [-0.078411, 0.930809, 0.147602],
               [0.004733, 0.691367, 0.303900]],
}


def luminance(path):
    rgb = np.asarray(Image.open(path).convert("RGB"), dtype=np.float64) / 255.0
    return rgb @ np.array([0.2126, 0.7152, 0.0722])


def erode(mask, r):
    out = mask.copy()
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            out &= np.roll(np.roll(mask, dy, 0), dx, 1)
    return out


def edge_width(row):
    """10-90 % rise at the start of `row` (silhouette entered from the left), or None."""
    idx = np.nonzero(row > 0.04)[0]
    if len(idx) < 20:
        return None
    start = max(idx[0] - 4, 0)
    plateau = np.percentile(row[idx[0]:idx[0] + 16], 90)
    seg = row[start:idx[0] + 16]
    lo = np.argmax(seg >= 0.1 * plateau)
    hi = np.argmax(seg >= 0.9 * plateau)
    # sub-pixel: linear interpolation at both crossings
    def cross(i, level):
        if i == 0:
            return 0.0
        a, b = seg[i - 1], seg[i]
        return i - 1 + (level - a) / max(b - a, 1e-9)
    return cross(hi, 0.9 * plateau) - cross(lo, 0.1 * plateau)


def metrics(path):
    y = luminance(path)
    mask = y > 0.04
    rows = np.nonzero(mask.any(1))[0]
    top, bottom = rows[0], rows[-1]
    h = bottom - top
    widths = []
    for r in range(top + int(0.2 * h), bottom - int(0.2 * h)):
        for row in (y[r], y[r, ::-1]):
            w = edge_width(row)
            if w is not None:
                widths.append(w)
    inner = erode(mask, 8)
    vals = y[inner]
    rms = vals.std() / vals.mean()
    k = 3
    pad = np.pad(y, k, mode="edge")
    win = np.lib.stride_tricks.sliding_window_view(pad, (2 * k + 1, 2 * k + 1))
    lmean = win.mean(axis=(-1, -2))
    lstd = win.std(axis=(-1, -2))
    local = (lstd[inner] / np.maximum(lmean[inner], 1e-6)).mean()
    return np.median(widths), rms, local, inner.sum()


def srgb_to_lin(c):
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def lin_to_lab(rgb):
    m = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]])
    xyz = m @ np.clip(rgb, 0, 1) / np.array([0.95047, 1.0, 1.08883])
    f = np.where(xyz > 0.008856, np.cbrt(xyz), 7.787 * xyz + 16 / 116)
    return np.array([116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])])


def colours(hexes):
    lin = [srgb_to_lin([int(h.lstrip("#")[i:i + 2], 16) / 255 for i in (0, 2, 4)]) for h in hexes]
    names = ["csf-gm", "csf-wm", "gm-wm"]
    pairs = [(0, 1), (0, 2), (1, 2)]
    for vision, mat in [("normal", np.eye(3))] + [(k, np.array(v)) for k, v in MACHADO.items()]:
        labs = [lin_to_lab(mat @ c) for c in lin]
        d = [np.linalg.norm(labs[a] - labs[b]) for a, b in pairs]
        print(f"{vision:7s} " + "  ".join(f"{n} dE {v:5.1f}" for n, v in zip(names, d)))


def main(argv):
    if argv and argv[0] == "--colours":
        colours(argv[1:4])
        return
    print(f"{'image':40s} {'edge_px':>8s} {'rms':>6s} {'local':>6s} {'px':>6s}")
    for path in argv:
        e, r, l, n = metrics(path)
        print(f"{path:40s} {e:8.2f} {r:6.3f} {l:6.3f} {n:6d}")


if __name__ == "__main__":
    main(sys.argv[1:])
