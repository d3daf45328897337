#!/usr/bin/env python3
"""A calibration survey in each room of make_rooms.py, and the site it calibrates.

An installer calibrates an array's zenith by flying a drone through the room against a
reference (`aim calibrate`). Here the drone hovers at marked points: a grid of horizontal
distances 3, 4.5, 6, 7.5 and 9 m from the array at six azimuths per layer, in layers 1.5 m
above the floor and every metre up to 1 m under the ceiling, every point inside the room
with a 0.5 m margin; 2 s at each point, in order, the room's response to each point overlapping
the next (the room keeps ringing when the drone moves on). The grid does not depend on the
test sources of make_rooms.py (drawn at zenith 45-80 deg, range 4-10 m), and the survey's
drone signals come from seeds of their own (SURVEY_SEED + ...), never a test seed.

For every (array, room, RT60) that make_rooms.py uses, writes DIR/<array>-<room>-rt<RT60>/:
`survey.wav` (float, Pa), `reference.csv` (t, x, y, z: where the drone hovered), `site.toml`
(the array where make_rooms.py puts it), and with --host-sim and --aim runs the product's
path on it: `host-sim analyze survey.wav --frames frames-1.aimraw` (the chip's frames as its
link carries them), then `aim calibrate frames-1.aimraw --reference reference.csv --site
site.toml --out site-calibrated.toml`.

    python3 tools/reverb/survey.py --out /tmp/reverb-survey \\
        --host-sim target/release/host-sim --aim target/release/aim
"""
import argparse
import os
import subprocess
import sys

import numpy as np
import pyroomacoustics as pra

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from make_rooms import ARRAYS, ARRAY_HEIGHT_M, C, FS, ROOMS, drone_signal, write_wav  # noqa: E402

SURVEY_SEED = 900_000
HOVER_S = 2.0
DISTANCES_M = (3.0, 4.5, 6.0, 7.5, 9.0)
AZIMUTHS = 6
MARGIN_M = 0.5

SITE_GEOMETRY = {"respeaker6": "respeaker-6mic", "respeaker4": "respeaker-4mic"}


def survey_points(room_dim, array_xy):
    """The hover points, ENU m (room coordinates), layer by layer."""
    points = []
    heights = np.arange(1.5, room_dim[2] - 1.0 + 1e-9, 1.0)
    for layer, z in enumerate(heights):
        for d in DISTANCES_M:
            for k in range(AZIMUTHS):
                az = 2 * np.pi * (k + 0.5 * (layer % 2)) / AZIMUTHS
                p = np.array([array_xy[0] + d * np.cos(az), array_xy[1] + d * np.sin(az), z])
                if np.all(p > MARGIN_M) and np.all(p < np.array(room_dim) - MARGIN_M):
                    points.append(p)
    return points


def conditions(rt60s, arrays, rooms):
    """(array, room, rt60) as make_rooms.py pairs them (a room too large for the RT60 is left out)."""
    out = []
    for rt60 in rt60s:
        for array in arrays:
            for room in rooms:
                try:
                    pra.inverse_sabine(rt60, ROOMS[room][0])
                except ValueError:
                    continue
                out.append((array, room, rt60))
    return out


def make_survey(out, index, array, room_name, rt60, max_order):
    room_dim, array_xy = ROOMS[room_name]
    absorption, order = pra.inverse_sabine(rt60, room_dim)
    order = min(order, max_order)
    mics = np.array([[array_xy[0] + x, array_xy[1] + y, ARRAY_HEIGHT_M] for x, y in ARRAYS[array]]).T
    points = survey_points(room_dim, array_xy)
    hop = int(HOVER_S * FS)
    y = np.zeros((mics.shape[1], hop * len(points) + FS * 4))
    for k, p in enumerate(points):
        rng = np.random.default_rng(SURVEY_SEED + 1000 * index + k)
        room = pra.ShoeBox(room_dim, fs=FS, materials=pra.Material(absorption),
                           max_order=order, air_absorption=False)
        room.add_source(p.tolist(), signal=drone_signal(rng, HOVER_S))
        room.add_microphone_array(pra.MicrophoneArray(mics, FS))
        room.simulate()
        s = room.mic_array.signals
        n = min(s.shape[1], y.shape[1] - k * hop)
        y[:, k * hop:k * hop + n] += s[:, :n]
    y = y[:, :hop * len(points)]
    rng = np.random.default_rng(SURVEY_SEED + 1000 * index + 999)
    noise_rms = np.sqrt(np.mean(y ** 2, axis=1, keepdims=True)) * 10 ** (-25 / 20)
    y = y + rng.standard_normal(y.shape) * noise_rms
    os.makedirs(out, exist_ok=True)
    write_wav(os.path.join(out, "survey.wav"), y)
    with open(os.path.join(out, "reference.csv"), "w") as f:
        f.write("t,x,y,z\n")
        # A row every 0.05 s, as a tracking reference logs (aim calibrate interpolates between
        # rows no more than a few tenths of a second apart).
        for k, p in enumerate(points):
            for t in k * HOVER_S + np.arange(0.0, HOVER_S - 1e-9, 0.05):
                f.write(f"{t:.3f},{p[0]:.4f},{p[1]:.4f},{p[2]:.4f}\n")
        f.write(f"{len(points) * HOVER_S:.3f},{p[0]:.4f},{p[1]:.4f},{p[2]:.4f}\n")
    positions = ", ".join(f"[{x:.6f}, {y:.6f}]" for x, y in ARRAYS[array])
    with open(os.path.join(out, "site.toml"), "w") as f:
        f.write(f"""# {array} in pyroomacoustics' {room_name} ({room_dim[0]} x {room_dim[1]} x {room_dim[2]} m), RT60 {rt60} s (Sabine)
sample_rate_hz = {FS}
speed_of_sound_mps = {C}

[[array]]
id = 1
geometry = "{SITE_GEOMETRY[array]}"
positions = [{positions}]
position = [{array_xy[0]}, {array_xy[1]}, {ARRAY_HEIGHT_M}]
yaw_deg = 0.0
""")
    return len(points)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True)
    ap.add_argument("--rt60", default="0.3,0.6,1.0")
    ap.add_argument("--arrays", default="respeaker6,respeaker4")
    ap.add_argument("--rooms", default="hall20,hall24")
    ap.add_argument("--max-order", type=int, default=40)
    ap.add_argument("--host-sim", help="host-sim binary: make each survey's frames")
    ap.add_argument("--aim", help="aim binary: calibrate each survey's site")
    ap.add_argument("--keep-audio", action="store_true",
                    help="a survey whose survey.wav exists is not simulated again (another "
                         "host-sim build on the same surveys)")
    a = ap.parse_args()
    conds = conditions([float(x) for x in a.rt60.split(",")], a.arrays.split(","), a.rooms.split(","))
    for index, (array, room, rt60) in enumerate(conds):
        d = os.path.join(a.out, f"{array}-{room}-rt{rt60:.1f}")
        if a.keep_audio and os.path.exists(os.path.join(d, "survey.wav")):
            print(f"{d}: audio kept", flush=True)
        else:
            n = make_survey(d, index, array, room, rt60, a.max_order)
            print(f"{d}: {n} points, {n * HOVER_S:.0f} s", flush=True)
        if a.host_sim:
            subprocess.run([a.host_sim, "analyze", os.path.join(d, "survey.wav"), "--array", array,
                            "--frames", os.path.join(d, "frames-1.aimraw")],
                           check=True, stdout=subprocess.DEVNULL)
        if a.host_sim and a.aim:
            r = subprocess.run([a.aim, "calibrate", os.path.join(d, "frames-1.aimraw"),
                                "--reference", os.path.join(d, "reference.csv"),
                                "--site", os.path.join(d, "site.toml"),
                                "--out", os.path.join(d, "site-calibrated.toml")],
                               capture_output=True, text=True)
            print(r.stderr.strip(), flush=True)
            if r.returncode != 0:
                print(f"{d}: aim calibrate failed (exit {r.returncode})", flush=True)


if __name__ == "__main__":
    main()
