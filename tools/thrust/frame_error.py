#!/usr/bin/env python3
"""How far one `Peaks` frame's thrust measurement (Σ BPF² over the rotors) is from the truth.

For every run directory of a `host-sim bench` (`DIR/runs/<family>/seed-<n>/`, or run
directories given one by one), decodes `frames-1.aimraw` with `aim frames`, folds each frame's
peaks onto the BPF as the tracker does (`aim_tracker::motion::bpf_groups`: the nearest
multiple of the shaft rate of the profile's hover BPF, harmonics 1..4n, kept within the
profile's BPF range, peaks under 0.25 of the strongest dropped, peaks within 2 Hz merged),
forms Σ BPF² by sharing the rotors equally among the groups
(`aim_tracker::dynamics::sum_bpf_squared`) and compares it with the truth's Σ (n·rotor_hz)²
averaged over the frame's span (`truth.csv`). Prints the relative error's sd, median absolute
value and share beyond 2 %, overall and by the number of groups heard, and the same for a
"group hold" (a frame hearing fewer groups than the frame before is completed by that frame's
groups shifted with the ones heard, at most HOLD frames in a row; each heard group within
MATCH of its frequency of a held one).

Profile: the DJI Mini 2's (2 blades, 4 rotors, 0.249 kg, k_v 2.27e-5 N/Hz², 200-500 Hz), the
default suite's drone. Only the standard library; needs `aim` (target/release/aim).

    python3 tools/thrust/frame_error.py BENCH_DIR [--aim target/release/aim] [--hold 4] [--match 0.012]
"""
import argparse
import bisect
import csv
import glob
import json
import os
import statistics
import subprocess

G = 9.80665
BLADES, ROTORS = 2, 4
HOVER_BPF = BLADES * (0.249 * G / (ROTORS * 2.27e-5)) ** 0.5
BPF_MIN, BPF_MAX = 200.0, 500.0
MIN_RELATIVE, MIN_SEPARATION = 0.25, 2.0
RATE = 48000.0


def fold(peaks):
    """The frame's BPF groups (Hz), as the tracker's bpf_groups forms them."""
    shaft = HOVER_BPF / BLADES
    inside = []
    for p in peaks:
        hz, amp = p["hz"], 10 ** (p["amp_db"] / 20)
        h = round(hz / shaft)
        if 1 <= h <= 4 * BLADES and BPF_MIN <= hz * BLADES / h <= BPF_MAX:
            inside.append((hz * BLADES / h, amp))
    if not inside:
        return []
    strongest = max(a for _, a in inside)
    inside = sorted(x for x in inside if x[1] >= MIN_RELATIVE * strongest)
    groups = []
    for f, a in inside:
        if groups and f - groups[-1][0] < MIN_SEPARATION:
            g, ga = groups[-1]
            groups[-1] = ((g * ga + f * a) / (ga + a), ga + a)
        else:
            groups.append((f, a))
    return [f for f, _ in groups]


def run_frames(run, aim):
    """(t_centre, groups, true Σ BPF²) per Peaks frame of one run."""
    rows = list(csv.DictReader(open(os.path.join(run, "truth.csv"))))
    rotor_keys = [k for k in rows[0] if k.startswith("rotor")]
    ts = [float(r["t"]) for r in rows]
    true_sum = [sum((BLADES * float(r[k])) ** 2 for k in rotor_keys) for r in rows]
    out = subprocess.run(
        [aim, "frames", os.path.join(run, "frames-1.aimraw")],
        capture_output=True, text=True, check=True,
    ).stdout
    frames = []
    for line in out.splitlines():
        j = json.loads(line)
        if j["kind"] != "peaks":
            continue
        t0 = j["t"]
        t1 = t0 + j["span_samples"] / RATE
        i0, i1 = bisect.bisect_left(ts, t0), bisect.bisect_left(ts, t1)
        if i1 <= i0:
            continue
        truth = sum(true_sum[i0:i1]) / (i1 - i0)
        frames.append(((t0 + t1) / 2, fold(j["peaks"]) if j["peaks"] else [], truth))
    return frames


def errors(frames, hold, match):
    """Relative errors of Σ BPF² with the group hold (hold = 0: the groups heard only)."""
    out = []
    held, held_t, in_row = [], float("-inf"), 0
    for t, groups, truth in frames:
        if not groups:
            held = []
            continue
        used = groups
        nxt = 0 < t - held_t <= 0.4
        completed = False
        if nxt and len(groups) < len(held) and in_row < hold:
            nearest = [min(held, key=lambda h: abs(h - f)) for f in groups]
            if all(abs(f - h) < match * f for f, h in zip(groups, nearest)):
                shift = statistics.mean(f - h for f, h in zip(groups, nearest))
                used = [h + shift for h in held]
                in_row += 1
                held_t = t
                completed = True
        if not completed:
            held, held_t, in_row = groups, t, 0
        measured = sum(f * f for f in used) * ROTORS / len(used)
        out.append((len(groups), measured / truth - 1))
    return out


def describe(label, errs):
    if len(errs) < 2:
        return
    absolute = [abs(e) for e in errs]
    print(
        f"{label:<22} frames {len(errs):6d}  sd {100 * statistics.pstdev(errs):.2f} %"
        f"  median |e| {100 * statistics.median(absolute):.2f} %"
        f"  beyond 2 % {100 * sum(a > 0.02 for a in absolute) / len(absolute):.1f} %"
    )


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="+", help="bench output directories or run directories")
    ap.add_argument("--aim", default="target/release/aim")
    ap.add_argument("--hold", type=int, default=4, help="most completed frames in a row")
    ap.add_argument("--match", type=float, default=0.012, help="match tolerance, fraction")
    a = ap.parse_args()
    runs = []
    for d in a.dirs:
        found = sorted(glob.glob(os.path.join(d, "runs", "*", "seed-*")))
        runs += found if found else [d]
    runs = [r for r in runs if os.path.exists(os.path.join(r, "frames-1.aimraw"))]
    if not runs:
        raise SystemExit("no run directory with frames-1.aimraw and truth.csv found")
    frames = [run_frames(r, a.aim) for r in runs]
    print(f"{len(runs)} runs")
    heard = [e for f in frames for e in errors(f, 0, a.match)]
    describe("groups heard", [e for _, e in heard])
    for n in (1, 2, 3, 4):
        describe(f"  {n} group(s)", [e for g, e in heard if g == n])
    held = [e for f in frames for e in errors(f, a.hold, a.match)]
    describe(f"hold {a.hold}, match {a.match}", [e for _, e in held])


if __name__ == "__main__":
    main()
