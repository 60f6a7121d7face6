"""Medians of the lighting benchmark's rounds (benches/lighting-rounds.sh output): per volume
and look, the median raymarch GPU time and its ratio to the headlight's.
Usage: python3 benches/lighting-report.py LIGHTING.txt"""
import re
import statistics
import sys
from collections import defaultdict

times = defaultdict(list)
for line in open(sys.argv[1]):
    m = re.match(r"(\S+) (\S+) r\d+: raymarch: ([\d.]+) ms GPU", line)
    if m:
        times[(m.group(1), m.group(2))].append(float(m.group(3)))
for volume in sorted({v for v, _ in times}):
    base = statistics.median(times[(volume, "headlight")])
    for (v, look), ts in times.items():
        if v == volume:
            med = statistics.median(ts)
            print(f"{volume:24s} {look:15s} {med:9.3f} ms  x{med / base:.3f}  ({len(ts)} rounds)")
