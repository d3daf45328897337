//! The parity report: every output of the checked computations, one line each, floats as bit
//! patterns (hex), so that equal text means equal bits.
use core::fmt::{self, Write};

use crate::signal::Signal;

/// Sample rate of the golden input, Hz.
pub const SAMPLE_RATE_HZ: u32 = 48_000;

/// Writes the whole parity report to `w`.
pub fn write_parity(w: &mut impl Write) -> fmt::Result {
    write_rfft(w)?;
    writeln!(w, "end")
}

/// microfft `rfft_1024` of the first 1024 samples of microphone 0 (as f32 of the 24-bit value):
/// `rfft <bin> <re> <im>`.
fn write_rfft(w: &mut impl Write) -> fmt::Result {
    let mut x = [0f32; 1024];
    reference_rfft_input(&mut x);
    let spectrum = microfft::real::rfft_1024(&mut x);
    for (k, c) in spectrum.iter().enumerate() {
        writeln!(w, "rfft {k} {:08x} {:08x}", c.re.to_bits(), c.im.to_bits())?;
    }
    Ok(())
}

/// The input of the reference `rfft_1024`: microphone 0 of the golden signal, 24-bit values as
/// f32 scaled to ±1.
pub fn reference_rfft_input(x: &mut [f32; 1024]) {
    let mut signal = Signal::new(&[0], 1, SAMPLE_RATE_HZ, 1);
    let mut words = [0i32; 1024];
    signal.fill(&mut words);
    for (x, w) in x.iter_mut().zip(words) {
        *x = (w >> 8) as f32 * (1.0 / 8_388_608.0);
    }
}
