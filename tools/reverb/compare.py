#!/usr/bin/env python3
"""AIM's on-chip DoA against pyroomacoustics' SRP-PHAT on the recordings of make_rooms.py.

For every case in DIR/cases.jsonl: runs `host-sim analyze WAV --array ARRAY --jsonl` (the
on-chip pipeline, aim-dsp, on 24-bit TDM words) and pyroomacoustics' SRP-PHAT (far field, 3-D
grid over azimuth and zenith 0-90 deg at --grid-deg, 1024-point STFT with a Hann window and
hop 1024, 200-6000 Hz) on the same WAV, in the same windows: one estimate per AIM DoA frame,
over the frame's `span_s` (8 blocks of 1024 samples, 0.171 s). The first 0.2 s (the direct
sound and the room filling up) are skipped for both. Prints per-condition (array, RT60) median
and p90 absolute azimuth and zenith error and the median signed zenith error (bias), and
writes every frame to DIR/frames.jsonl.

With --survey SDIR (the surveys of survey.py, one per array, room and RT60, each with the site
`aim calibrate` wrote from the chip's frames) two more rows per condition: AIM+CAL, the first
host-sim's zenith corrected by its room's calibrated site as the tracker corrects it
(`zenith_correction_deg`: linear between points, the end points' bias beyond, the result kept
within 0-90 deg), and SRP+CAL, SRP-PHAT's zenith corrected by a calibration fitted the same way
on SRP-PHAT's own estimates of the same survey (5 deg bins of measured zenith, the median of
measured - true in each bin of at least 20 frames whose median absolute deviation is at most
3 deg: `aim calibrate`'s defaults), so that the two methods get the same help.

    python3 tools/reverb/compare.py --dir /tmp/reverb --host-sim target/release/host-sim
    python3 tools/reverb/compare.py --dir /tmp/reverb --survey /tmp/reverb-survey
"""
import argparse
import hashlib
import json
import os
import subprocess
from collections import defaultdict

import numpy as np
import pyroomacoustics as pra

FS = 48_000
BAND_HZ = (200.0, 6000.0)
SKIP_S = 0.2
ARRAYS = {
    "respeaker6": [(0.0463 * np.cos(2 * np.pi * i / 6), 0.0463 * np.sin(2 * np.pi * i / 6))
                   for i in range(6)],
    "respeaker4": [(0.065 / np.sqrt(2) * np.cos(np.pi / 4 + np.pi / 2 * i),
                    0.065 / np.sqrt(2) * np.sin(np.pi / 4 + np.pi / 2 * i)) for i in range(4)],
}


def read_wav(path):
    """Float32 WAV -> (channels, samples)."""
    with open(path, "rb") as f:
        raw = f.read()
    ch = int.from_bytes(raw[22:24], "little")
    i = raw.index(b"data")
    n = int.from_bytes(raw[i + 4:i + 8], "little")
    return np.frombuffer(raw[i + 8:i + 8 + n], dtype="<f4").reshape(-1, ch).T.astype(np.float64)


def aim_frames(host_sim, wav, array):
    out = subprocess.run([host_sim, "analyze", wav, "--array", array, "--jsonl"],
                         check=True, capture_output=True, text=True).stdout
    return [o for o in map(json.loads, out.splitlines()) if o["kind"] == "doa"]


class Srp:
    """SRP-PHAT, far field, on a fine grid: per pair the PHAT cross spectrum summed over the
    window's 1024-sample Hann frames, band 200-6000 Hz, turned into a correlation by a 32x
    zero-padded inverse FFT; the power of a direction is the sum over pairs of the correlation
    at the direction's pair delay (linear interpolation). Exhaustive over azimuth and zenith
    0-90 deg at `grid_deg`. `--check-pra` compares it with pyroomacoustics' own SRP."""

    def __init__(self, array, grid_deg):
        self.p = np.array(ARRAYS[array])
        m = len(self.p)
        self.pairs = [(i, j) for i in range(m) for j in range(i + 1, m)]
        az = np.radians(np.arange(-180, 180, grid_deg))
        zen = np.radians(np.arange(0, 90 + 1e-9, grid_deg))
        A, Z = np.meshgrid(az, zen, indexing="ij")
        self.az, self.zen = A.ravel(), Z.ravel()
        u = np.stack([np.sin(self.zen) * np.cos(self.az), np.sin(self.zen) * np.sin(self.az)])
        # Arrival at mic j minus arrival at mic i, samples: (p_i - p_j) . u / c * fs.
        self.tau = np.stack([(self.p[i] - self.p[j]) @ u for i, j in self.pairs]) / 343.0 * FS
        self.up = 32
        self.nfft = 1024

    def locate(self, x):
        frames = (x.shape[1] - self.nfft) // self.nfft + 1
        win = np.hanning(self.nfft)
        X = np.stack([np.fft.rfft(x[:, k * self.nfft:(k + 1) * self.nfft] * win, axis=1)
                      for k in range(frames)])  # (frames, mics, bins)
        f = np.fft.rfftfreq(self.nfft, 1 / FS)
        band = (f >= BAND_HZ[0]) & (f <= BAND_HZ[1])
        U = X / np.maximum(np.abs(X), 1e-30)
        n = self.nfft * self.up
        power = np.zeros(self.az.size)
        for k, (i, j) in enumerate(self.pairs):
            g = np.zeros(self.nfft // 2 + 1, complex)
            g[band] = np.sum(U[:, j, band] * np.conj(U[:, i, band]), axis=0)
            # R(tau) = sum_k Re(G(k) e^{+j 2 pi k tau / N}) peaks at tau = t_j - t_i.
            r = np.fft.irfft(np.concatenate([g, np.zeros(n // 2 + 1 - g.size)]), n) * n
            lag = self.tau[k] * self.up
            lo = np.floor(lag).astype(int)
            w = lag - lo
            power += (1 - w) * r[lo % n] + w * r[(lo + 1) % n]
        best = int(np.argmax(power))
        return np.degrees(self.az[best]), np.degrees(self.zen[best])


def check_pra(array, x):
    """pyroomacoustics' SRP (2 deg grid) on the same window, for the cross-check."""
    mics = np.array([[px, py, 0.0] for px, py in ARRAYS[array]]).T
    doa = pra.doa.algorithms["SRP"](mics, FS, 1024, c=343.0, num_src=1, dim=3,
                                    azimuth=np.radians(np.arange(-180, 180, 2.0)),
                                    colatitude=np.radians(np.arange(0, 91, 2.0)))
    frames = (x.shape[1] - 1024) // 1024 + 1
    win = np.hanning(1024)
    X = np.stack([np.fft.rfft(x[:, k * 1024:(k + 1) * 1024] * win, axis=1) for k in range(frames)])
    doa.locate_sources(np.transpose(X, (1, 2, 0)), num_src=1, freq_range=list(BAND_HZ))
    return np.degrees(doa.azimuth_recon[0]), np.degrees(doa.colatitude_recon[0])


def read_correction(site_path):
    """`zenith_correction_deg = [[measured, bias], ...]` of a site file's only array, degrees."""
    for line in open(site_path):
        if line.startswith("zenith_correction_deg"):
            return json.loads(line.split("=", 1)[1])
    raise SystemExit(f"{site_path}: no zenith_correction_deg (did aim calibrate fit it?)")


def correct(points, zen_deg):
    """A measured zenith (0-90 deg) corrected as aim_tracker::zenith::ZenithCorrection::correct."""
    if not points:
        return zen_deg
    zs = [p[0] for p in points]
    bs = [p[1] for p in points]
    bias = float(np.interp(zen_deg, zs, bs))  # the end points' bias beyond them
    return min(max(zen_deg - bias, 0.0), 90.0)


def fit_points(measured, true, bin_deg=5.0, min_frames=20, max_mad_deg=3.0):
    """Per bin of measured zenith, the median of measured - true (aim calibrate's rule)."""
    bins = defaultdict(list)
    for m, t in zip(measured, true):
        bins[int(np.floor(m / bin_deg))].append(m - t)
    points = []
    for k in sorted(bins):
        e = np.array(bins[k])
        med = float(np.median(e))
        if e.size >= min_frames and np.median(np.abs(e - med)) <= max_mad_deg:
            points.append([(k + 0.5) * bin_deg, med])
    return points


def reference_at(ref, t):
    """Where the survey's drone was at t (the row at or before t)."""
    i = max(0, int(np.searchsorted(ref[:, 0], t, side="right")) - 1)
    return ref[i, 1:]


def srp_cache_key(survey_dir, grid_deg):
    """What SRP-PHAT's calibration of a survey depends on: the grid, the survey's audio (size
    and modification time), its reference and its site."""
    wav = os.stat(os.path.join(survey_dir, "survey.wav"))
    digest = lambda name: hashlib.sha1(open(os.path.join(survey_dir, name), "rb").read()).hexdigest()
    return {"grid_deg": grid_deg, "survey_bytes": wav.st_size, "survey_mtime_ns": wav.st_mtime_ns,
            "reference_sha1": digest("reference.csv"), "site_sha1": digest("site.toml")}


def srp_survey_points(survey_dir, array, host_sim, grid_deg):
    """SRP-PHAT's own calibration from the survey: cached in SURVEY/srp-correction.json with
    the key it was computed for (srp_cache_key); computed again when the key differs."""
    cache = os.path.join(survey_dir, "srp-correction.json")
    key = srp_cache_key(survey_dir, grid_deg)
    if os.path.exists(cache):
        stored = json.load(open(cache))
        if isinstance(stored, dict) and stored.get("key") == key:
            return stored["points"]
        print(f"{cache}: made for another survey or grid; computing it again", flush=True)
    wav = os.path.join(survey_dir, "survey.wav")
    x = read_wav(wav)
    ref = np.loadtxt(os.path.join(survey_dir, "reference.csv"), delimiter=",", skiprows=1)
    site = open(os.path.join(survey_dir, "site.toml")).read()
    pos = json.loads(site.split("\nposition = ", 1)[1].split("\n", 1)[0])
    srp = Srp(array, grid_deg)
    measured, true = [], []
    for fr in aim_frames(host_sim, wav, array):
        s0 = int(round(fr["t"] * FS))
        s1 = s0 + int(round(fr["span_s"] * FS))
        if s1 > x.shape[1]:
            continue
        _, zen = srp.locate(x[:, s0:s1])
        v = reference_at(ref, fr["t"] + fr["span_s"] / 2) - np.array(pos)
        measured.append(zen)
        true.append(np.degrees(np.arccos(v[2] / np.linalg.norm(v))))
    points = fit_points(measured, true)
    json.dump({"key": key, "points": points}, open(cache, "w"))
    return points


def wrap(d):
    return (d + 180.0) % 360.0 - 180.0


def summary(rows, key):
    az = np.abs([r[key + "_az_err"] for r in rows if key + "_az_err" in r])
    zen = [r[key + "_zen_err"] for r in rows if key + "_zen_err" in r]
    return (np.median(az), np.percentile(az, 90), np.median(np.abs(zen)),
            np.percentile(np.abs(zen), 90), np.median(zen))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dir", required=True)
    ap.add_argument("--host-sim", action="append", default=None, metavar="[LABEL=]PATH",
                    help="host-sim binary (repeatable, e.g. aim=target/release/host-sim "
                         "base=/tmp/host-sim-base); default aim=target/release/host-sim")
    ap.add_argument("--grid-deg", type=float, default=0.5)
    ap.add_argument("--check-pra", type=int, default=0,
                    help="also run pyroomacoustics' SRP on the first N windows and print both")
    ap.add_argument("--no-srp", action="store_true", help="AIM only (faster)")
    ap.add_argument("--survey", help="surveys of survey.py: also AIM and SRP-PHAT calibrated")
    a = ap.parse_args()
    bins = [h.split("=", 1) if "=" in h else ["aim", h]
            for h in (a.host_sim or ["target/release/host-sim"])]
    cases = [json.loads(l) for l in open(os.path.join(a.dir, "cases.jsonl"))]
    srp = {}
    calib = {}
    rows = []
    for c in cases:
        wav = os.path.join(a.dir, c["name"] + ".wav")
        x = read_wav(wav)
        runs = {label: aim_frames(path, wav, c["array"]) for label, path in bins}
        first = bins[0][0]
        if not a.no_srp and c["array"] not in srp:
            srp[c["array"]] = Srp(c["array"], a.grid_deg)
        for n, fr in enumerate(runs[first]):
            if fr["t"] < SKIP_S:
                continue
            row = {"case": c["name"], "array": c["array"], "rt60": c["rt60_target_s"],
                   "t": fr["t"], "drr_db": c["drr_db"], "true_zen": c["zenith_deg"],
                   "range_m": c["range_m"]}
            for label, frs in runs.items():
                f2 = [g for g in frs if abs(g["t"] - fr["t"]) < 1e-6]
                if not f2:
                    continue
                f2 = f2[0]
                row[label + "_az_err"] = wrap(f2["azimuth_deg"] - c["azimuth_deg"])
                row[label + "_zen_err"] = f2["zenith_deg"] - c["zenith_deg"]
                row[label + "_quality"] = f2["quality"]
                row[label + "_residual"] = f2["residual_samples"]
            if not a.no_srp:
                s0 = int(round(fr["t"] * FS))
                s1 = s0 + int(round(fr["span_s"] * FS))
                if s1 > x.shape[1]:
                    continue
                az, zen = srp[c["array"]].locate(x[:, s0:s1])
                row["srp_az_err"] = wrap(az - c["azimuth_deg"])
                row["srp_zen_err"] = zen - c["zenith_deg"]
                if a.check_pra > 0:
                    a.check_pra -= 1
                    paz, pzen = check_pra(c["array"], x[:, s0:s1])
                    print(f"check {c['name']} t={fr['t']:.2f}: ours {az:.1f}/{zen:.1f}, "
                          f"pyroomacoustics {paz:.1f}/{pzen:.1f}, truth "
                          f"{c['azimuth_deg']:.1f}/{c['zenith_deg']:.1f}", flush=True)
            if a.survey:
                sdir = os.path.join(a.survey, f"{c['array']}-{c['room']}-rt{c['rt60_target_s']:.1f}")
                if sdir not in calib:
                    calib[sdir] = (
                        read_correction(os.path.join(sdir, "site-calibrated.toml")),
                        None if a.no_srp else srp_survey_points(sdir, c["array"], bins[0][1], a.grid_deg),
                    )
                aim_pts, srp_pts = calib[sdir]
                if first + "_zen_err" in row:
                    zen = row[first + "_zen_err"] + c["zenith_deg"]
                    row[first + "+cal_az_err"] = row[first + "_az_err"]
                    row[first + "+cal_zen_err"] = correct(aim_pts, zen) - c["zenith_deg"]
                if "srp_zen_err" in row and srp_pts is not None:
                    zen = row["srp_zen_err"] + c["zenith_deg"]
                    row["srp+cal_az_err"] = row["srp_az_err"]
                    row["srp+cal_zen_err"] = correct(srp_pts, zen) - c["zenith_deg"]
            rows.append(row)
    with open(os.path.join(a.dir, "frames.jsonl"), "w") as f:
        for r in rows:
            f.write(json.dumps(r) + "\n")
    groups = defaultdict(list)
    for r in rows:
        groups[(r["array"], r["rt60"])].append(r)
    methods = [label for label, _ in bins] + ([] if a.no_srp else ["srp"])
    if a.survey:
        methods += [bins[0][0] + "+cal"] + ([] if a.no_srp else ["srp+cal"])
    print("| array | RT60 | cases/frames | method | azimuth median (p90) | zenith median (p90) | zenith bias |")
    print("|---|---|---|---|---|---|---|")
    for (array, rt60), g in sorted(groups.items()):
        ncases = len({r["case"] for r in g})
        for m in methods:
            am, a9, zm, z9, zb = summary(g, m)
            print(f"| {array} | {rt60:.1f} s | {ncases}/{len(g)} | {m.upper()} | "
                  f"{am:.1f}° ({a9:.1f}°) | {zm:.1f}° ({z9:.1f}°) | {zb:+.1f}° |")


if __name__ == "__main__":
    main()
