#!/usr/bin/env python3
"""Instructions `Pipeline::configure` spends in the beacon template's synthesis, estimated
from the firmware ELF (BENCHMARKS.md "Firmware"; needs unicorn and pyelftools, as
`cargo xtask boot`).

`aim_dsp::beacon::Detector::configure` calls `beacon::waveform_at(t: f64)` once per tap of every
template lag it filters; the firmware target has no double-precision FPU, so each call runs
libm's `sin`/`cos`/`fmod` in software. This script emulates the ELF's start-up code to `main`
(unicorn, Cortex-M7; the FPU is then enabled), calls the ELF's own `waveform_at` for 300
integer arguments in (0, LEN) (the template's arguments are integers), checks each result
against a float64 reimplementation of the waveform, and multiplies the mean instruction
count by the number of calls `configure` makes (its loop bounds, replicated below from
dsp/src/beacon.rs at aim-dsp 4a11571).

usage: waveform_cost.py ELF
"""
import math
import random
import struct
import sys

from elftools.elf.elffile import ELFFile
from unicorn import UC_ARCH_ARM, UC_HOOK_CODE, UC_MODE_MCLASS, UC_MODE_THUMB, Uc, UcError
from unicorn.arm_const import (UC_ARM_REG_D0, UC_ARM_REG_LR, UC_ARM_REG_PC, UC_ARM_REG_SP,
                               UC_CPU_ARM_CORTEX_M7)

# dsp/src/beacon.rs
CHIPS, CHIP_SAMPLES = 127, 24
PULSE = 2 * CHIP_SAMPLES
LEN = (CHIPS - 1) * CHIP_SAMPLES + PULSE
DECIMATION, TAPS = 12, PULSE
TEMPLATE_LEN = (LEN - 1 + TAPS - 1) // DECIMATION + 1
OFFSETS = DECIMATION // 2


def chips():
    out, state = [], 0x7F
    for _ in range(CHIPS):
        out.append(1 if state & 1 else -1)
        bit = (state ^ (state >> 1)) & 1
        state = (state >> 1) | (bit << 6)
    return out


CHIP_TABLE = chips()


def waveform(t):
    if not 0 < t < LEN:
        return 0.0
    hi, env = int(math.floor(t / CHIP_SAMPLES)), 0.0
    for k in (hi - 1, hi):
        if 0 <= k < CHIPS and 0 <= t - CHIP_SAMPLES * k < PULSE:
            s = math.sin(math.pi * (t - CHIP_SAMPLES * k) / PULSE)
            env += CHIP_TABLE[k] * s * s
    return env * math.cos(0.75 * math.pi * math.fmod(t, 8.0))


def calls():
    """waveform_at calls of Detector::configure: the template (d = 0), then the coarse table
    (offsets d = -OFFSETS..=OFFSETS, lags -1..=1), each lag filtered over taps 1..TAPS."""
    def filtered(d, m):
        return sum(1 for k in range(1, TAPS) if 0 < DECIMATION * m - k - d < LEN)
    template = sum(filtered(0, m) for m in range(TEMPLATE_LEN))
    table = sum(filtered(i - OFFSETS, m + j - 1) for i in range(2 * OFFSETS + 1)
                for j in range(3) for m in range(TEMPLATE_LEN))
    return template + table


def main(path):
    with open(path, "rb") as f:
        elf = ELFFile(f)
        symbols = {s.name: s["st_value"] for s in elf.get_section_by_name(".symtab").iter_symbols()}
        segments = [(s["p_paddr"], s.data()) for s in elf.iter_segments()
                    if s["p_type"] == "PT_LOAD" and s["p_filesz"] > 0]
    wave = next(v for n, v in symbols.items() if "6beacon11waveform_at" in n) & ~1
    main_fn = symbols["main"] & ~1
    uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
    uc.ctl_set_cpu_model(UC_CPU_ARM_CORTEX_M7)
    for start, size in [(0, 0x1_0000), (0x0800_0000, 0x20_0000), (0x2000_0000, 0x2_0000),
                        (0x2400_0000, 0x8_0000), (0x4000_0000, 0x2000_0000)]:
        uc.mem_map(start, size)
    try:
        uc.mem_map(0xE000_0000, 0x10_0000)
    except UcError:
        pass
    for paddr, data in segments:
        uc.mem_write(paddr, data)
    sp, reset = struct.unpack("<II", uc.mem_read(0x0800_0000, 8))
    uc.reg_write(UC_ARM_REG_SP, sp)
    uc.emu_start(reset | 1, main_fn, count=5_000_000)
    assert uc.reg_read(UC_ARM_REG_PC) & ~1 == main_fn, "main not reached"
    count = [0]
    uc.hook_add(UC_HOOK_CODE, lambda *_: count.__setitem__(0, count[0] + 1))
    ret = 0x100  # in ITCM: a return address outside the image
    uc.mem_write(ret, b"\x00\xbf\x00\xbf")
    rng = random.Random(1)
    counts = []
    for t in (float(rng.randint(1, LEN - 1)) for _ in range(300)):
        uc.reg_write(UC_ARM_REG_D0, struct.unpack("<Q", struct.pack("<d", t))[0])
        uc.reg_write(UC_ARM_REG_SP, 0x2001_F000)
        uc.reg_write(UC_ARM_REG_LR, ret | 1)
        count[0] = 0
        uc.emu_start(wave | 1, ret, count=10_000_000)
        got = struct.unpack("<d", struct.pack("<Q", uc.reg_read(UC_ARM_REG_D0)))[0]
        if abs(got - waveform(t)) > 1e-9:
            sys.exit(f"waveform_at({t}) = {got}, expected {waveform(t)}")
        counts.append(count[0])
    mean, n = sum(counts) / len(counts), calls()
    print(f"waveform_at: {mean:.0f} instructions per call (mean of {len(counts)}, "
          f"min {min(counts)}, max {max(counts)}); {n} calls in Detector::configure; "
          f"{mean * n / 1e9:.2f} G instructions")


if __name__ == "__main__":
    main(sys.argv[1])
