#!/usr/bin/env python3
"""The side-by-side table and the scaling plot of one `benches/device-scaling.sh` run.

Usage: python3 benches/scaling_report.py RUN_DIR
Reads RUN_DIR/bench-*.json (morphray) and RUN_DIR/peers-*/peers.json (VTK, pygfx; a volume's
peers may come from several calls, peers-NAME-nii-gz*/, merged), prints a
Markdown table, and writes RUN_DIR/scaling.svg: voxels (log) against morphray's and the peers'
frame time and time to first pixel (log), drawn by hand (no plotting library needed).
"""
import glob
import json
import math
import os
import sys

run = sys.argv[1]
ORDER = ["phantom-128x128x96", "phantom-256x256x192", "mni152", "phantom-384x384x288",
         "phantom-512x512x512"]


def load(path):
    with open(path) as f:
        return json.load(f)


# The volumes this run has (the lavapipe run, benches/lavapipe-scaling.sh, has fewer).
ORDER = [n for n in ORDER if os.path.exists(os.path.join(run, f"bench-{n}-nii-gz.json"))]
first = load(os.path.join(run, f"bench-{ORDER[0]}-nii-gz.json"))
DEVICE = "H100" if "H100" in first["device"] else first["device"].split(" (")[0]
SIZE = "x".join(str(v) for v in first["image"]) if isinstance(first["image"], list) else str(first["image"])
rows = []
for name in ORDER:
    bench = load(os.path.join(run, f"bench-{name}-nii-gz.json"))
    peers = {p["peer"]: p
             for path in sorted(glob.glob(os.path.join(run, f"peers-{name}-nii-gz*", "peers.json")))
             for p in load(path)["summary"]}
    dims = bench["dims"]
    voxels = dims[0] * dims[1] * dims[2]
    rm = bench["raymarch"]
    row = {
        "name": name, "dims": dims, "voxels": voxels,
        "gpu": rm["gpu_ms"]["median"], "wall": rm["cpu_wall_ms"]["median"],
        "cold": bench["ttfp"]["cold"]["total_ms"]["median"],
        "warm": bench["ttfp"]["warm"]["total_ms"]["median"],
        "vtk": peers["vtk-composite"]["frame_ms"]["median"],
        "vtk_plain": peers["vtk-composite-plain"]["frame_ms"]["median"],
        "vtk_ttfp": peers["vtk-composite"]["ttfp_ms"]["median"],
        "pygfx": peers["pygfx-mip"]["frame_ms"]["median"],
        "pygfx_ttfp": peers["pygfx-mip"]["ttfp_ms"]["median"],
    }
    nii = os.path.join(run, f"bench-{name}-nii.json")
    if os.path.exists(nii):
        b = load(nii)
        row["nii_cold"] = b["ttfp"]["cold"]["total_ms"]["median"]
        row["nii_warm"] = b["ttfp"]["warm"]["total_ms"]["median"]
    rows.append(row)

print("| volume (voxels) | morphray GPU / wall ms | VTK composite shaded / plain ms | frame ratio (VTK shaded / morphray wall) | first pixel morphray cold / warm ms | VTK ms | ratio (VTK / morphray cold) | pygfx MIP frame / first pixel ms |")
print("| --- | --- | --- | --- | --- | --- | --- | --- |")
for r in rows:
    d = "x".join(map(str, r["dims"]))
    extra = ""
    if "nii_cold" in r:
        extra = f"; .nii {r['nii_cold']:.0f} / {r['nii_warm']:.0f}"
    print(f"| {r['name']} {d} ({r['voxels'] / 1e6:.1f} M) | {r['gpu']:.3f} / {r['wall']:.3f} | "
          f"{r['vtk']:.1f} / {r['vtk_plain']:.1f} | {r['vtk'] / r['wall']:.0f}x | "
          f"{r['cold']:.0f} / {r['warm']:.0f}{extra} | {r['vtk_ttfp']:.0f} | {r['vtk_ttfp'] / r['cold']:.1f}x | "
          f"{r['pygfx']:.1f} / {r['pygfx_ttfp']:.0f} |")

# The plot: two panels side by side, log-log, one line per series.
W, H, PAD = 900, 380, 60
panel_w = (W - 3 * PAD) / 2
series = [
    ("frame", [("morphray (GPU, curvature + shading)", "gpu", "#c0392b"),
               ("VTK composite + shading", "vtk", "#2471a3"),
               ("pygfx MIP", "pygfx", "#27ae60")]),
    ("first pixel", [("morphray cold", "cold", "#c0392b"),
                     ("VTK composite", "vtk_ttfp", "#2471a3"),
                     ("pygfx MIP", "pygfx_ttfp", "#27ae60")]),
]
xs = [r["voxels"] for r in rows]
x0, x1 = math.log10(min(xs) / 1.5), math.log10(max(xs) * 1.5)
out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" font-size="11">',
       f'<rect width="{W}" height="{H}" fill="white"/>']
for p, (title, lines) in enumerate(series):
    left = PAD + p * (panel_w + PAD)
    top, bottom = 30, H - 50
    values = [r[key] for _, key, _ in lines for r in rows]
    y0, y1 = math.floor(math.log10(min(values))), math.ceil(math.log10(max(values)))
    px = lambda v: left + (math.log10(v) - x0) / (x1 - x0) * panel_w
    py = lambda v: bottom - (math.log10(v) - y0) / (y1 - y0) * (bottom - top)
    out.append(f'<text x="{left + panel_w / 2}" y="18" text-anchor="middle" font-size="13">{title} (ms, {DEVICE}, {SIZE})</text>')
    out.append(f'<rect x="{left}" y="{top}" width="{panel_w}" height="{bottom - top}" fill="none" stroke="#888"/>')
    for e in range(y0, y1 + 1):
        y = py(10 ** e)
        out.append(f'<line x1="{left}" x2="{left + panel_w}" y1="{y}" y2="{y}" stroke="#ddd"/>')
        out.append(f'<text x="{left - 5}" y="{y + 4}" text-anchor="end">{10 ** e:g}</text>')
    for e in range(math.ceil(x0), math.floor(x1) + 1):
        x = px(10 ** e)
        out.append(f'<line x1="{x}" x2="{x}" y1="{top}" y2="{bottom}" stroke="#ddd"/>')
        out.append(f'<text x="{x}" y="{bottom + 15}" text-anchor="middle">{10 ** e / 1e6:g} M</text>')
    out.append(f'<text x="{left + panel_w / 2}" y="{bottom + 32}" text-anchor="middle">voxels</text>')
    for i, (label, key, colour) in enumerate(lines):
        pts = " ".join(f"{px(r['voxels']):.1f},{py(r[key]):.1f}" for r in rows)
        out.append(f'<polyline points="{pts}" fill="none" stroke="{colour}" stroke-width="2"/>')
        for r in rows:
            out.append(f'<circle cx="{px(r["voxels"]):.1f}" cy="{py(r[key]):.1f}" r="3" fill="{colour}"/>')
        out.append(f'<text x="{left + 8}" y="{top + 15 + 14 * i}" fill="{colour}">{label}</text>')
out.append("</svg>")
with open(os.path.join(run, "scaling.svg"), "w") as f:
    f.write("\n".join(out) + "\n")
