"""Markdown table of benches/niivue-side-by-side.sh's raw output (RAW_DIR as its argument).
Medians over rounds; the ratio is morphray's time over NiiVue's, taken round by round (the two ran
back to back in each round, so shared-machine load hits both alike) and then the median."""
import glob
import json
import re
import statistics as st
import sys

raw = sys.argv[1]
nv = [json.loads(line) for line in open(f"{raw}/niivue.jsonl") if line.strip()]
rows = {}
for n in nv:
    if not n.get("ok"):
        continue
    key = (n["name"], n["size"])
    txt = open(f"{raw}/morphray-{n['name']}-{n['size']}-r{n['round']}.txt").read()
    frame = re.search(r"^raymarch: ([\d.]+) ms GPU median", txt, re.M)
    cold = re.search(r"total \(spawn -> fence\)\s+([\d.]+)", txt)
    device = re.search(r"^morphray \S+ on (.+?) \(", txt, re.M)
    if not frame:
        continue
    r = rows.setdefault(key, {"nv": [], "nvc": [], "nvl": [], "m": [], "mc": [], "rf": [], "rc": [],
                              "lean": [], "rl": [],
                              "nvdev": n["renderer"], "mdev": device.group(1) if device else "?"})
    m, mc = float(frame.group(1)), float(cold.group(1)) if cold else None
    r["nv"].append(n["frameMedianMs"]); r["nvc"].append(n["tFirstFrame"])
    r["nvl"].append(n["firstFrameFromLaunchMs"])
    r["m"].append(m)
    r["rf"].append(m / n["frameMedianMs"])
    if mc is not None:
        r["mc"].append(mc); r["rc"].append(mc / n["tFirstFrame"])
    # The same round's frame with LEAN_FLAGS, when the script ran it.
    lean_path = f"{raw}/morphray-lean-{n['name']}-{n['size']}-r{n['round']}.txt"
    lean = re.search(r"^raymarch: ([\d.]+) ms GPU median", open(lean_path).read(), re.M) \
        if glob.glob(lean_path) else None
    if lean:
        r["lean"].append(float(lean.group(1))); r["rl"].append(float(lean.group(1)) / n["frameMedianMs"])

med = st.median
print("| volume | size | renderer | API -> device | frame ms (median) | first frame, cold (s) | morphray / NiiVue (frame; cold) | rounds |")
print("|---|---|---|---|---|---|---|---|")
for (name, size), r in sorted(rows.items()):
    dev = re.sub(r"^ANGLE \([^,]*, ([^(,]+).*", r"\1", r["nvdev"]).strip()
    print(f"| {name} | {size} | NiiVue 1.0.0-rc.9 (defaults) | WebGL2 -> ANGLE -> {dev} | "
          f"{med(r['nv']):.0f} | {med(r['nvc']) / 1000:.2f} ({med(r['nvl']) / 1000:.2f} with browser launch) | 1 | {len(r['nv'])} |")
    mc = f"{med(r['mc']) / 1000:.2f}" if r["mc"] else "-"
    rc = f"{med(r['rc']):.2f}x" if r["rc"] else "-"
    print(f"| {name} | {size} | morphray (step 0.5, shading on) | Vulkan -> {r['mdev']} | "
          f"{med(r['m']):.0f} | {mc} | {med(r['rf']):.2f}x; {rc} | {len(r['m'])} |")
    if r["lean"]:
        print(f"| {name} | {size} | morphray, LEAN_FLAGS | Vulkan -> {r['mdev']} | "
              f"{med(r['lean']):.0f} | - | {med(r['rl']):.2f}x; - | {len(r['lean'])} |")
print()
print("NiiVue renderer string:", ", ".join(sorted({r["nvdev"] for r in rows.values()})))
