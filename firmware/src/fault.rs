//! Faults: a panic or a hard fault is logged, recorded in RAM that the reset keeps, and the
//! board resets; the next start reports it in `Hello` ([`crate::boot`]). A stack overflow hits
//! an MPU guard region and becomes such a fault instead of silently overwriting the statics.
//!
//! - **Retained cell**: [`Retained`] lives in cortex-m-rt's `.uninit` section (DTCM, `NOLOAD`):
//!   the start-up code neither loads nor zeroes it, and a system reset (software, watchdog,
//!   pin) leaves the RAM as it was. It holds the boot count and the last fault's message,
//!   guarded by a magic word (which also names the layout) and a CRC-32, so garbage after a
//!   power-on, or a record of another layout, is never taken for a report.
//! - **Panic** ([`panicked`]): the message (`file:line message`, the path cut to its last two
//!   parts, the whole cut to [`MESSAGE_LEN`] bytes) goes to the cell and to the defmt log,
//!   then the core resets (`SCB::sys_reset`). Debug builds with a debugger attached halt on a
//!   breakpoint first, so probe-rs shows where. A `defmt::panic!` has no text on the chip (its
//!   message is interned for the host), so it records `defmt panic (message in the RTT log)`.
//! - **Hard fault** (every fault: the configurable ones are not enabled, so they escalate): the
//!   handler first moves the stack pointer back to the top of the stack (an overflow may have
//!   left it in the guard), then records the faulting PC, or "stack overflow" when the stack
//!   pointer was at or below the guard, and resets.
//! - **Stack guard** ([`install_stack_guard`]): MPU region 0, 32 bytes, no access, at the
//!   stack's lowest address (`_stack_end` rounded up to 32 bytes, above every static). The
//!   stack grows down into it and faults there. Other addresses keep the default memory map
//!   (PRIVDEFENA); the MPU is off inside the hard-fault handler (HFNMIENA = 0).
//!
//! The handlers themselves are defined in the binary by [`fault_handlers!`](crate::fault_handlers).
use core::fmt::Write;
use core::sync::atomic::{AtomicBool, Ordering};

/// Most bytes of a fault message kept across the reset (what a `Hello` can carry).
pub const MESSAGE_LEN: usize = aim_wire::MAX_PANIC_MESSAGE;

/// Size of the MPU stack guard region, bytes (the smallest region of the ARMv7-M MPU).
pub const STACK_GUARD_BYTES: u32 = 32;

/// The guard's size as a symbol in the image, for a check of the ELF: an image that installs
/// the guard has `AIM_STACK_GUARD_BYTES` (= 32; the guard itself is
/// `[align_up(_stack_end, 32), + 32)`, set up at run time by [`install_stack_guard`]).
#[used]
#[unsafe(no_mangle)]
pub static AIM_STACK_GUARD_BYTES: u32 = STACK_GUARD_BYTES;

/// Magic word of a valid [`Retained`] cell: "AIM" and the layout version 1.
const MAGIC: u32 = 0x4149_4d01;

/// What ended the previous run, as the retained cell records it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum Fault {
    /// Nothing recorded (a reset the firmware did not cause, or a power-on).
    None,
    /// A panic.
    Panic,
    /// A hard fault (a stack overflow into the guard included).
    HardFault,
}

impl Fault {
    fn code(self) -> u32 {
        match self {
            Fault::None => 0,
            Fault::Panic => 1,
            Fault::HardFault => 2,
        }
    }

    fn from_code(code: u32) -> Fault {
        match code {
            1 => Fault::Panic,
            2 => Fault::HardFault,
            _ => Fault::None,
        }
    }
}

/// The retained cell's contents.
#[derive(Debug, Clone, Copy)]
#[repr(C)]
pub struct Retained {
    magic: u32,
    /// Starts since power-on (this one included, once [`start_boot`] ran).
    pub boot_count: u32,
    fault: u32,
    len: u32,
    message: [u8; MESSAGE_LEN],
    crc: u32,
}

const WORDS: usize = core::mem::size_of::<Retained>() / 4;
const _: () = assert!(core::mem::size_of::<Retained>() == WORDS * 4);

#[unsafe(link_section = ".uninit.aim_retained")]
static mut RETAINED: core::mem::MaybeUninit<[u32; WORDS]> = core::mem::MaybeUninit::uninit();

impl Retained {
    fn empty(boot_count: u32) -> Self {
        Self { magic: MAGIC, boot_count, fault: 0, len: 0, message: [0; MESSAGE_LEN], crc: 0 }
    }

    fn compute_crc(&self) -> u32 {
        let words = self.to_words();
        let mut bytes = [0u8; (WORDS - 1) * 4];
        for (chunk, w) in bytes.chunks_exact_mut(4).zip(&words[..WORDS - 1]) {
            chunk.copy_from_slice(&w.to_le_bytes());
        }
        aim_wire::crc32(&bytes)
    }

    fn to_words(self) -> [u32; WORDS] {
        // SAFETY: `Retained` is `repr(C)`, made of u32s and a u8 array whose length is a
        // multiple of 4 (checked above): no padding, every byte initialised.
        unsafe { core::mem::transmute::<Retained, [u32; WORDS]>(self) }
    }

    fn from_words(words: [u32; WORDS]) -> Self {
        // SAFETY: every bit pattern is a valid `Retained` (integers and bytes only).
        unsafe { core::mem::transmute::<[u32; WORDS], Retained>(words) }
    }

    /// The fault this record reports.
    pub fn fault(&self) -> Fault {
        Fault::from_code(self.fault)
    }

    /// The recorded message (empty if none or not valid UTF-8).
    pub fn message(&self) -> &str {
        let len = (self.len as usize).min(MESSAGE_LEN);
        core::str::from_utf8(&self.message[..len]).unwrap_or("")
    }
}

fn load() -> Retained {
    let mut words = [0u32; WORDS];
    let cell = core::ptr::addr_of!(RETAINED).cast::<u32>();
    for (i, w) in words.iter_mut().enumerate() {
        // SAFETY: in bounds of the static; volatile because the RAM holds what the previous
        // run (or the power-on) left there, which the compiler cannot know.
        *w = unsafe { core::ptr::read_volatile(cell.add(i)) };
    }
    Retained::from_words(words)
}

fn store(mut record: Retained) {
    record.magic = MAGIC;
    record.crc = record.compute_crc();
    let cell = core::ptr::addr_of_mut!(RETAINED).cast::<u32>();
    for (i, w) in record.to_words().iter().enumerate() {
        // SAFETY: in bounds of the static; single core, and the writers are start-up code
        // (before any task) and the fault handlers (interrupts off, then reset).
        unsafe { core::ptr::write_volatile(cell.add(i), *w) };
    }
}

/// The valid record the previous run left, if any.
fn previous() -> Option<Retained> {
    let record = load();
    (record.magic == MAGIC && record.crc == record.compute_crc()).then_some(record)
}

/// Reads what the previous run left (if `power_on` is false and the cell is valid) and starts
/// this run's record: boot count one more than the previous (1 after a power-on or without a
/// valid cell), no fault. Returns the previous record and this run's boot count. Call once,
/// first thing at start-up.
pub fn start_boot(power_on: bool) -> (Option<Retained>, u32) {
    let previous = if power_on { None } else { previous() };
    let boot_count = previous.map_or(1, |p| p.boot_count.wrapping_add(1).max(1));
    store(Retained::empty(boot_count));
    (previous, boot_count)
}

/// Records `fault` with `message` in the retained cell, keeping the boot count.
pub fn record(fault: Fault, message: &str) {
    let boot_count = previous().map_or(0, |p| p.boot_count);
    let mut record = Retained::empty(boot_count);
    record.fault = fault.code();
    let bytes = message.as_bytes();
    let len = bytes.len().min(MESSAGE_LEN);
    record.message[..len].copy_from_slice(&bytes[..len]);
    record.len = len as u32;
    store(record);
}

/// A fixed buffer that `core::fmt` writes into, cutting at a character boundary when full.
#[derive(Debug)]
pub struct MessageBuffer {
    bytes: [u8; MESSAGE_LEN],
    len: usize,
}

impl MessageBuffer {
    /// An empty buffer.
    pub const fn new() -> Self {
        Self { bytes: [0; MESSAGE_LEN], len: 0 }
    }

    /// What was written.
    pub fn as_str(&self) -> &str {
        core::str::from_utf8(&self.bytes[..self.len]).unwrap_or("")
    }
}

impl Default for MessageBuffer {
    fn default() -> Self {
        Self::new()
    }
}

impl Write for MessageBuffer {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        let room = MESSAGE_LEN - self.len;
        let mut take = s.len().min(room);
        while !s.is_char_boundary(take) {
            take -= 1;
        }
        self.bytes[self.len..self.len + take].copy_from_slice(&s.as_bytes()[..take]);
        self.len += take;
        Ok(())
    }
}

/// The last two components of a source path (`src/capture.rs` of
/// `/home/x/.cargo/registry/.../src/capture.rs`): the part that fits a short message.
pub fn short_path(path: &str) -> &str {
    let mut cut = path.len();
    for _ in 0..2 {
        match path.get(..cut).and_then(|head| head.rfind('/')) {
            Some(i) => cut = i,
            None => return path,
        }
    }
    // `cut` is the index of a '/', so `cut + 1` is a character boundary.
    path.get(cut + 1..).unwrap_or(path)
}

static PANICKING: AtomicBool = AtomicBool::new(false);

/// The panic handler's body: records `file:line message`, logs it, resets (see the module
/// docs). A panic while handling a panic resets at once.
pub fn panicked(info: &core::panic::PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    if PANICKING.swap(true, Ordering::Relaxed) {
        cortex_m::peripheral::SCB::sys_reset();
    }
    let mut message = MessageBuffer::new();
    if let Some(location) = info.location() {
        let _ = write!(message, "{}:{} ", short_path(location.file()), location.line());
    }
    // Only a message without arguments: formatting any panic's arguments (`{}` of the
    // `PanicMessage`) links every formatter a panic site uses, 17 KB of flash measured.
    if let Some(text) = info.message().as_str() {
        let _ = message.write_str(text);
    }
    record(Fault::Panic, message.as_str());
    defmt::error!("panic: {=str}; resetting", message.as_str());
    halt_if_debugging();
    cortex_m::peripheral::SCB::sys_reset()
}

/// The body of `defmt`'s panic handler (`defmt::panic!`, `defmt::unwrap!`, …): the message was
/// logged by defmt and has no text on the chip.
pub fn defmt_panicked() -> ! {
    cortex_m::interrupt::disable();
    PANICKING.store(true, Ordering::Relaxed);
    record(Fault::Panic, "defmt panic (message in the RTT log)");
    halt_if_debugging();
    cortex_m::peripheral::SCB::sys_reset()
}

/// In debug builds with a debugger attached, stops on a breakpoint (probe-rs shows where).
fn halt_if_debugging() {
    if cfg!(debug_assertions) && cortex_m::peripheral::DCB::is_debugger_attached() {
        cortex_m::asm::bkpt();
    }
}

unsafe extern "C" {
    static _stack_end: u32;
    static _stack_start: u32;
}

/// Lowest address of the MPU stack guard region: `_stack_end` rounded up to 32 bytes.
pub fn stack_guard_base() -> u32 {
    // Linker-script symbol: only its address is taken.
    let end = core::ptr::addr_of!(_stack_end) as u32;
    (end + STACK_GUARD_BYTES - 1) & !(STACK_GUARD_BYTES - 1)
}

/// Lowest address of the stack the firmware may use (just above the guard).
pub fn stack_bottom() -> u32 {
    stack_guard_base() + STACK_GUARD_BYTES
}

/// Initial stack pointer, the top of the stack (`_stack_start`).
pub fn stack_top() -> u32 {
    // Linker-script symbol: only its address is taken.
    core::ptr::addr_of!(_stack_start) as u32
}

/// Installs the stack guard (see the module docs) and enables the MPU. Call once at start-up,
/// while the stack is still shallow.
pub fn install_stack_guard(mpu: &mut cortex_m::peripheral::MPU) {
    const CTRL_ENABLE: u32 = 1;
    const CTRL_PRIVDEFENA: u32 = 1 << 2;
    const RASR_ENABLE: u32 = 1;
    const RASR_SIZE_32B: u32 = 4 << 1; // 2^(4 + 1) bytes
    const RASR_AP_NONE: u32 = 0 << 24;
    const RASR_XN: u32 = 1 << 28;
    let base = stack_guard_base();
    // Keeps the marker symbol in the image (and reads it, so the two cannot disagree).
    // SAFETY: a plain read of an immutable static (volatile: a real reference to it).
    let size = unsafe { core::ptr::read_volatile(core::ptr::addr_of!(AIM_STACK_GUARD_BYTES)) };
    debug_assert_eq!(size, STACK_GUARD_BYTES);
    cortex_m::asm::dsb();
    // SAFETY: region 0 is the only region; it covers 32 bytes no code or data uses (between
    // the last static and the stack in use, which is far above at start-up).
    unsafe {
        mpu.ctrl.write(0);
        mpu.rnr.write(0);
        mpu.rbar.write(base);
        mpu.rasr.write(RASR_XN | RASR_AP_NONE | RASR_SIZE_32B | RASR_ENABLE);
        mpu.ctrl.write(CTRL_PRIVDEFENA | CTRL_ENABLE);
    }
    cortex_m::asm::dsb();
    cortex_m::asm::isb();
}

/// The hard-fault handler's body, entered from the `HardFault` of
/// [`fault_handlers!`](crate::fault_handlers) with a fresh stack and the stack pointer at the
/// fault, `sp` (where the core stacked the faulting context, unless it overflowed).
///
/// # Safety
/// Only the `HardFault` vector may call this.
pub unsafe extern "C" fn hard_fault(sp: u32) -> ! {
    let mut message = MessageBuffer::new();
    if sp < stack_bottom() + 32 || sp > stack_top() {
        let _ = write!(message, "hard fault: stack overflow (sp {:#010x})", sp);
    } else {
        // SAFETY: `sp` lies inside the stack (checked above); the core stacked r0-r3, r12, lr,
        // pc, xpsr there, pc at +24.
        let pc = unsafe { core::ptr::read_volatile((sp + 24) as *const u32) };
        // SAFETY: CFSR is a read-only view of fault status for this read.
        let cfsr = unsafe { (*cortex_m::peripheral::SCB::PTR).cfsr.read() };
        let _ = write!(message, "hard fault: pc {:#010x} cfsr {:#010x}", pc, cfsr);
    }
    record(Fault::HardFault, message.as_str());
    defmt::error!("{=str}; resetting", message.as_str());
    cortex_m::peripheral::SCB::sys_reset()
}

/// Defines, in a firmware binary, the panic handler, defmt's panic handler and the `HardFault`
/// vector of this module: record, log, reset. (A library cannot define them: a binary may
/// choose another handler, as the `tests/hil` binaries do with panic-probe.)
#[macro_export]
macro_rules! fault_handlers {
    () => {
        #[panic_handler]
        fn panic(info: &::core::panic::PanicInfo) -> ! {
            $crate::fault::panicked(info)
        }

        #[::defmt::panic_handler]
        fn defmt_panic() -> ! {
            $crate::fault::defmt_panicked()
        }

        /// The hard-fault vector: moves the stack pointer back to the top of the stack (a
        /// stack overflow leaves it in the guard) before any Rust code runs, then records and
        /// resets in `aim_firmware::fault::hard_fault`.
        #[unsafe(naked)]
        #[unsafe(no_mangle)]
        unsafe extern "C" fn HardFault() -> ! {
            ::core::arch::naked_asm!(
                "mrs r0, MSP",
                "ldr r1, =_stack_start",
                "msr MSP, r1",
                "b {handler}",
                handler = sym $crate::fault::hard_fault,
            )
        }
    };
}
