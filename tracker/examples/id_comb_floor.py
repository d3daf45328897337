#!/usr/bin/env python3
"""Is a rotor comb in a recording at all? A check independent of aim-dsp (diagnostic, not
part of the product; needs numpy and scipy).

    python3 tracker/examples/id_comb_floor.py LO_HZ HI_HZ FILE_LIST

FILE_LIST names WAVs (16 or 48 kHz, mono), one per line. Per file it prints two numbers:
- the median over 0.512 s frames of the best harmonic sum in LO_HZ..HI_HZ;
- the median over 1.8 s spans (14 frames, 0.128 s hop) of the best *track* of harmonic sums
  (the fundamental may move by 3 bins = 5.9 Hz per hop), per frame.
The spectrum is the chip's kind (8 kHz, 4096-point Hann, 1.95 Hz bins), whitened by a
25-bin running median; a fundamental's sum is sum over h = 1..8 of (w - 1)+ / sqrt(h) at the
largest w within 1 bin of h*f. A recording whose numbers sit among those of recordings with
no drone has no comb a per-frame (or 1.8 s) comb detector can find.
"""
import sys

import numpy as np
from scipy.io import wavfile
from scipy.ndimage import median_filter
from scipy.signal import decimate

N, HOP, H = 4096, 1024, 8
BIN_HZ = 8000 / N


def whitened_frames(path):
    rate, x = wavfile.read(path)
    x = x.astype(np.float64)
    if x.ndim > 1:
        x = x.mean(axis=1)
    x = decimate(x, rate // 8000)
    w = np.hanning(N)
    out = []
    for s in range(0, len(x) - N, HOP):
        m = np.abs(np.fft.rfft(w * x[s:s + N]))
        out.append(m / (median_filter(m, size=25, mode="nearest") + 1e-12))
    return np.array(out)


def harmonic_sums(white, lo, hi):
    ks = np.arange(lo, hi + 1)
    weights = 1 / np.sqrt(np.arange(1, H + 1))
    out = np.zeros((white.shape[0], len(ks)))
    for h in range(1, H + 1):
        idx = np.minimum(ks * h, white.shape[1] - 2)
        v = np.maximum(np.maximum(white[:, idx - 1], white[:, idx]), white[:, idx + 1])
        out += weights[h - 1] * np.where(ks * h < white.shape[1] - 2, np.maximum(v - 1, 0), 0)
    return out


def best_track(hs, length=14, step=3):
    best = []
    for s in range(0, hs.shape[0] - length + 1, 2):
        acc = hs[s].copy()
        for t in range(s + 1, s + length):
            m = acc.copy()
            for d in range(1, step + 1):
                m[d:] = np.maximum(m[d:], acc[:-d])
                m[:-d] = np.maximum(m[:-d], acc[d:])
            acc = m + hs[t]
        best.append(acc.max() / length)
    return np.array(best)


def main():
    lo, hi = int(float(sys.argv[1]) / BIN_HZ), int(float(sys.argv[2]) / BIN_HZ)
    for path in (l.strip() for l in open(sys.argv[3]) if l.strip()):
        hs = harmonic_sums(whitened_frames(path), lo, hi)
        print(f"{path} {np.median(hs.max(axis=1)):.2f} {np.median(best_track(hs)):.2f}")


if __name__ == "__main__":
    main()
