#!/usr/bin/env python3
"""Golden room figures from an independent simulator (pyroomacoustics' image-source method),
for host-sim's `tests/room_oracle.rs` (which needs no Python).

Per room (static geometry, all walls alike, energy absorption alpha from Eyring's formula for
a nominal RT60, no air absorption, no randomised ISM, image order high enough for the whole
decay, 16 kHz):
- T30 of each microphone's impulse response: Schroeder backward integral, least-squares line
  from -5 to -35 dB extrapolated to -60 dB (the same definition host-sim's test applies), and
  pyroomacoustics' own `measure_rt60(decay_db=30)` beside it;
- the direct-to-reverberant ratio: energy within +-2.5 ms of the direct arrival against the rest;
- the direct path and every image of order <= 2: its arrival delay at each microphone (s) and
  its pressure gain (product of the walls' sqrt(1 - alpha)), from pyroomacoustics' own images.

    python3 tools/reverb/oracle_ir.py > host-sim/tests/data/room_oracle.json
"""
import json
import sys

import numpy as np
import pyroomacoustics as pra

FS = 16_000
C = 343.0

# name, size (m), nominal RT60 (s), source (m), array centre (m); three microphones of a
# 4.63 cm circle (ReSpeaker 6-mic radius) at 0, 60 and 180 degrees.
ROOMS = [
    ("hall-0.4", (10.0, 8.0, 4.0), 0.4, (7.0, 5.5, 2.6), (3.0, 2.5, 0.8)),
    ("hall-0.8", (20.0, 15.0, 5.0), 0.8, (13.0, 9.0, 3.0), (6.0, 7.0, 0.8)),
    ("hall-1.5", (24.0, 20.0, 8.0), 1.5, (15.0, 14.0, 4.0), (8.0, 9.0, 0.8)),
]
MIC_ANGLES_DEG = (0.0, 60.0, 180.0)
RADIUS_M = 0.0463


def eyring_alpha(size, rt60):
    x, y, z = size
    v = x * y * z
    s = 2 * (x * y + x * z + y * z)
    return 1.0 - np.exp(-24.0 * np.log(10.0) / C * v / (s * rt60))


def t30(ir):
    e = np.asarray(ir, dtype=float) ** 2
    edc = np.cumsum(e[::-1])[::-1]
    db = 10 * np.log10(np.maximum(edc / edc[0], 1e-300))
    i0 = int(np.argmax(db <= -5.0))
    i1 = int(np.argmax(db <= -35.0))
    t = np.arange(i0, i1 + 1) / FS
    slope = np.polyfit(t, db[i0:i1 + 1], 1)[0]
    return -60.0 / slope


def main():
    out = {"generator": f"tools/reverb/oracle_ir.py, pyroomacoustics {pra.__version__}",
           "fs_hz": FS, "c_mps": C, "rooms": []}
    for name, size, rt60, src, centre in ROOMS:
        alpha = float(eyring_alpha(size, rt60))
        # Order for the whole decay to -60 dB along the slowest (axis-aligned) direction, at most 60.
        decay_m = -60.0 / (10 * np.log10(1 - alpha)) * min(size)
        order = int(min(60, np.ceil(decay_m / min(size)) + 2))
        room = pra.ShoeBox(size, fs=FS, materials=pra.Material(alpha), max_order=order,
                           air_absorption=False, use_rand_ism=False)
        room.set_sound_speed(C)
        room.add_source(list(src))
        mics = np.array([[centre[0] + RADIUS_M * np.cos(np.radians(a)),
                          centre[1] + RADIUS_M * np.sin(np.radians(a)), centre[2]]
                         for a in MIC_ANGLES_DEG]).T
        room.add_microphone_array(mics)
        room.compute_rir()
        rec = {"name": name, "size_m": list(size), "alpha": alpha, "image_order": order,
               "source_m": list(src), "mics_m": mics.T.tolist(), "mics": []}
        for m in range(mics.shape[1]):
            ir = np.asarray(room.rir[m][0])
            d = np.linalg.norm(np.array(src) - mics[:, m])
            # pyroomacoustics delays every response by its fractional-delay filter's half length.
            k = int(round(d / C * FS)) + pra.constants.get("frac_delay_length") // 2
            w = int(round(0.0025 * FS))
            direct = float(np.sum(ir[max(0, k - w):k + w + 1] ** 2))
            rest = float(np.sum(ir ** 2)) - direct
            rec["mics"].append({
                "t30_s": float(t30(ir)),
                "pra_t30_s": float(pra.experimental.measure_rt60(ir, fs=FS, decay_db=30)),
                "drr_db": float(10 * np.log10(direct / rest)),
            })
        s = room.sources[0]
        images = []
        for i in range(s.images.shape[1]):
            if s.orders[i] > 2:
                continue
            p = s.images[:, i]
            images.append({
                "order": int(s.orders[i]),
                "gain": float(s.damping[0, i]),
                "delays_s": [float(np.linalg.norm(p - mics[:, m]) / C) for m in range(mics.shape[1])],
            })
        images.sort(key=lambda x: x["delays_s"][0])
        rec["images"] = images
        out["rooms"].append(rec)
        print(name, alpha, order, [round(m["t30_s"], 3) for m in rec["mics"]],
              [round(m["drr_db"], 2) for m in rec["mics"]], file=sys.stderr)
    json.dump(out, sys.stdout, indent=1)


if __name__ == "__main__":
    main()
