#!/usr/bin/env python3
"""Zenith error of the on-chip pipeline against the simulator's truth.

usage: zenith_bias.py SIM_DIR ANALYZE_JSONL [ARRAY_ID] [MIN_ZENITH_DEG]

SIM_DIR is the output of `host-sim simulate` (truth.csv, site.toml); ANALYZE_JSONL is the
output of `host-sim analyze SIM_DIR/array-<id>.wav --array ... --jsonl`. Prints the median,
p10 and p90 of (measured − true) zenith in degrees over the Doa outputs whose true zenith is
above MIN_ZENITH_DEG (default 60°, the grazing angles that dominate range error).
"""
import csv
import json
import math
import sys
import tomllib


def main():
    sim_dir, jsonl = sys.argv[1], sys.argv[2]
    array_id = int(sys.argv[3]) if len(sys.argv) > 3 else 1
    min_zenith = float(sys.argv[4]) if len(sys.argv) > 4 else 60.0
    with open(f"{sim_dir}/site.toml", "rb") as f:
        site = tomllib.load(f)
    array = next(a for a in site["array"] if a["id"] == array_id)
    ax, ay, az = array["position"]
    truth = list(csv.DictReader(open(f"{sim_dir}/truth.csv")))
    dt = float(truth[1]["t"]) - float(truth[0]["t"])
    errors = []
    for line in open(jsonl):
        out = json.loads(line)
        if out["kind"] != "doa":
            continue
        t = out["t"] + out.get("span_s", 0.0) / 2  # middle of the span the output describes
        row = truth[min(int(round(t / dt)), len(truth) - 1)]
        dx, dy, dz = float(row["x"]) - ax, float(row["y"]) - ay, float(row["z"]) - az
        zenith = math.degrees(math.atan2(math.hypot(dx, dy), dz))
        if zenith > min_zenith:
            errors.append(out["zenith_deg"] - zenith)
    if not errors:
        sys.exit("no Doa output above the zenith threshold")
    errors.sort()
    pick = lambda q: errors[min(int(q * len(errors)), len(errors) - 1)]
    print(f"n {len(errors)} zenith error (deg, true zenith > {min_zenith:g}): "
          f"median {pick(0.5):+.2f} p10 {pick(0.1):+.2f} p90 {pick(0.9):+.2f}")


if __name__ == "__main__":
    main()
