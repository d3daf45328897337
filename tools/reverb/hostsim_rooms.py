#!/usr/bin/env python3
"""host-sim's rooms against pyroomacoustics on the quantity the tracker feels: the zenith bias.

For every `all` case of an image_split.py directory (a static drone-like source in hall
20 x 15 x 5 m, every surface at Sabine's alpha), writes a host-sim scenario with the same
geometry and absorption (a DJI-Mini-2-like drone hovering at the source position, 3 s, the
same array 0.8 m up at (6, 7)), simulates it with host-sim's room model at the given image
orders (`3t`: images to order 3 plus the statistical late tail, as the issue-18 halls; `12`:
exact images to order 12, no tail), runs `host-sim analyze` (the on-chip pipeline) on
host-sim's and on pyroomacoustics' WAV, and prints the median signed zenith error of the DoA
frames after the first 0.2 s for each. The sources differ (host-sim's rotors against
make_rooms.py's synthetic comb); the geometry, the absorption and the pipeline are the same.

    python3 tools/reverb/hostsim_rooms.py --dir /tmp/image-split --host-sim target/release/host-sim --orders 3t
"""
import argparse
import json
import os
import subprocess

import numpy as np

GEOMETRY = {"respeaker6": "respeaker-6mic", "respeaker4": "respeaker-4mic"}


def zenith_bias(host_sim, wav, array, truth_deg):
    out = subprocess.run([host_sim, "analyze", "--array", array, "--jsonl", wav],
                         check=True, capture_output=True, text=True).stdout
    z = [f["zenith_deg"] for f in map(json.loads, out.splitlines())
         if f.get("kind") == "doa" and f["t"] >= 0.2]
    return float(np.median(z)) - truth_deg


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dir", required=True)
    ap.add_argument("--host-sim", required=True)
    ap.add_argument("--orders", default="3t")
    a = ap.parse_args()
    orders = a.orders.split(",")
    cases = [json.loads(line) for line in open(os.path.join(a.dir, "cases.jsonl"))]
    cases = [c for c in cases if c.get("var") == "all"]
    work = os.path.join(a.dir, "host-sim")
    os.makedirs(work, exist_ok=True)
    print("| case | true zenith | pyroomacoustics | " + " | ".join(f"host-sim {o}" for o in orders) + " |")
    print("|---|---|---|" + "---|" * len(orders))
    diffs = {o: [] for o in orders}
    for c in cases:
        az, zen, r = np.radians(c["azimuth_deg"]), np.radians(c["zenith_deg"]), c["range_m"]
        pos = [6 + r * np.sin(zen) * np.cos(az), 7 + r * np.sin(zen) * np.sin(az),
               0.8 + r * np.cos(zen)]
        pra_bias = zenith_bias(a.host_sim, os.path.join(a.dir, c["name"] + ".wav"), c["array"],
                               c["zenith_deg"])
        cells = []
        for o in orders:
            order, tail = (int(o[:-1]), "true") if o.endswith("t") else (int(o), "false")
            name = f"{c['name']}-o{o}"
            toml = os.path.join(work, name + ".toml")
            with open(toml, "w") as f:
                f.write(f'description = "static source as {c["name"]}"\nseed = 7\nduration_s = 3.0\n'
                        f'[drone]\npreset = "dji-mini-2"\n[path]\nkind = "hover"\n'
                        f'position = [{pos[0]:.4f}, {pos[1]:.4f}, {pos[2]:.4f}]\n'
                        f'[room]\nsize_m = {list(map(float, c["room_dim"]))}\n'
                        f'absorption = {c["absorption"]}\nreflection_order = {order}\n'
                        f'late_tail = {tail}\n[[array]]\nid = 1\n'
                        f'geometry = "{GEOMETRY[c["array"]]}"\nposition = [6.0, 7.0, 0.8]\n')
            out = os.path.join(work, name)
            subprocess.run([a.host_sim, "simulate", toml, "--out", out, "--threads", "1"],
                           check=True, capture_output=True)
            b = zenith_bias(a.host_sim, os.path.join(out, "array-1.wav"), c["array"], c["zenith_deg"])
            diffs[o].append(b - pra_bias)
            cells.append(f"{b:+.1f}°")
        print(f"| {c['name']} | {c['zenith_deg']:.1f}° | {pra_bias:+.1f}° | " + " | ".join(cells) + " |",
              flush=True)
    for o in orders:
        d = np.array(diffs[o])
        print(f"host-sim {o} minus pyroomacoustics: median {np.median(d):+.1f}°, "
              f"median |.| {np.median(np.abs(d)):.1f}°, max |.| {np.max(np.abs(d)):.1f}°")


if __name__ == "__main__":
    main()
