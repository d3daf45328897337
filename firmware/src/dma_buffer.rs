//! Statics in AXI SRAM: the DMA buffers (`.axisram`; AXI SRAM is a RAM the DMA1/DMA2
//! controllers can reach, DTCM, the default RAM of this firmware, is not) and the DSP state
//! (`.dsp_state`: the `aim_dsp::Pipeline`, 127 KB, which does not fit in DTCM beside the other
//! statics and the stack).
//!
//! Both output sections of the root `memory.x` are `NOLOAD`: the start-up code neither loads
//! nor zeroes them, so each static there is zero-filled at run time, once, by
//! [`axisram_buffer!`](crate::axisram_buffer) or [`dsp_state!`](crate::dsp_state), before the
//! single `&'static mut` to it is made. These, with the `u32` → `i32` view of a captured
//! chunk, are the firmware's `unsafe` blocks.
//!
//! The data cache stays off (`main` enables the instruction cache only), so DMA and CPU see the
//! same memory without cache maintenance (firmware/README.md, "Memory").

/// Types for which the all-zero bit pattern is a valid value (and which hold no pointers).
///
/// # Safety
/// Implement only for types whose every field, recursively, is an integer, a float, a `bool`
/// (zero is `false`; no invariant may tie it to other fields that zero bytes would break) or
/// an array of such: no enum, `Option`, reference, pointer, `NonZero` or `char`.
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

// SAFETY: audited field by field, recursively, against aim-dsp at commit 4a11571 (the last
// commit to dsp/ under fw14's 7ffb462), after the beacon detector and the snippets were added:
// `Pipeline` (dsp/src/pipeline.rs) holds `Config` (`Geometry`; `snippets: bool`), `Pair`,
// `DelayEstimate`, `Twiddles`, `FrontEnd` (`HalfBand`), `SpectralPath` (`Decimator`,
// `comb::History` with `missed: [bool; 4]`), `IdExtractor`, `GapStats`, `beacon::Detector`
// (`Picker` with `has_pending: bool`, `Lag`), microfft's `Complex32` (num-complex 0.4.6,
// `repr(C)` of two `f32`), and integers, floats, `bool`s and arrays of these; no enum,
// `Option`, reference, pointer, `NonZero` or `char`. All-zero is `false` for every `bool`, and
// no `bool` guards data zero would make inconsistent (`configured`, `beacon_on`,
// `has_pending`, `missed` all false: nothing pending, nothing configured). Zero bytes are an
// inert, unconfigured pipeline (`push` ignores input until `configured`); `Pipeline::configure`
// then sets every field whose zero differs from `Pipeline::empty()` (`config`, `front`,
// `decimation`, the `Decimator`'s `len`/`factor`/`end`, `mono_decimation`, the detector's
// `len`/`base` via `restart`). Re-audit when `Pipeline` or a type inside it gains a field.
unsafe impl ZeroIsValid for aim_dsp::Pipeline {}

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

/// Places a zero-filled `[$t; $len]` in AXI SRAM (`.axisram`, the DMA buffers) and returns
/// `&'static mut [$t; $len]`.
///
/// Each expansion owns one buffer; evaluating the same expansion twice panics (at start-up,
/// where all buffers are taken), so the returned reference is unique.
#[macro_export]
macro_rules! axisram_buffer {
    ($t:ty, $len:expr) => {
        $crate::zero_filled_static!(".axisram", [$t; $len], "an AXI SRAM buffer was taken twice")
    };
}

/// Places a zero-filled `$t` in AXI SRAM (`.dsp_state`: CPU state that is no DMA buffer) and
/// returns `&'static mut $t`. Same rules as [`axisram_buffer!`](crate::axisram_buffer).
#[macro_export]
macro_rules! dsp_state {
    ($t:ty) => {
        $crate::zero_filled_static!(".dsp_state", $t, "DSP state was taken twice")
    };
}

/// The body of [`axisram_buffer!`](crate::axisram_buffer) and [`dsp_state!`](crate::dsp_state):
/// a `MaybeUninit<$t>` static in the NOLOAD output section `$section`, zero-filled when taken.
#[doc(hidden)]
#[macro_export]
macro_rules! zero_filled_static {
    ($section:literal, $t:ty, $twice:literal) => {{
        #[unsafe(link_section = $section)]
        static mut SLOT: ::core::mem::MaybeUninit<$t> = ::core::mem::MaybeUninit::uninit();
        static TAKEN: ::core::sync::atomic::AtomicBool =
            ::core::sync::atomic::AtomicBool::new(false);
        if TAKEN.swap(true, ::core::sync::atomic::Ordering::AcqRel) {
            ::defmt::panic!($twice);
        }
        // SAFETY: TAKEN makes this the only reference ever created to SLOT.
        unsafe { $crate::dma_buffer::zero_fill(&mut *::core::ptr::addr_of_mut!(SLOT)) }
    }};
}
