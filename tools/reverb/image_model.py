#!/usr/bin/env python3
"""Floor-ceiling image model of a planar array's zenith bias, checked against measured frames.

For each case of a tools/reverb directory (cases.jsonl + WAVs), the zenith of every 0.171 s
DoA frame is measured with the numpy model of the chip's spatial path (variants.py, mode
plain); the case's median bias is compared with the bias the vertical image series predicts:
the images of the source in the floor and the ceiling (heights z_s + 2kH and -z_s + 2kH, n
reflections, amplitude beta^n / r_i with beta = sqrt(1 - alpha)), their horizontal direction
cosines averaged with weights (beta^n / r_i)^p. Needs the source's true range: the model is a
measurement model for a tracker hypothesis, not a correction a single frame can apply.

    python3 tools/reverb/image_model.py --dir /tmp/reverb-tune --p 2,2.5,3
"""
import argparse, json, os, sys
import numpy as np
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import compare, variants  # noqa: E402

ARRAY_HEIGHT_M = 0.8


def predicted_zenith(zen_deg, r, height_m, beta, p, kmax=60):
    zen = np.radians(zen_deg)
    dh, zs = r * np.sin(zen), ARRAY_HEIGHT_M + r * np.cos(zen)
    num = den = 0.0
    for k in range(-kmax, kmax + 1):
        for img_z, n in ((zs + 2 * k * height_m, abs(2 * k)), (-zs + 2 * k * height_m, abs(2 * k - 1))):
            ri = np.hypot(dh, img_z - ARRAY_HEIGHT_M)
            w = (beta ** n / ri) ** p
            num += w * dh / ri
            den += w
    return np.degrees(np.arcsin(num / den))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dir", required=True)
    ap.add_argument("--p", default="3")
    a = ap.parse_args()
    ps = [float(x) for x in a.p.split(",")]
    rows = []
    for line in open(os.path.join(a.dir, "cases.jsonl")):
        c = json.loads(line)
        if c.get("var", "all") != "all":
            continue
        x = compare.read_wav(os.path.join(a.dir, c["name"] + ".wav"))
        pos = np.array(compare.ARRAYS[c["array"]])
        n = variants.N * variants.BLOCKS
        zs = [variants.estimate(x[:, s:s + n], pos, "plain")[1]
              for s in range(int(compare.SKIP_S * variants.FS), x.shape[1] - n + 1, n)]
        bias = float(np.median(zs)) - c["zenith_deg"]
        beta = np.sqrt(1 - c["absorption"])
        pred = [predicted_zenith(c["zenith_deg"], c["range_m"], c["room_dim"][2], beta, p) - c["zenith_deg"] for p in ps]
        rows.append((c["array"], c["rt60_target_s"], bias, pred))
    print("| array | RT60 | cases | median bias | " + " | ".join(f"median |bias - model p={p}|" for p in ps) + " |")
    print("|---|---|---|---|" + "---|" * len(ps))
    for key in sorted({(r[0], r[1]) for r in rows}):
        sel = [r for r in rows if (r[0], r[1]) == key]
        b = np.array([r[2] for r in sel])
        cells = [f"{np.median(np.abs(b - np.array([r[3][i] for r in sel]))):.1f}°" for i in range(len(ps))]
        print(f"| {key[0]} | {key[1]:.1f} s | {len(sel)} | {np.median(b):+.1f}° | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
