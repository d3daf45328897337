#!/usr/bin/env python3
"""Prototype of AIM's spatial path in numpy, to try direct-path ideas before they go on chip.

GCC-PHAT per pair over one DoA window (8 Hann blocks of 1024 samples at 48 kHz), each bin
weighted by its block-to-block coherence |G|/8 as aim-dsp does, the lag by a 64x zero-padded
inverse FFT within the physical range, then plain least squares over the pairs (no robust
step). Variants (--modes, comma separated):

  plain       band 200-6000 Hz (aim-dsp's default band)
  cdr         per bin, remove the diffuse-field part before the phase is read: with the
              spherical-diffuse coherence sinc(2 pi f d / c) and a unit-modulus direct term,
              the diffuse share beta solves |G - beta sinc| = 1 - beta; weight (1 - beta)
  b15         band 1500-7300 Hz (the same number of bins as the default band: same cost)
  hi          band 2000-6000 Hz
  w9          band 200-9000 Hz (the most aim-dsp's 192 band bins allow; ~50 % more cost)
  wide        band 200-12000 Hz
  phat        band 200-6000 Hz, every bin's phase alone (no coherence weight)
  cc          band 200-6000 Hz, plain cross-spectrum (no PHAT: louder bins weigh more)
  tonal       band 200-6000 Hz, only bins within one bin of a harmonic of 320 Hz (the comb)
  noise       band 200-6000 Hz, only the bins between the harmonics (the broadband part)

    python3 tools/reverb/variants.py --dir /tmp/reverb-tune --modes plain,cdr,b15,hi,w9,wide
"""
import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import compare  # noqa: E402

FS = 48_000
N = 1024
BLOCKS = 8
BANDS = {"plain": (200, 6000), "cdr": (200, 6000), "phat": (200, 6000), "cc": (200, 6000),
         "tonal": (200, 6000), "noise": (200, 6000), "b15": (1500, 7300), "hi": (2000, 6000),
         "w9": (200, 9000), "wide": (200, 12000)}


def estimate(x, positions, mode):
    m = len(positions)
    pairs = [(i, j) for i in range(m) for j in range(i + 1, m)]
    win = np.hanning(N)
    X = np.stack([np.fft.rfft(x[:, k * N:(k + 1) * N] * win, axis=1) for k in range(BLOCKS)])
    f = np.fft.rfftfreq(N, 1 / FS)
    lo, hi = BANDS[mode]
    band = (f >= lo) & (f <= hi)
    harmonic = np.round(f / 320.0)
    comb = (np.abs(f - harmonic * 320.0) <= FS / N) & (harmonic >= 1)
    if mode == "tonal":
        band &= comb
    elif mode == "noise":
        band &= ~comb
    U = X / np.maximum(np.abs(X), 1e-30)
    up = 64
    n = N * up
    A, b = [], []
    for i, j in pairs:
        d = positions[i] - positions[j]
        dist = np.hypot(*d)
        G = np.sum(U[:, j, :] * np.conj(U[:, i, :]), axis=0) / BLOCKS
        g = np.zeros(N // 2 + 1, complex)
        if mode == "cdr":
            gx = G[band]
            gn = np.sinc(2 * f[band] * dist / 343.0)  # np.sinc(x) = sin(pi x) / (pi x)
            qa, qb, qc = gn ** 2 - 1, 2 - 2 * gx.real * gn, np.abs(gx) ** 2 - 1
            disc = np.sqrt(np.maximum(qb * qb - 4 * qa * qc, 0))
            with np.errstate(divide="ignore", invalid="ignore"):
                r1, r2 = (-qb + disc) / (2 * qa), (-qb - disc) / (2 * qa)
            beta = np.nan_to_num(np.where((r1 >= 0) & (r1 < 1), r1,
                                          np.where((r2 >= 0) & (r2 < 1), r2, 0.0)))
            s = gx - beta * gn
            g[band] = s / np.maximum(np.abs(s), 1e-12) * (1 - beta)
        elif mode == "phat":
            g[band] = G[band] / np.maximum(np.abs(G[band]), 1e-12)
        elif mode == "cc":
            g[band] = np.sum(X[:, j, band] * np.conj(X[:, i, band]), axis=0)
        else:
            g[band] = G[band] * np.abs(G[band])
        r = np.fft.irfft(np.concatenate([g, np.zeros(n // 2 + 1 - g.size)]), n) * n
        max_lag = int(np.ceil(dist / 343 * FS + 1)) * up
        lags = np.r_[0:max_lag + 1, n - max_lag:n]
        k = lags[np.argmax(r[lags])]
        A.append(d)
        b.append((k if k <= n // 2 else k - n) / up / FS * 343)
    u = np.linalg.lstsq(np.array(A), np.array(b), rcond=None)[0]
    return np.degrees(np.arctan2(u[1], u[0])), np.degrees(np.arcsin(min(np.hypot(*u), 1.0)))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dir", required=True)
    ap.add_argument("--modes", default="plain,cdr,b15,hi,w9,wide")
    a = ap.parse_args()
    modes = a.modes.split(",")
    res = {m: {} for m in modes}
    for line in open(os.path.join(a.dir, "cases.jsonl")):
        c = json.loads(line)
        x = compare.read_wav(os.path.join(a.dir, c["name"] + ".wav"))
        p = np.array(compare.ARRAYS[c["array"]])
        for s0 in range(int(compare.SKIP_S * FS), x.shape[1] - N * BLOCKS + 1, N * BLOCKS):
            for m in modes:
                az, zen = estimate(x[:, s0:s0 + N * BLOCKS], p, m)
                res[m].setdefault((c["array"], c["rt60_target_s"], c.get("var", "all")), []).append(
                    (compare.wrap(az - c["azimuth_deg"]), zen - c["zenith_deg"]))
    print("| array | RT60 | room | variant | frames | azimuth median (p90) | zenith median (p90) | zenith bias |")
    print("|---|---|---|---|---|---|---|---|")
    keys = sorted({k for m in modes for k in res[m]})
    for k in keys:
        for m in modes:
            v = np.array(res[m][k])
            az, zen = np.abs(v[:, 0]), v[:, 1]
            print(f"| {k[0]} | {k[1]:.1f} s | {k[2]} | {m} | {len(v)} | {np.median(az):.1f}° "
                  f"({np.percentile(az, 90):.1f}°) | {np.median(np.abs(zen)):.1f}° "
                  f"({np.percentile(np.abs(zen), 90):.1f}°) | {np.median(zen):+.1f}° |")


if __name__ == "__main__":
    main()
