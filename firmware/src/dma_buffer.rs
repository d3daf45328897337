//! Buffers in AXI SRAM, the RAM the DMA1/DMA2 controllers can reach (DTCM, the default RAM of
//! this firmware, is not reachable by them).
//!
//! The `.axisram` output section of the root `memory.x` is `NOLOAD`: the start-up code neither
//! loads nor zeroes it, so a buffer there is zero-filled at run time, once, by
//! [`axisram_buffer!`](crate::axisram_buffer), before the single `&'static mut` to it is made.
//! These, and the zero-initialised `Pipeline` static (see [`assume_zeroed`]), are the
//! firmware's `unsafe` blocks, with the `u32` → `i32` view of a captured chunk.
//!
//! The data cache stays off (`main` enables the instruction cache only), so DMA and CPU see the
//! same memory without cache maintenance.

/// Types for which the all-zero bit pattern is a valid value (and which hold no pointers).
///
/// # Safety
/// Implement only for types whose every field is an integer or an array of such.
pub unsafe trait ZeroIsValid {}
// SAFETY: plain integers: every bit pattern, zero included, is a valid value.
unsafe impl ZeroIsValid for u8 {}
// SAFETY: as above.
unsafe impl ZeroIsValid for u32 {}
// SAFETY: as above.
unsafe impl ZeroIsValid for i32 {}
// SAFETY: as above.
unsafe impl ZeroIsValid for u64 {}
// SAFETY: `Chunk` is an array of u32 and a u64 (`repr(C)`), nothing else.
unsafe impl ZeroIsValid for crate::capture::Chunk {}
// SAFETY: an array of zero-valid elements is zero-valid.
unsafe impl<T: ZeroIsValid, const N: usize> ZeroIsValid for [T; N] {}

// SAFETY: audited against aim-dsp at commit d468704 and again after `GapStats` was added:
// every field of `Pipeline`, recursively (`Config`, `Geometry`, `Pair`, `DelayEstimate`,
// `FrontEnd`, `SpectralPath`, `Decimator`, `GapStats`, microfft's `Complex32`), is an integer,
// a float, a `bool` or an array of those; no enum,
// reference, `NonZero` or `Option`. Zero bytes are an inert, unconfigured pipeline that
// `Pipeline::configure` then sets up. Re-audit when `Pipeline` gains a field.
unsafe impl ZeroIsValid for aim_dsp::Pipeline {}

/// The `T` in a static initialised with `MaybeUninit::zeroed()` (such a static sits in `.bss`,
/// which the start-up code zeroes: neither stack nor flash holds a copy).
///
/// # Safety
/// Every byte of `*slot` must be zero (nothing has written to it since start-up).
pub unsafe fn assume_zeroed<T: ZeroIsValid>(
    slot: &'static mut core::mem::MaybeUninit<T>,
) -> &'static mut T {
    // SAFETY: the bytes are zero (caller) and all-zero is a valid `T` (ZeroIsValid).
    unsafe { slot.assume_init_mut() }
}

/// Zero-fills `slot` and returns it as an initialised `&'static mut T`.
///
/// # Safety
/// `slot` must not be referenced anywhere else, ever (the macro guarantees it with a flag).
#[doc(hidden)]
pub unsafe fn zero_fill<T: ZeroIsValid>(
    slot: &'static mut core::mem::MaybeUninit<T>,
) -> &'static mut T {
    // SAFETY: `slot` is valid for writes of one `T`; all-zero is a valid `T` (ZeroIsValid), so
    // after the fill the value is initialised.
    unsafe {
        core::ptr::write_bytes(slot.as_mut_ptr(), 0, 1);
        slot.assume_init_mut()
    }
}

/// Places a zero-filled `[$t; $len]` in AXI SRAM and returns `&'static mut [$t; $len]`.
///
/// Each expansion owns one buffer; evaluating the same expansion twice panics (at start-up,
/// where all buffers are taken), so the returned reference is unique.
#[macro_export]
macro_rules! axisram_buffer {
    ($t:ty, $len:expr) => {{
        #[unsafe(link_section = ".axisram")]
        static mut BUFFER: ::core::mem::MaybeUninit<[$t; $len]> =
            ::core::mem::MaybeUninit::uninit();
        static TAKEN: ::core::sync::atomic::AtomicBool =
            ::core::sync::atomic::AtomicBool::new(false);
        if TAKEN.swap(true, ::core::sync::atomic::Ordering::AcqRel) {
            ::defmt::panic!("an AXI SRAM buffer was taken twice");
        }
        // SAFETY: TAKEN makes this the only reference ever created to BUFFER.
        unsafe { $crate::dma_buffer::zero_fill(&mut *::core::ptr::addr_of_mut!(BUFFER)) }
    }};
}
