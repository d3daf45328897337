#!/usr/bin/env python3
"""Emulated start of an STM32H743 firmware ELF, from the reset vector to main's first
peripheral access (run by `cargo xtask boot`, so by CI).

The image is loaded as a flash programmer writes it (every PT_LOAD segment at its physical
address) into a Cortex-M7 (the unicorn engine) whose memory map is the STM32H743's: flash,
ITCM, DTCM, AXI SRAM, SRAM1-4, backup SRAM, system memory, the peripheral space
(0x4000_0000-0x5FFF_FFFF, plain memory) and the private peripheral bus. Nothing else is
mapped, so an access to the reserved space between them -- the zero loop of a `.bss` that runs
from DTCM into AXI SRAM, a stack pointer outside RAM, a wild vector -- stops the run with the
address and the instruction that made it.

SP and PC come from the vector table at 0x0800_0000 (BOOT0 low, the NUCLEO's default). The run
passes when the code reaches `main` (cortex-m-rt's entry trampoline) and then touches a
peripheral register: from there on the firmware talks to hardware this model does not have
(embassy polls RCC ready flags), and everything before it -- start-up code, RAM
initialisation, the FPU enable -- has run on the real memory map. It fails on an unmapped
access, a CPU exception, or when neither happens within the instruction limit.

Then the chip and clock probe (`aim_firmware::clocks::ClockPlan::probe`) that runs before
`embassy_stm32::init`: the run goes on from main's first peripheral access to embassy's first
register access (DBGMCU_CR), once per case below, with two registers given values (the rest
of the peripheral space stays plain memory):
- DBGMCU_IDCODE reads `REV_ID << 16 | 0x450` (revision V 0x2003, or revision Y 0x1003);
- RCC_CR reads HSERDY = HSEON (an external clock that starts at once), or HSERDY = 0 (no
  clock on OSC_IN: the probe must give up after its timeout instead of hanging).
Each case must reach embassy's init within the instruction limit; the probe must read the
IDCODE; HSEON must be on at that point with a clock and off without one (the fallback to the
HSI); where the image keeps the core-clock variable (`clocks::SYSCLK`), it must hold 480 MHz
for revision V and 400 MHz for revision Y.

usage: emulate_start.py ELF [ELF ...]      exit 0 when every image reaches main's first
                                           peripheral access, 1 otherwise.
"""
import sys

from elftools.elf.elffile import ELFFile
from unicorn import (UC_ARCH_ARM, UC_HOOK_CODE, UC_HOOK_INTR, UC_HOOK_MEM_READ,
                     UC_HOOK_MEM_UNMAPPED, UC_HOOK_MEM_WRITE, UC_MEM_FETCH_UNMAPPED,
                     UC_MEM_READ_UNMAPPED, UC_MEM_WRITE_UNMAPPED, UC_MODE_MCLASS,
                     UC_MODE_THUMB, Uc, UcError)
from unicorn.arm_const import UC_ARM_REG_PC, UC_ARM_REG_SP, UC_CPU_ARM_CORTEX_M7

# (name, start, size) of the STM32H743 memory map (RM0433, "Memory map").
REGIONS = [
    ("ITCM", 0x0000_0000, 0x1_0000),
    ("FLASH", 0x0800_0000, 0x20_0000),
    ("SYSTEM", 0x1FF0_0000, 0x2_0000),
    ("DTCM", 0x2000_0000, 0x2_0000),
    ("AXISRAM", 0x2400_0000, 0x8_0000),
    ("SRAM1-3", 0x3000_0000, 0x4_8000),
    ("SRAM4", 0x3800_0000, 0x1_0000),
    ("BKPSRAM", 0x3880_0000, 0x1000),
]
PERIPHERALS = ("PERIPH", 0x4000_0000, 0x2000_0000)
# The private peripheral bus (SCB, NVIC, SysTick, DWT, MPU): cortex-m-rt enables the FPU here.
PPB = ("PPB", 0xE000_0000, 0x10_0000)
INSTRUCTION_LIMIT = 20_000_000
FLASH_START = 0x0800_0000
DBGMCU_IDCODE = 0x5C00_1000
DBGMCU_CR = 0x5C00_1004
RCC_CR = 0x5802_4400
HSEON, HSERDY = 1 << 16, 1 << 17
# (revision id, external clock present, expected core clock in Hz)
PROBE_CASES = [(0x2003, True, 480_000_000), (0x2003, False, 480_000_000),
               (0x1003, True, 400_000_000)]


def region_name(address):
    for name, start, size in REGIONS + [PERIPHERALS, PPB]:
        if start <= address < start + size:
            return name
    return "unmapped"


def emulate(path, case=None):
    """The start of `path` to main's first peripheral access (case None), or, for a probe
    case `(rev_id, hse, sysclk)`, on to embassy's init; returns a failure message or None."""
    with open(path, "rb") as f:
        elf = ELFFile(f)
        symbols = {s.name: s["st_value"] for s in elf.get_section_by_name(".symtab").iter_symbols()}
        segments = [(seg["p_paddr"], seg.data()) for seg in elf.iter_segments()
                    if seg["p_type"] == "PT_LOAD" and seg["p_filesz"] > 0]
    if "main" not in symbols:
        return f"{path}: no `main` symbol"
    main = symbols["main"] & ~1
    sysclk_var = next((v for n, v in symbols.items() if "6clocks6SYSCLK" in n), None)

    uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
    uc.ctl_set_cpu_model(UC_CPU_ARM_CORTEX_M7)
    for _, start, size in REGIONS + [PERIPHERALS]:
        uc.mem_map(start, size)
    try:
        uc.mem_map(PPB[1], PPB[2])
    except UcError:
        pass  # the engine models the PPB itself
    flash_end = FLASH_START + 0x20_0000
    for paddr, data in segments:
        if not (FLASH_START <= paddr and paddr + len(data) <= flash_end):
            return f"{path}: load segment at {paddr:#010x} ({len(data)} bytes) is not in flash"
        uc.mem_write(paddr, data)

    sp = int.from_bytes(uc.mem_read(FLASH_START, 4), "little")
    reset = int.from_bytes(uc.mem_read(FLASH_START + 4, 4), "little")
    state = {"main": False, "done": None, "fault": None, "count": 0, "idcode": False,
             "init": False}

    def on_code(uc, address, size, _):
        state["count"] += 1
        if address == main and not state["main"]:
            state["main"] = True
            if case is None:
                print(f"  reached main at {address:#010x} after {state['count']} instructions")

    def on_peripheral(uc, access, address, size, value, _):
        if not state["main"]:
            return
        if state["done"] is None:
            pc = uc.reg_read(UC_ARM_REG_PC)
            kind = "write" if access == UC_HOOK_MEM_WRITE else "access"
            state["done"] = f"main's first peripheral {kind}: {address:#010x} at pc {pc:#010x}"
            if case is None:
                uc.emu_stop()
                return
        rev_id, hse, _ = case
        # A read hook runs before the read: what it writes is what the code reads.
        if access != UC_HOOK_MEM_WRITE and address == DBGMCU_IDCODE:
            state["idcode"] = True
            uc.mem_write(DBGMCU_IDCODE, ((rev_id << 16) | 0x450).to_bytes(4, "little"))
        elif access != UC_HOOK_MEM_WRITE and RCC_CR <= address < RCC_CR + 4:
            cr = int.from_bytes(uc.mem_read(RCC_CR, 4), "little")
            cr = (cr | HSERDY) if hse and cr & HSEON else (cr & ~HSERDY)
            uc.mem_write(RCC_CR, cr.to_bytes(4, "little"))
        elif address == DBGMCU_CR and state["idcode"]:
            state["init"] = True
            uc.emu_stop()

    def on_unmapped(uc, access, address, size, value, _):
        pc = uc.reg_read(UC_ARM_REG_PC)
        kind = {UC_MEM_READ_UNMAPPED: "read", UC_MEM_WRITE_UNMAPPED: "write",
                UC_MEM_FETCH_UNMAPPED: "fetch"}.get(access, "access")
        state["fault"] = (f"{kind} of unmapped {address:#010x} (reserved space) at pc "
                          f"{pc:#010x} after {state['count']} instructions: a bus fault on the "
                          f"board")
        return False

    def on_interrupt(uc, number, _):
        pc = uc.reg_read(UC_ARM_REG_PC)
        state["fault"] = f"CPU exception {number} at pc {pc:#010x} after {state['count']} instructions"
        uc.emu_stop()

    uc.hook_add(UC_HOOK_CODE, on_code)
    uc.hook_add(UC_HOOK_MEM_READ | UC_HOOK_MEM_WRITE, on_peripheral,
                begin=PERIPHERALS[1], end=PERIPHERALS[1] + PERIPHERALS[2] - 1)
    uc.hook_add(UC_HOOK_MEM_UNMAPPED, on_unmapped)
    uc.hook_add(UC_HOOK_INTR, on_interrupt)
    uc.reg_write(UC_ARM_REG_SP, sp)
    print(f"{path}: SP {sp:#010x} ({region_name(sp - 4)}), reset vector {reset:#010x}")
    try:
        uc.emu_start(reset | 1, 0xFFFF_FFFF, count=INSTRUCTION_LIMIT)
    except UcError as error:
        if state["fault"] is None:
            pc = uc.reg_read(UC_ARM_REG_PC)
            state["fault"] = f"{error} at pc {pc:#010x} after {state['count']} instructions"
    if state["fault"]:
        where = "before main" if not state["main"] else "after main"
        return f"{path}: {where}: {state['fault']}"
    if case is not None:
        rev_id, hse, sysclk = case
        label = f"probe (REV_ID {rev_id:#06x}, {'with' if hse else 'without'} HSE)"
        if not state["init"]:
            return (f"{path}: {label}: embassy's init not reached within {INSTRUCTION_LIMIT} "
                    f"instructions (IDCODE read: {state['idcode']})")
        hseon = bool(int.from_bytes(uc.mem_read(RCC_CR, 4), "little") & HSEON)
        if hseon != hse:
            return f"{path}: {label}: HSEON is {'on' if hseon else 'off'} at embassy's init"
        note = ""
        if sysclk_var is not None:
            chosen = int.from_bytes(uc.mem_read(sysclk_var, 4), "little")
            if chosen != sysclk:
                return f"{path}: {label}: core clock {chosen} Hz, expected {sysclk}"
            note = f", core clock {chosen} Hz"
        print(f"  {label}: embassy's init reached after {state['count']} instructions, "
              f"HSE {'on' if hseon else 'off (HSI fallback)'}{note}")
        return None
    if state["done"]:
        print(f"  {state['done']}: start-up ok")
        return None
    if not state["main"]:
        return f"{path}: main not reached within {INSTRUCTION_LIMIT} instructions"
    return f"{path}: no peripheral access within {INSTRUCTION_LIMIT} instructions after main"


def main(paths):
    if not paths:
        print(__doc__.strip().splitlines()[-2], file=sys.stderr)
        return 2
    failures = []
    for path in paths:
        failure = emulate(path)
        if failure is None:
            failures.extend(f for f in (emulate(path, case) for case in PROBE_CASES) if f)
        else:
            failures.append(failure)
    for failure in failures:
        print(f"emulated start FAILED: {failure}", file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
