//! Hann windows: a table for the spatial blocks, an in-place multiply for long buffers.

use core::f32::consts::PI;

use crate::gcc_phat::Twiddles;

/// Fills `out` with the periodic Hann window of length `out.len()`: 0.5 − 0.5 cos(2πn/N).
///
/// ```
/// let mut w = [0.0f32; 8];
/// aim_dsp::window::hann(&mut w);
/// assert_eq!(w[0], 0.0);
/// assert!((w[4] - 1.0).abs() < 1e-6);
/// ```
pub fn hann(out: &mut [f32]) {
    let n = out.len() as f32;
    for (i, w) in out.iter_mut().enumerate() {
        *w = 0.5 - 0.5 * libm::cosf(2.0 * PI * i as f32 / n);
    }
}

/// Multiplies `buf` in place by the periodic Hann window of length `buf.len()`.
///
/// The cosine comes from a rotating phasor re-seeded every 64 samples from the phasor table
/// `tw` (exact grid points when `buf.len()` is a multiple of 64 dividing 65 536, e.g. 4096), so
/// a 4096-point window costs one `libm` sine/cosine pair instead of 4096.
pub fn apply_hann(buf: &mut [f32], tw: &Twiddles) {
    const RESEED: usize = 64;
    let n = buf.len();
    let step = 2.0 * PI / n as f32;
    let (ss, cs) = (libm::sinf(step), libm::cosf(step));
    for (chunk_index, chunk) in buf.chunks_mut(RESEED).enumerate() {
        // 2π·(chunk_index·RESEED)/n on the table's 1024-point grid.
        let u = (chunk_index * RESEED) as f32 * (1024.0 / n as f32);
        let (mut s, mut c) = tw.sin_cos_grid(u);
        for x in chunk {
            *x *= 0.5 - 0.5 * c;
            let c2 = c * cs - s * ss;
            s = s * cs + c * ss;
            c = c2;
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn streaming_hann_matches_table() {
        let mut table = [0.0f32; 4096];
        super::hann(&mut table);
        let mut ones = [1.0f32; 4096];
        super::apply_hann(&mut ones, &crate::gcc_phat::Twiddles::new());
        let worst = table.iter().zip(&ones).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
        assert!(worst < 2e-6, "worst deviation {worst}");
    }
}
