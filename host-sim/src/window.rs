//! Sliding windows of source signals, so a simulation holds a bounded stretch of every source
//! (the output block plus the longest path's delay) instead of the whole run.
//!
//! A [`SourceWindow`] receives the signal's samples in order and keeps their second differences
//! (`s[k−1] − 2 s[k] + s[k+1]`, zero at both ends of the signal, as
//! [`crate::propagation::PreparedSource`] computes them for a whole signal); the renderer reads
//! it through [`SourceWindow::view`].
use crate::propagation::SourceView;

/// A window of one source signal of `total` samples on the grid `t0_s + k / sample_rate_hz`.
#[derive(Clone, Debug)]
pub struct SourceWindow {
    t0_s: f64,
    sample_rate_hz: f64,
    total: usize,
    /// Signal index of `samples[0]`.
    start: usize,
    samples: Vec<f32>,
    second_difference: Vec<f32>,
}

impl SourceWindow {
    /// An empty window at the start of a signal of `total` samples.
    pub fn new(t0_s: f64, sample_rate_hz: f64, total: usize) -> Self {
        Self {
            t0_s,
            sample_rate_hz,
            total,
            start: 0,
            samples: Vec::new(),
            second_difference: Vec::new(),
        }
    }

    /// Signal index one past the last sample received.
    pub fn end(&self) -> usize {
        self.start + self.samples.len()
    }

    /// Appends the signal's next samples (those past `total` are ignored).
    pub fn push(&mut self, new: &[f32]) {
        let room = self.total - self.end();
        for &x in &new[..new.len().min(room)] {
            let g = self.end();
            self.samples.push(x);
            self.second_difference.push(0.0);
            // Sample g completes the second difference of sample g − 1 (never of sample 0;
            // g < total, so g − 1 ≤ total − 2).
            if g >= 2 && g - 2 >= self.start {
                let i = g - 1 - self.start;
                self.second_difference[i] =
                    self.samples[i - 1] - 2.0 * self.samples[i] + self.samples[i + 1];
            }
        }
    }

    /// Drops the samples before signal index `from` (keeping the last two received, which the
    /// next second difference needs).
    pub fn trim(&mut self, from: usize) {
        let cut = from.min(self.end().saturating_sub(2)).saturating_sub(self.start);
        self.samples.drain(..cut);
        self.second_difference.drain(..cut);
        self.start += cut;
    }

    /// The samples whose second difference is known: all received but the last, unless the
    /// last is the signal's last.
    pub fn view(&self) -> SourceView<'_> {
        let n = if self.end() == self.total {
            self.samples.len()
        } else {
            self.samples.len().saturating_sub(1)
        };
        SourceView {
            t0_s: self.t0_s,
            sample_rate_hz: self.sample_rate_hz,
            start: self.start,
            total: self.total,
            samples: &self.samples[..n],
            second_difference: &self.second_difference[..n],
        }
    }

    /// Samples held now.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// Whether no sample is held.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::propagation::PreparedSource;
    use crate::sound::SourceSignal;

    /// Fed in uneven pieces and trimmed as it goes, the window holds exactly the whole
    /// signal's samples and second differences over its span.
    #[test]
    fn window_matches_the_whole_signal() {
        let total = 1000;
        let samples: Vec<f32> = (0..total).map(|k| ((k * 7919) % 1013) as f32 * 0.01).collect();
        let whole = SourceSignal { t0_s: -0.5, sample_rate_hz: 100.0, samples: samples.clone() };
        let prepared = PreparedSource::new(&whole);
        let full = prepared.view();
        let mut w = SourceWindow::new(-0.5, 100.0, total);
        let mut fed = 0;
        for (i, piece) in [1usize, 2, 3, 97, 250, 1, 400, 600].iter().enumerate() {
            let to = (fed + piece).min(total + 5);
            let chunk: Vec<f32> =
                (fed..to).map(|k| samples.get(k).copied().unwrap_or(9.0)).collect();
            w.push(&chunk);
            fed = to;
            let v = w.view();
            for (j, (s, d)) in v.samples.iter().zip(v.second_difference).enumerate() {
                let k = v.start + j;
                assert_eq!((*s, *d), (full.samples[k], full.second_difference[k]), "k {k}");
            }
            assert!(v.start + v.samples.len() <= fed.min(total));
            w.trim(fed.saturating_sub(10 * i));
        }
        assert_eq!(w.end(), total);
        assert_eq!(w.view().samples.len(), w.len());
    }
}
