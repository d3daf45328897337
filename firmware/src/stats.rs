//! Counters the streaming tasks update and the `Health` frame reports, and the DWT cycle
//! counter used to time the DSP.
//!
//! Counters are atomics because the capture and uplink tasks run on an interrupt executor and
//! the DSP task in thread mode. They only count up (wrapping) so a host can difference them.
use core::sync::atomic::{AtomicU32, Ordering};

/// Event counters shared by the capture, DSP and uplink tasks.
#[derive(Debug)]
pub struct Counters {
    /// SAI/DMA ring overruns (each one restarted the capture driver; samples were lost).
    pub dma_overruns: AtomicU32,
    /// Capture chunks handed to the DSP task (each `CHUNK_FRAMES` frames).
    pub chunks_captured: AtomicU32,
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
            chunks_captured: AtomicU32::new(0),
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
    /// Enables trace and starts the cycle counter.
    pub fn start(dcb: &mut cortex_m::peripheral::DCB, dwt: &mut cortex_m::peripheral::DWT) -> Self {
        dcb.enable_trace();
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
