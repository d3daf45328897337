#!/usr/bin/env python3
"""Range from the room's echoes (issue 12 lead; BENCHMARKS.md, "Issue 12, session 21").

A single planar array tells the direction well and the range poorly. In a room the same sound
also arrives from the image of the drone in the ceiling (and in each wall), later by a lag
that depends on where along the ray the drone is. With the room's box known (the site file's
`[room]`), each range along a given direction predicts those lags; the whitened
autocorrelation of the microphones' signal (tonal bins notched, so the rotor comb's own
periodicity does not mask the echoes) shows peaks at them.

1. `gen OUT HOST_SIM`: hover recordings at 10 positions (seeded, 4–16 m east, 3.5–13 m north,
   1–3.5 m up) in five rooms: the square scenarios' order-1 room, the noisy hall's room and
   noise, the reverberant halls at RT60 0.8 and 1.5 s (order 3 + tail) and the 9 m warehouse
   aisle at 1.8 s; one ReSpeaker 6-mic array on the floor at (10, 2, 0.05), as the squares.
2. `est OUT [--zenith-bias DEG] [--wall-weight W] [--joint]`: per recording, windows of 8192
   samples (0.171 s at 48 kHz); autocorrelation of the spectrum divided by its running median
   (31 bins), bins more than 4x the median (tones) and outside 0.5–12 kHz removed, averaged
   over the six microphones; then along the TRUE direction (its zenith offset by
   `--zenith-bias`) the range in 0.5–30 m whose predicted first-order image lags (ceiling
   weight 1, each wall `--wall-weight`) have the largest summed autocorrelation. `--joint`
   also searches the zenith within ±12°. `--measured HOST_SIM`: the direction is the median
   DoA of the chip's pipeline on the recording (`host-sim analyze`) instead. Prints, per room, the share of estimates within 10 %
   of the true range for 0.51 s (three windows) and for the whole 2.9 s (17 windows).

This measures whether the cue exists in the simulator's rooms; it is not the tracker.
Needs numpy and scipy.
"""
import csv
import glob
import math
import os
import random
import re
import subprocess
import sys

import numpy as np
import scipy.io.wavfile as wf
from scipy.ndimage import median_filter

C = 343.2
N = 8192

ROOMS = {
    "los": ("size_m = [20.0, 20.0, 5.0]\nabsorption = [0.15, 0.15, 0.15, 0.15, 0.05, 0.4]\n"
            "reflection_order = 1\n", ""),
    "noisy": ("size_m = [20.0, 20.0, 5.0]\nabsorption = [0.05, 0.05, 0.05, 0.05, 0.05, 0.15]\n"
              "reflection_order = 1\n",
              "[diffuse_noise]\nspl_db = 55.0\ndirections = 12\n[[noise]]\n"
              "position = [13.0, 1.0, 0.5]\ncentre_hz = 450.0\nbandwidth_hz = 100.0\n"
              "spl_db = 62.0\ndistance_m = 1.0\n"),
    "rt0.8": ("size_m = [20.0, 20.0, 5.0]\nrt60_s = 0.8\nreflection_order = 3\n", ""),
    "rt1.5": ("size_m = [20.0, 20.0, 5.0]\nrt60_s = 1.5\nreflection_order = 3\n", ""),
    "wh1.8": ("size_m = [40.0, 14.0, 9.0]\nrt60_s = 1.8\nreflection_order = 3\n", ""),
}


def gen(out, host_sim):
    rng = random.Random(2101)
    pos = [(round(rng.uniform(4, 16), 2), round(rng.uniform(3.5, 13), 2),
            round(rng.uniform(1.0, 3.5), 2)) for _ in range(10)]
    os.makedirs(out, exist_ok=True)
    for name, (room, extra) in ROOMS.items():
        for k, p in enumerate(pos):
            y = min(p[1], 12.5) if name == "wh1.8" else p[1]
            text = (f"seed = {100 + k}\nduration_s = 3.0\n[drone]\npreset = \"dji-mini-2\"\n"
                    f"[path]\nkind = \"hover\"\nposition = [{p[0]}, {y}, {p[2]}]\n[room]\n{room}\n"
                    f"{extra}\n[[array]]\nid = 1\ngeometry = \"respeaker-6mic\"\n"
                    f"position = [10.0, 2.0, 0.05]\nyaw_deg = 0.0\n")
            f = f"{out}/{name}-{k}.toml"
            open(f, "w").write(text)
            subprocess.run([host_sim, "simulate", f, "--out", f"{out}/{name}-{k}", "--threads", "1"],
                           check=True, capture_output=True)
        print(name, "simulated", flush=True)


def load(d):
    fs, x = wf.read(d + "/array-1.wav")
    x = x.astype(float)
    site = open(d + "/site.toml").read()
    arr = np.array(eval(re.search(r"^position = (\[.*\])", site, re.M).group(1)))
    box = np.array(eval(re.search(r"size = (\[.*\])", site).group(1)))
    rows = list(csv.DictReader(open(d + "/truth.csv")))
    src = np.array([float(rows[len(rows) // 2][k]) for k in "xyz"])
    return fs, x, arr, box, src


def along(a, fs, arr, box, zenith, azimuth, wall_weight):
    u = np.array([math.sin(zenith) * math.cos(azimuth), math.sin(zenith) * math.sin(azimuth),
                  math.cos(zenith)])
    rs = np.arange(0.5, 30, 0.01)
    src = arr[None, :] + rs[:, None] * u[None, :]
    inside = np.all((src > 0) & (src < box[None, :]), axis=1)
    score = np.zeros(len(rs))
    planes = [(2, box[2], 1.0)]
    if wall_weight > 0:
        planes += [(0, 0.0, wall_weight), (0, box[0], wall_weight), (1, 0.0, wall_weight),
                   (1, box[1], wall_weight)]
    for axis, plane, w in planes:
        img = src.copy()
        img[:, axis] = 2 * plane - src[:, axis]
        lag = (np.linalg.norm(img - arr, axis=1) - rs) / C * fs
        ok = (lag > 0.3e-3 * fs) & (lag < N / 2)
        score += w * np.where(ok, np.interp(lag, np.arange(N), a), 0.0)
    score[~inside] = -1
    i = int(np.argmax(score))
    return rs[i], score[i]


def measured_direction(d, host_sim):
    """The median DoA of the chip's pipeline on the recording (`host-sim analyze`), as a unit
    vector (the array lies flat with yaw 0, so its frame is the world's)."""
    import json
    out = subprocess.run([host_sim, "analyze", "--array", "respeaker6", "--jsonl",
                          d + "/array-1.wav"], check=True, capture_output=True, text=True).stdout
    doa = [json.loads(line) for line in out.splitlines() if '"kind":"doa"' in line]
    az = math.radians(float(np.median([x["azimuth_deg"] for x in doa])))
    zen = math.radians(float(np.median([x["zenith_deg"] for x in doa])))
    return np.array([math.sin(zen) * math.cos(az), math.sin(zen) * math.sin(az), math.cos(zen)])


def estimate(a, fs, arr, box, u, bias_deg, wall_weight, joint):
    zen = math.acos(u[2]) + math.radians(bias_deg)
    az = math.atan2(u[1], u[0])
    best = (-9.0, None)
    for d in (np.arange(-12, 12.01, 0.5) if joint else [0.0]):
        z = zen + math.radians(d)
        if z >= math.pi / 2:
            continue
        r, s = along(a, fs, arr, box, z, az, wall_weight)
        if s > best[0]:
            best = (s, r)
    return best[1]


def est(out, bias, wall_weight, joint, host_sim=None):
    res = {}
    for d in sorted(glob.glob(out + "/*-[0-9]")):
        room = os.path.basename(d).rsplit("-", 1)[0]
        fs, x, arr, box, src = load(d)
        v = src - arr
        r = np.linalg.norm(v)
        f = np.fft.rfftfreq(N, 1 / fs)
        band = (f > 500) & (f < 12000)
        wins = [np.fft.rfft(x[k:k + N] * np.hanning(N)[:, None], axis=0)
                for k in range(0, len(x) - N + 1, N)]
        spec = np.mean([np.mean(np.abs(X) ** 2, axis=1) for X in wins], axis=0)
        med = median_filter(spec, size=31)
        keep = ((spec <= 4 * med) & band).astype(float)
        acs = []
        for X in wins:
            p = np.abs(X) ** 2 / (med[:, None] + 1e-20) * keep[:, None]
            a = np.fft.irfft(np.mean(p, axis=1), n=N)
            acs.append(a / a[0])
        frames = [estimate(np.mean(acs[i:i + 3], axis=0), fs, arr, box, v / r, bias, wall_weight,
                           joint) for i in range(0, len(acs) - 2, 3)]
        whole = estimate(np.mean(acs, axis=0), fs, arr, box, v / r, bias, wall_weight, joint)
        if host_sim:
            m = measured_direction(d, host_sim)
            zen_err = math.degrees(math.acos(m[2]) - math.acos(v[2] / r))
            frames = [estimate(np.mean(acs[i:i + 3], axis=0), fs, arr, box, m, bias, wall_weight,
                               joint) for i in range(0, len(acs) - 2, 3)]
            whole = estimate(np.mean(acs, axis=0), fs, arr, box, m, bias, wall_weight, joint)
            res.setdefault(room + "-zen", []).append(zen_err)
        res.setdefault(room, []).append((r, frames, whole))
    for room, runs in res.items():
        if room.endswith("-zen"):
            print(f"{room[:-4]:6s} measured zenith minus true: median {np.median(runs):+.1f} deg, "
                  f"range {min(runs):+.1f} to {max(runs):+.1f}")
            continue
        rel = np.array([abs(e - r) / r for r, fr, _ in runs for e in fr])
        rel_all = np.array([abs(w - r) / r for r, _, w in runs])
        print(f"{room:6s} zenith bias {bias:+.0f} deg: 0.51 s estimates {len(rel)}: within 10 % "
              f"{100 * np.mean(rel < 0.1):5.1f} %, median |error| {100 * np.median(rel):5.1f} % | "
              f"2.9 s: within 10 % {100 * np.mean(rel_all < 0.1):5.1f} %, median "
              f"{100 * np.median(rel_all):5.1f} % (true ranges {min(r for r, _, _ in runs):.1f}-"
              f"{max(r for r, _, _ in runs):.1f} m)")


def main(argv):
    if len(argv) >= 4 and argv[1] == "gen":
        gen(argv[2], argv[3])
    elif len(argv) >= 3 and argv[1] == "est":
        opts = argv[3:]
        bias = float(opts[opts.index("--zenith-bias") + 1]) if "--zenith-bias" in opts else 0.0
        ww = float(opts[opts.index("--wall-weight") + 1]) if "--wall-weight" in opts else 0.0
        hs = opts[opts.index("--measured") + 1] if "--measured" in opts else None
        est(argv[2], bias, ww, "--joint" in opts, hs)
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main(sys.argv)
