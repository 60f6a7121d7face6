#!/usr/bin/env python3
"""Surface metrics of tools/figures/side-by-side.sh's pictures, and which renderer is sharper.

    python tools/figures/side_by_side_metrics.py PICTURES_DIR VOLUME [VOLUME ...]

Reads PICTURES_DIR/VOLUME-{morphray-default,morphray-best,morphray-matcap,niivue}.png. Prints one row per
picture: surface_metrics.py's edge_px, rms, local, px; the silhouette's width in pixels and
edge_%w = 100 * edge_px / width (the two renderers frame a volume differently: morphray's
perspective fit against NiiVue's orthographic one); local3 = `local` on the luminance smoothed by
a 3x3 mean first, so pixel-sized speckle (NiiVue's ray dither, morphray's jitter) counts less than
folds several pixels wide. Then one comparison line per volume: edge width (smaller = sharper)
and sulcal local contrast (larger = more) of morphray default and best against NiiVue. `local`
needs a silhouette wider than 16 px (it is NaN for thin vessels alone).
"""
import os
import sys
import warnings

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from surface_metrics import erode, luminance, metrics  # noqa: E402

COLUMNS = ["morphray-default", "morphray-best", "morphray-matcap", "niivue"]


def silhouette_width(path):
    cols = np.nonzero((luminance(path) > 0.04).any(0))[0]
    return int(cols[-1] - cols[0] + 1) if len(cols) else 0


def box(y, k):
    """Mean of y over (2k+1)^2 windows, edges padded by repetition."""
    win = np.lib.stride_tricks.sliding_window_view(np.pad(y, k, mode="edge"), (2 * k + 1,) * 2)
    return win.mean(axis=(-1, -2))


def local_smoothed(path):
    """surface_metrics' `local` (7x7 std / mean inside the 8-px-eroded silhouette) after a 3x3 mean."""
    y = luminance(path)
    inner = erode(y > 0.04, 8)
    if not inner.any():
        return float("nan")
    ys = box(y, 1)
    win = np.lib.stride_tricks.sliding_window_view(np.pad(ys, 3, mode="edge"), (7, 7))
    return float((win.std(axis=(-1, -2))[inner] / np.maximum(win.mean(axis=(-1, -2))[inner], 1e-6)).mean())


def verdict_edge(m, n):
    if np.isnan(m) or np.isnan(n):
        return "n/a"
    return "morphray sharper" if m < n else ("NiiVue sharper" if n < m else "equal")


def verdict_local(m, n):
    if np.isnan(m) or np.isnan(n):
        return "n/a"
    return "morphray higher" if m > n else ("NiiVue higher" if n > m else "equal")


def main(argv):
    if len(argv) < 2:
        sys.exit(__doc__)
    pics, volumes = argv[0], argv[1:]
    print()
    print(f"{'picture':28s} {'edge_px':>8s} {'rms':>6s} {'local':>6s} {'px':>7s} {'width_px':>8s} {'edge_%w':>7s} {'local3':>6s}")
    rows = {}
    for v in volumes:
        for c in COLUMNS:
            path = os.path.join(pics, f"{v}-{c}.png")
            with warnings.catch_warnings():  # empty silhouette interior: NaN, said in the doc
                warnings.simplefilter("ignore", RuntimeWarning)
                e, r, loc, n = metrics(path)
            w = silhouette_width(path)
            loc3 = local_smoothed(path)
            rows[v, c] = (e, loc, loc3)
            print(f"{v + '-' + c:28s} {e:8.2f} {r:6.3f} {loc:6.3f} {n:7d} {w:8d} "
                  f"{100 * e / max(w, 1):7.2f} {loc3:6.3f}")
    print()
    print("edge_px: silhouette 10-90 % rise, smaller = sharper; local, local3: sulcal local "
          "contrast, larger = more")
    for v in volumes:
        ne, nl, nl3 = rows[v, "niivue"]
        for c in COLUMNS[:-1]:
            e, loc, loc3 = rows[v, c]
            name = c.replace("morphray-", "morphray ")
            print(f"{v}, {name} vs NiiVue: edge {e:.2f} vs {ne:.2f} px ({verdict_edge(e, ne)}); "
                  f"local {loc:.3f} vs {nl:.3f} ({verdict_local(loc, nl)}); "
                  f"local3 {loc3:.3f} vs {nl3:.3f} ({verdict_local(loc3, nl3)})")


if __name__ == "__main__":
    main(sys.argv[1:])
