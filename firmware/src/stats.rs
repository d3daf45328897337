//! Counters the streaming tasks update and the `Health` frame reports, and the DWT cycle
//! counter used to time the DSP.
//!
//! Counters are atomics because the capture and uplink tasks run on an interrupt executor and
//! the DSP task in thread mode. They only count up (wrapping) so a host can difference them.
use core::sync::atomic::{AtomicU32, Ordering};

/// Event counters shared by the capture, DSP and uplink tasks. Each loss has its own counter,
/// and every one of them is in `Health` (the gap counters come from the pipeline itself).
#[derive(Debug)]
pub struct Counters {
    /// DMA ring overruns: the ring wrapped before the capture task read it (each one restarted
    /// the capture driver; the samples lost are a gap).
    pub dma_overruns: AtomicU32,
    /// SAI FIFO overruns: the SAI's own overrun flag, read and cleared after every chunk (each
    /// one restarted the capture driver: the slot order of the frames after it is unknown).
    pub sai_overruns: AtomicU32,
    /// Chunks the capture task discarded because the DSP task had no free queue slot (DSP
    /// overload; each is a gap of `CHUNK_FRAMES` frames, and capture keeps running).
    pub dsp_overloads: AtomicU32,
    /// Capture chunks handed to the DSP task (each `CHUNK_FRAMES` frames).
    pub chunks_captured: AtomicU32,
    /// DSP outputs dropped because one chunk produced more than the processing task buffers.
    pub outputs_overflowed: AtomicU32,
    /// Frames dropped because the uplink queue was full (the oldest frame is dropped).
    pub frames_dropped: AtomicU32,
    /// Frames that did not fit the uplink frame buffer or failed to encode.
    pub frames_unencodable: AtomicU32,
    /// Frames fully written to USART3.
    pub frames_sent: AtomicU32,
    /// USART3 transmit errors.
    pub uart_errors: AtomicU32,
}

impl Counters {
    /// All counters at zero.
    pub const fn new() -> Self {
        Self {
            dma_overruns: AtomicU32::new(0),
            sai_overruns: AtomicU32::new(0),
            dsp_overloads: AtomicU32::new(0),
            chunks_captured: AtomicU32::new(0),
            outputs_overflowed: AtomicU32::new(0),
            frames_dropped: AtomicU32::new(0),
            frames_unencodable: AtomicU32::new(0),
            frames_sent: AtomicU32::new(0),
            uart_errors: AtomicU32::new(0),
        }
    }
}

impl Default for Counters {
    fn default() -> Self {
        Self::new()
    }
}

/// Adds one to `counter` (wrapping).
pub fn bump(counter: &AtomicU32) {
    counter.fetch_add(1, Ordering::Relaxed);
}

/// Reads `counter`.
pub fn read(counter: &AtomicU32) -> u32 {
    counter.load(Ordering::Relaxed)
}

/// The firmware's counters.
pub static COUNTERS: Counters = Counters::new();

/// The Cortex-M7 DWT cycle counter (core clock cycles, wraps every 2³² cycles = 8.9 s at 480 MHz).
#[derive(Debug)]
pub struct CycleCounter(());

impl CycleCounter {
    /// Enables trace, unlocks the DWT and starts the cycle counter.
    ///
    /// The Cortex-M7's DWT has a software lock (the CoreSight lock access register): until it
    /// is unlocked, writes to DWT_CTRL are ignored, so without a debugger attached (which
    /// unlocks it) the counter would never start and read 0. `tests/hil` `dsp_time` checks
    /// that it counts.
    pub fn start(dcb: &mut cortex_m::peripheral::DCB, dwt: &mut cortex_m::peripheral::DWT) -> Self {
        dcb.enable_trace();
        cortex_m::peripheral::DWT::unlock();
        dwt.enable_cycle_counter();
        Self(())
    }

    /// The current cycle count.
    pub fn now(&self) -> u32 {
        cortex_m::peripheral::DWT::cycle_count()
    }

    /// Cycles elapsed since `start` (correct across one wrap).
    pub fn since(&self, start: u32) -> u32 {
        self.now().wrapping_sub(start)
    }
}

/// Cycle statistics over a reporting interval.
#[derive(Debug, Clone, Copy, Default)]
pub struct CycleStats {
    /// Sum of the measured cycles.
    pub total: u64,
    /// Largest single measurement.
    pub max: u32,
    /// Number of measurements.
    pub count: u32,
}

impl CycleStats {
    /// Adds one measurement.
    pub fn record(&mut self, cycles: u32) {
        self.total += u64::from(cycles);
        self.max = self.max.max(cycles);
        self.count += 1;
    }

    /// Mean cycles per measurement (0 when empty).
    pub fn mean(&self) -> u32 {
        if self.count == 0 {
            0
        } else {
            u32::try_from(self.total / u64::from(self.count)).unwrap_or(u32::MAX)
        }
    }
}
