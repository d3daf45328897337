//! Support for AIM's QEMU Cortex-M4F binaries (`mps2-an386`): semihosting output and exit,
//! a panic handler that fails the run, and the probe table the `insn_probe` plugin watches.
//!
//! Why a separate workspace and what the binaries check: see `tests/qemu/README.md`.
#![no_std]

use core::fmt::{self, Write};

use aim_golden::probe::{Probe, SLOTS};
use cortex_m_semihosting::{debug, hio};

// The probe table: one `bx lr` (2 bytes) per probe id. A call into slot `id` starts a
// translation block at `aim_probe_table + 2 * id`, which is how the plugin knows which probe
// ran; the call itself costs about five instructions.
core::arch::global_asm!(
    ".section .text.aim_probe_table,\"ax\",%progbits",
    ".global aim_probe_table",
    ".p2align 2",
    ".thumb",
    "aim_probe_table:",
    ".rept {slots}",
    "bx lr",
    ".endr",
    slots = const SLOTS,
);

extern "C" {
    static aim_probe_table: u8;
}

/// Marks `probe`: from here until the next probe, instructions are charged to it.
#[inline(always)]
pub fn probe(probe: Probe) {
    let slot = (&raw const aim_probe_table) as usize + 2 * probe.id();
    // SAFETY: `slot` is the address of a `bx lr` in the table above (id < SLOTS by
    // construction of `Probe`); the low bit selects Thumb state. The call returns at once and
    // touches no memory.
    let f: extern "C" fn() = unsafe { core::mem::transmute(slot | 1) };
    f();
}

/// The semihosting standard output (the QEMU process's stdout).
pub struct Out(hio::HostStream);

impl Out {
    /// Opens the host's standard output; exits with failure if semihosting is unavailable.
    pub fn open() -> Self {
        match hio::hstdout() {
            Ok(stream) => Out(stream),
            Err(()) => fail(),
        }
    }
}

impl Write for Out {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        self.0.write_all(s.as_bytes()).map_err(|()| fmt::Error)
    }
}

/// Ends the QEMU run with exit status 0.
pub fn succeed() -> ! {
    debug::exit(debug::EXIT_SUCCESS);
    #[allow(clippy::empty_loop)]
    loop {}
}

/// Ends the QEMU run with exit status 1.
pub fn fail() -> ! {
    debug::exit(debug::EXIT_FAILURE);
    #[allow(clippy::empty_loop)]
    loop {}
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    if let Ok(mut err) = hio::hstderr() {
        let _ = writeln!(Adapter(&mut err), "panic: {info}");
    }
    fail()
}

/// `fmt::Write` for a semihosting stream.
struct Adapter<'a>(&'a mut hio::HostStream);

impl Write for Adapter<'_> {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        self.0.write_all(s.as_bytes()).map_err(|()| fmt::Error)
    }
}

/// The word painted below the stack pointer by [`StackGauge::paint`].
const PAINT: u32 = 0xA5A5_5A5A;

/// Measures the peak stack depth of a piece of code: paints the free stack below the current
/// stack pointer, and later finds the lowest word that was overwritten.
#[derive(Debug)]
pub struct StackGauge {
    /// Stack pointer when painted.
    top: usize,
    /// Lowest painted address.
    bottom: usize,
}

impl StackGauge {
    /// Paints `depth` bytes below the current stack pointer (minus a small margin for this
    /// function's own frame). No interrupts run in these binaries, so nothing else uses that
    /// memory until the measured code does.
    #[inline(never)]
    pub fn paint(depth: usize) -> Self {
        let top = cortex_m::register::msp::read() as usize;
        let margin = 256;
        let bottom = (top - depth) & !3;
        let mut addr = bottom;
        while addr < top - margin {
            // SAFETY: [bottom, top − margin) is free stack (below every live frame, above the
            // end of RAM: `depth` is far smaller than the 4 MiB stack region), word-aligned.
            unsafe { core::ptr::write_volatile(addr as *mut u32, PAINT) };
            addr += 4;
        }
        StackGauge { top, bottom }
    }

    /// Bytes of stack used below the painting caller's stack pointer since [`StackGauge::paint`].
    pub fn used(&self) -> usize {
        let mut addr = self.bottom;
        // SAFETY: reads the painted, word-aligned region again.
        while addr < self.top && unsafe { core::ptr::read_volatile(addr as *const u32) } == PAINT {
            addr += 4;
        }
        self.top - addr
    }
}
