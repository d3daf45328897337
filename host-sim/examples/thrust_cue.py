#!/usr/bin/env python3
"""How much of a drone's acceleration the rotor speeds show, with and without the wake
(issue 12; BENCHMARKS.md, "Issue 12, session 20").

For each run folder (a `host-sim bench` run: truth.csv and frames-1.aimraw):

1. Truth rotor speeds (the simulator's): the thrust ratio rho = f^2 / f_hover^2 per rotor
   (hover = median where the drone is still), turned into a horizontal acceleration
   a = g sqrt(rho^2 - 1) from the mean of all rotors, the slowest rotor, or the two slowest;
   smoothed over 0.5 s and compared with the truth's |a_h| (cruise: the phantom acceleration
   the wake makes; accelerating: the level seen against the true one).
2. The frames (`aim frames`, as the tracker reads them): each Peaks frame's amplitude-weighted
   centre and its lowest group, rho - 1 against the truth over the frame's span fitted as
   alpha * |a_h|^2 / (2 g^2) + k |v_h| + c; the residual's sd is the cue's noise per frame.

Usage: thrust_cue.py AIM RUN_DIR...   (AIM: the `aim` binary)
Needs numpy.
"""
import json
import subprocess
import sys

import numpy as np

G = 9.81


def truth(run):
    return np.genfromtxt(run + "/truth.csv", delimiter=",", names=True)


def rotor_speeds(run):
    d = truth(run)
    rotors = [n for n in d.dtype.names if n.startswith("rotor")]
    f = np.vstack([d[n] for n in rotors]).T
    sp = np.hypot(d["vx"], d["vy"])
    ah = np.hypot(d["ax"], d["ay"])
    still = (sp < 0.03) & (ah < 0.05) & (np.abs(d["vz"]) < 0.03)
    rho = f**2 / np.median(f[still] ** 2, axis=0)
    ker = np.ones(50) / 50
    smooth = lambda x: np.convolve(x, ker, "same")
    out = []
    for name, r in [("mean", rho.mean(1)), ("min", rho.min(1)), ("low2", np.sort(rho, 1)[:, :2].mean(1))]:
        r, a_true = smooth(r), smooth(ah)
        a = G * np.sqrt(np.clip(r**2 - 1, 0, None))
        cruise = (a_true < 0.2) & (sp > 0.5)
        acc = a_true > 0.5
        out.append(f"{name}: cruise {a[cruise].mean():.2f} m/s2, accelerating {a[acc].mean():.2f} "
                   f"against {a_true[acc].mean():.2f} m/s2")
    return out


def frames_fit(aim, run):
    d = truth(run)
    text = subprocess.run([aim, "frames", run + "/frames-1.aimraw"], capture_output=True,
                          text=True, check=True).stdout
    rows = []
    for line in text.splitlines():
        j = json.loads(line)
        if j["kind"] != "peaks" or not j["peaks"]:
            continue
        t0 = j["sample_index"] / 48000
        m = (d["t"] >= t0) & (d["t"] < t0 + j["span_samples"] / 48000)
        if m.sum() < 10:
            continue
        w = np.array([10 ** (p["amp_db"] / 10) for p in j["peaks"]])
        hz = np.array([p["hz"] for p in j["peaks"]])
        ah2 = np.mean(d["ax"][m] ** 2 + d["ay"][m] ** 2)
        vh = np.mean(np.hypot(d["vx"][m], d["vy"][m]))
        still = vh < 0.03 and np.sqrt(ah2) < 0.05
        rows.append(((w * hz).sum() / w.sum(), hz.min(), ah2, vh, still))
    r = np.array(rows, dtype=float)
    out = []
    for col, name in [(0, "centre"), (1, "lowest group")]:
        y = (r[:, col] / np.median(r[r[:, 4] > 0, col])) ** 2 - 1
        x = np.column_stack([r[:, 2] / (2 * G * G), r[:, 3], np.ones(len(r))])
        coef = np.linalg.lstsq(x, y, rcond=None)[0]
        resid = y - x @ coef
        out.append(f"{name}: n {len(r)}, alpha {coef[0]:.2f}, wake {100 * coef[1]:.2f} %/(m/s), "
                   f"residual sd {100 * resid.std():.2f} % (1 m/s2 gives {100 / (2 * G * G):.2f} %)")
    return out


def main():
    aim, runs = sys.argv[1], sys.argv[2:]
    for run in runs:
        print(run)
        for line in rotor_speeds(run) + frames_fit(aim, run):
            print("  " + line)


if __name__ == "__main__":
    main()
