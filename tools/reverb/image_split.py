#!/usr/bin/env python3
"""Which reflections bias the zenith: the same static source in four versions of a room.

For each source (make_rooms.py's drone-like signal and source draw, hall 20 x 15 x 5 m, array
0.8 m above the floor at (6, 7)) and RT60, pyroomacoustics renders the room four ways: `all`
(every surface absorbing alpha from Sabine's formula, as make_rooms.py), `fc` (floor and
ceiling at alpha, the four walls anechoic: alpha 0.999), `walls` (the walls at alpha, floor
and ceiling anechoic) and `direct` (no reflection). Writes float WAVs and DIR/cases.jsonl with
a `var` field; `variants.py --dir DIR` (or `image_model.py`) reads them.

    python3 tools/reverb/image_split.py --out /tmp/image-split --seeds 1-4
"""
import argparse
import json
import os
import sys

import numpy as np
import pyroomacoustics as pra

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import make_rooms as mr  # noqa: E402

WALLS = ["east", "west", "north", "south", "floor", "ceiling"]


def materials(var, alpha):
    if var == "fc":
        return {w: pra.Material(alpha if w in ("floor", "ceiling") else 0.999) for w in WALLS}
    if var == "walls":
        return {w: pra.Material(0.999 if w in ("floor", "ceiling") else alpha) for w in WALLS}
    return pra.Material(alpha)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True)
    ap.add_argument("--seeds", default="1-4")
    ap.add_argument("--rt60", default="0.6,1.0")
    ap.add_argument("--arrays", default="respeaker6,respeaker4")
    ap.add_argument("--array-height", type=float, default=mr.ARRAY_HEIGHT_M,
                    help="array height above the floor, m [0.8]")
    ap.add_argument("--variants", default="all,fc,walls,direct")
    a = ap.parse_args()
    mr.ARRAY_HEIGHT_M = a.array_height
    os.makedirs(a.out, exist_ok=True)
    room_dim, axy = mr.ROOMS["hall20"]
    with open(os.path.join(a.out, "cases.jsonl"), "w") as out:
        for rt60 in [float(x) for x in a.rt60.split(",")]:
            alpha, order = pra.inverse_sabine(rt60, room_dim)
            order = min(order, 40)
            for array in a.arrays.split(","):
                for seed in mr.seed_range(a.seeds):
                    rng = np.random.default_rng(seed)
                    az, zen, r, src = mr.draw_source(rng, room_dim, axy)
                    sig = mr.drone_signal(rng, 2.0)
                    for var in a.variants.split(","):
                        room = pra.ShoeBox(room_dim, fs=mr.FS, materials=materials(var, alpha),
                                           max_order=0 if var == "direct" else order,
                                           air_absorption=False)
                        room.add_source(src.tolist(), signal=sig)
                        mics = np.array([[axy[0] + x, axy[1] + y, mr.ARRAY_HEIGHT_M]
                                         for x, y in mr.ARRAYS[array]]).T
                        room.add_microphone_array(pra.MicrophoneArray(mics, mr.FS))
                        room.simulate()
                        y = room.mic_array.signals[:, : int(2.0 * mr.FS)]
                        noise = np.sqrt(np.mean(y ** 2, axis=1, keepdims=True)) * 10 ** (-25 / 20)
                        y = y + np.random.default_rng(seed + 99).standard_normal(y.shape) * noise
                        name = f"{array}-rt{rt60}-{var}-s{seed}"
                        mr.write_wav(os.path.join(a.out, name + ".wav"), y)
                        case = {"name": name, "seed": seed, "array": array, "room": "hall20",
                                "room_dim": list(room_dim), "rt60_target_s": rt60,
                                "absorption": round(float(alpha), 4), "var": var,
                                "array_height_m": mr.ARRAY_HEIGHT_M,
                                "azimuth_deg": az, "zenith_deg": zen, "range_m": r}
                        out.write(json.dumps(case) + "\n")
                        print(name, flush=True)


if __name__ == "__main__":
    main()
