#!/usr/bin/env python3
"""Static-source reverberant recordings from an independent room simulator (pyroomacoustics).

Shoebox rooms (image-source method, wall absorption from Sabine's formula for the stated RT60,
image order from pyroomacoustics' `inverse_sabine`, capped at --max-order), a drone-like source
(BPF 320 Hz with 10 harmonics, +-0.3 % rotor wobble, broadband noise 10 dB below the tones,
77 dB SPL at 1 m), sensor noise 25 dB below each microphone's signal, heard by a ReSpeaker
6-mic circle or 4-mic square 0.8 m above the floor, mic positions exactly those of aim-dsp's
presets. Writes one float WAV (pascals, 48 kHz) per case and `cases.jsonl` with the truth.

Nothing here shares code with host-sim: it is the oracle side of tools/reverb/.

    python3 tools/reverb/make_rooms.py --out /tmp/reverb --seeds 100-107
"""
import argparse
import json
import os

import numpy as np
import pyroomacoustics as pra

FS = 48_000
C = 343.0
ARRAY_HEIGHT_M = 0.8

ARRAYS = {
    # aim-dsp Geometry::respeaker_6mic: circle r = 0.0463 m, mic 0 on +x, counter-clockwise.
    "respeaker6": [(0.0463 * np.cos(2 * np.pi * i / 6), 0.0463 * np.sin(2 * np.pi * i / 6))
                   for i in range(6)],
    # aim-dsp Geometry::respeaker_4mic: square of side 0.065 m, mic 0 at +x+y, counter-clockwise.
    "respeaker4": [(0.065 / np.sqrt(2) * np.cos(np.pi / 4 + np.pi / 2 * i),
                    0.065 / np.sqrt(2) * np.sin(np.pi / 4 + np.pi / 2 * i)) for i in range(4)],
}

# Rooms (x, y, z metres) and where the array stands in them (x, y).
ROOMS = {
    "hall20": ((20.0, 15.0, 5.0), (6.0, 7.0)),
    "hall24": ((24.0, 20.0, 8.0), (8.0, 9.0)),
}


def drone_signal(rng, seconds, bpf_hz=320.0, harmonics=10, wobble=0.003, broadband_db=-10.0):
    """Pressure at 1 m, pascals: 10 harmonics of a wobbling BPF plus broadband noise."""
    n = int(seconds * FS)
    t = np.arange(n) / FS
    # Rotor wobble: a smooth random walk of the BPF within +-wobble (a few per second).
    knots = rng.uniform(-1.0, 1.0, int(seconds * 4) + 2)
    dev = np.interp(t, np.linspace(0, seconds, knots.size), knots) * wobble
    phase = 2 * np.pi * np.cumsum(bpf_hz * (1.0 + dev)) / FS
    tones = np.zeros(n)
    for h in range(1, harmonics + 1):
        tones += (1.0 / h ** 0.5) * np.sin(h * phase + rng.uniform(0, 2 * np.pi))
    noise = rng.standard_normal(n)
    # Broadband: pink-ish (1/f power above 200 Hz) via spectral shaping, 10 dB below the tones.
    spec = np.fft.rfft(noise)
    f = np.fft.rfftfreq(n, 1 / FS)
    spec /= np.sqrt(np.maximum(f, 200.0) / 200.0)
    noise = np.fft.irfft(spec, n)
    noise *= np.sqrt(np.mean(tones ** 2) / np.mean(noise ** 2)) * 10 ** (broadband_db / 20)
    x = tones + noise
    # 77 dB SPL at 1 m (DJI Mini 2, ALGORITHMS.md).
    return x * (20e-6 * 10 ** (77 / 20) / np.sqrt(np.mean(x ** 2)))


def draw_source(rng, room_dim, array_xy):
    """Azimuth (deg), zenith (deg), range (m) with the source inside the room (0.3 m margin)."""
    for _ in range(10_000):
        az = rng.uniform(-180, 180)
        zen = rng.uniform(45, 80)
        r = rng.uniform(4, 10)
        s = np.array([
            array_xy[0] + r * np.sin(np.radians(zen)) * np.cos(np.radians(az)),
            array_xy[1] + r * np.sin(np.radians(zen)) * np.sin(np.radians(az)),
            ARRAY_HEIGHT_M + r * np.cos(np.radians(zen)),
        ])
        if np.all(s > 0.3) and np.all(s < np.array(room_dim) - 0.3):
            return az, zen, r, s
    raise RuntimeError("no source position fits the room")


def write_wav(path, x):
    """Float32 WAV, one channel per row of x (pascals)."""
    data = np.ascontiguousarray(x.T.astype("<f4"))
    with open(path, "wb") as f:
        ch, n = x.shape[0], x.shape[1]
        byte_rate = FS * ch * 4
        f.write(b"RIFF" + (36 + data.nbytes).to_bytes(4, "little") + b"WAVE")
        f.write(b"fmt " + (16).to_bytes(4, "little") + (3).to_bytes(2, "little")
                + ch.to_bytes(2, "little") + FS.to_bytes(4, "little")
                + byte_rate.to_bytes(4, "little") + (ch * 4).to_bytes(2, "little")
                + (32).to_bytes(2, "little"))
        f.write(b"data" + data.nbytes.to_bytes(4, "little") + data.tobytes())


def make_case(out, seed, rt60, array, room_name, seconds, max_order):
    rng = np.random.default_rng(seed)
    room_dim, array_xy = ROOMS[room_name]
    az, zen, r, src = draw_source(rng, room_dim, array_xy)
    absorption, order = pra.inverse_sabine(rt60, room_dim)
    order = min(order, max_order)
    room = pra.ShoeBox(room_dim, fs=FS, materials=pra.Material(absorption),
                       max_order=order, air_absorption=False)
    sig = drone_signal(rng, seconds)
    room.add_source(src.tolist(), signal=sig)
    mics = np.array([[array_xy[0] + x, array_xy[1] + y, ARRAY_HEIGHT_M] for x, y in ARRAYS[array]]).T
    room.add_microphone_array(pra.MicrophoneArray(mics, FS))
    room.compute_rir()
    rir0 = room.rir[0][0]
    measured_rt60 = float(pra.experimental.measure_rt60(rir0, fs=FS, decay_db=30))
    room.simulate()
    y = room.mic_array.signals[:, : int(seconds * FS)]
    # Direct-to-reverberant ratio at mic 0: energy within 2.5 ms of the direct arrival vs after.
    d0 = int(np.argmax(np.abs(rir0)))
    w = int(0.0025 * FS)
    drr = 10 * np.log10(np.sum(rir0[max(0, d0 - w): d0 + w] ** 2) / np.sum(rir0[d0 + w:] ** 2))
    noise_rms = np.sqrt(np.mean(y ** 2, axis=1, keepdims=True)) * 10 ** (-25 / 20)
    y = y + rng.standard_normal(y.shape) * noise_rms
    name = f"{array}-{room_name}-rt{rt60:.1f}-s{seed}"
    write_wav(os.path.join(out, name + ".wav"), y)
    return {
        "name": name, "seed": seed, "array": array, "room": room_name, "room_dim": room_dim,
        "rt60_target_s": rt60, "rt60_measured_s": round(measured_rt60, 3), "max_order": order,
        "absorption": round(float(absorption), 4), "azimuth_deg": az, "zenith_deg": zen,
        "range_m": r, "drr_db": round(float(drr), 2), "seconds": seconds,
    }


def seed_range(text):
    a, _, b = text.partition("-")
    return list(range(int(a), int(b or a) + 1))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True)
    ap.add_argument("--seeds", default="100-107", help="source seeds, e.g. 100-107")
    ap.add_argument("--rt60", default="0.3,0.6,1.0")
    ap.add_argument("--arrays", default="respeaker6,respeaker4")
    ap.add_argument("--rooms", default="hall20,hall24")
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--max-order", type=int, default=40)
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    with open(os.path.join(a.out, "cases.jsonl"), "a") as f:
        for rt60 in [float(x) for x in a.rt60.split(",")]:
            for array in a.arrays.split(","):
                for seed in seed_range(a.seeds):
                    rooms = a.rooms.split(",")
                    room = rooms[seed % len(rooms)]
                    try:
                        pra.inverse_sabine(rt60, ROOMS[room][0])
                    except ValueError:  # too large for so short an RT60: the first room
                        room = rooms[0]
                    case = make_case(a.out, seed, rt60, array, room, a.seconds, a.max_order)
                    print(json.dumps(case), flush=True)
                    f.write(json.dumps(case) + "\n")


if __name__ == "__main__":
    main()
