//! Evaluation figures: the confusion matrix with per-class precision and recall, the type
//! accuracy among drone clips, and the detection ROC (drone against `none`) with the threshold
//! of a stated false-alarm rate.
use serde::Serialize;

/// Confusion matrix: `counts[true][predicted]`.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Confusion {
    /// Class names.
    pub classes: Vec<String>,
    /// Counts, rows the true class, columns the predicted one.
    pub counts: Vec<Vec<usize>>,
}

impl Confusion {
    /// An empty matrix of `classes`.
    pub fn new(classes: Vec<String>) -> Self {
        let k = classes.len();
        Self { classes, counts: vec![vec![0; k]; k] }
    }

    /// Counts one clip.
    pub fn add(&mut self, truth: usize, predicted: usize) {
        self.counts[truth][predicted] += 1;
    }

    /// Precision of class `c` (of the clips called `c`, the share that are), `None` when no clip
    /// was called `c`.
    pub fn precision(&self, c: usize) -> Option<f64> {
        let called: usize = self.counts.iter().map(|r| r[c]).sum();
        (called > 0).then(|| self.counts[c][c] as f64 / called as f64)
    }

    /// Recall of class `c` (of the clips of `c`, the share called `c`), `None` without clips.
    pub fn recall(&self, c: usize) -> Option<f64> {
        let n: usize = self.counts[c].iter().sum();
        (n > 0).then(|| self.counts[c][c] as f64 / n as f64)
    }

    /// Share of all clips on the diagonal.
    pub fn accuracy(&self) -> f64 {
        let n: usize = self.counts.iter().flatten().sum();
        let right: usize = (0..self.classes.len()).map(|c| self.counts[c][c]).sum();
        right as f64 / n.max(1) as f64
    }
}

/// One point of the ROC: at `threshold`, the share of drone clips with a drone probability
/// above it (`detection`) and of `none` clips (`false_alarm`).
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct RocPoint {
    /// Drone-probability threshold (a clip is a detection when its probability exceeds it).
    pub threshold: f64,
    /// Detection rate.
    pub detection: f64,
    /// False-alarm rate.
    pub false_alarm: f64,
}

/// The detection ROC of drone-probability scores: `positives` from drone clips, `negatives`
/// from `none` clips. One point per distinct negative score and the end points, by falling
/// threshold.
pub fn roc(positives: &[f64], negatives: &[f64]) -> Vec<RocPoint> {
    let at = |t: f64| RocPoint {
        threshold: t,
        detection: share_above(positives, t),
        false_alarm: share_above(negatives, t),
    };
    let mut ts: Vec<f64> = negatives.iter().chain(positives).copied().collect();
    ts.push(1.0);
    ts.sort_by(|a, b| b.total_cmp(a));
    ts.dedup();
    let mut points: Vec<RocPoint> = ts.into_iter().map(at).collect();
    points.push(RocPoint { threshold: f64::NEG_INFINITY, detection: 1.0, false_alarm: 1.0 });
    points
}

fn share_above(x: &[f64], t: f64) -> f64 {
    x.iter().filter(|&&v| v > t).count() as f64 / x.len().max(1) as f64
}

/// Area under the ROC (trapezoids), 0..=1.
pub fn auc(points: &[RocPoint]) -> f64 {
    points
        .windows(2)
        .map(|w| (w[1].false_alarm - w[0].false_alarm) * (w[1].detection + w[0].detection) / 2.0)
        .sum()
}

/// The operating point of the lowest threshold whose false-alarm rate is at most
/// `max_false_alarm` (the best detection at that false-alarm rate).
pub fn at_false_alarm(points: &[RocPoint], max_false_alarm: f64) -> Option<RocPoint> {
    points
        .iter()
        .filter(|p| p.false_alarm <= max_false_alarm)
        .min_by(|a, b| a.threshold.total_cmp(&b.threshold))
        .copied()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn confusion_precision_recall() {
        let mut c = Confusion::new(vec!["a".into(), "b".into()]);
        for (t, p) in [(0, 0), (0, 0), (0, 1), (1, 1)] {
            c.add(t, p);
        }
        assert_eq!(c.precision(0), Some(1.0));
        assert_eq!(c.recall(0), Some(2.0 / 3.0));
        assert_eq!(c.precision(1), Some(0.5));
        assert_eq!(c.accuracy(), 0.75);
    }

    #[test]
    fn roc_of_separable_and_of_overlapping_scores() {
        let pos = [0.9, 0.8, 0.7, 0.3];
        let neg: Vec<f64> = (0..100).map(|i| i as f64 / 200.0).collect(); // 0 .. 0.495
        let r = roc(&pos, &neg);
        // At ≤ 1 % false alarms: one negative (0.495) may be above; the threshold is the
        // second-highest negative score 0.49, and 3 of 4 drones are above it.
        let p = at_false_alarm(&r, 0.01).unwrap();
        assert_eq!(p.threshold, 0.49);
        assert_eq!(p.false_alarm, 0.01);
        assert_eq!(p.detection, 0.75);
        // AUC: the drone at 0.3 ranks above 60 of 100 negatives and ties one: (3 + 0.605) / 4.
        assert!((auc(&r) - (3.0 + 0.605) / 4.0).abs() < 1e-9, "{}", auc(&r));
        assert!((auc(&roc(&[0.9], &[0.1])) - 1.0).abs() < 1e-12);
    }
}
