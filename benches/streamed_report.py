#!/usr/bin/env python3
"""Markdown table of a `benches/device-streamed.sh` run: per variant and round, the first-pixel
phases that the streamed load changes (read, inflate, upload, minmax = the submission holding a
staged copy) and the totals, cold and warm (medians of 5 fresh processes each).

    python3 benches/streamed_report.py benches/results/h100-2026-11-24-streamed
"""
import json
import pathlib
import sys

PHASES = ["read", "inflate", "upload", "minmax", "pipelines"]


def median(side, name):
    value = side["phases"].get(name)
    return value["median"] if value else float("nan")


def row(path):
    report = json.loads(path.read_text())
    ttfp = report.get("ttfp")
    if not ttfp:
        return None
    cold, warm = ttfp["cold"], ttfp["warm"]
    load = cold.get("load_path", {})
    cells = [
        path.stem,
        str(load.get("io_threads", "?")),
        str(load.get("gzip_members", "?")),
        load.get("upload", "?"),
    ]
    cells += [f"{median(cold, p):.1f}" for p in PHASES]
    cells += [f"{cold['total_ms']['median']:.0f}", f"{warm['total_ms']['median']:.0f}"]
    return cells


def main():
    folder = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else ".")
    header = ["run", "threads", "gz members", "upload"] + [f"{p} ms" for p in PHASES]
    header += ["first pixel cold ms", "warm ms"]
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    for path in sorted(folder.glob("*.json")):
        cells = row(path)
        if cells:
            print("| " + " | ".join(cells) + " |")
    for viewer in sorted(folder.glob("viewer-*.txt")):
        times = [
            line.split(": ")[-1]
            for line in viewer.read_text().splitlines()
            if line.startswith("time to first pixel of ")
        ]
        print(f"\n{viewer.stem}: first pixel of each opened file: {', '.join(times)}")


if __name__ == "__main__":
    main()
