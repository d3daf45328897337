//! The classifier: an ensemble of multilayer perceptrons with one hidden layer (tanh) and a
//! softmax output each (their probabilities averaged), on standardised features, stored as a JSON file ([`Model`]'s fields, format
//! [`FORMAT`]).
//!
//! Why not an ML crate: linfa and smartcore were the candidates. A clip-level feature vector
//! of 75 numbers and a few thousand clips need nothing beyond a small dense network, and the
//! network's inference is two matrix–vector products a no_std chip can run from the same
//! JSON (weights as plain arrays, no crate-specific serialisation such as a bincode'd
//! `RandomForest`). The detection ROC needs calibrated-ish probabilities, which a softmax
//! gives and a forest's vote fractions give only coarsely. Training is mini-batch Adam on the
//! cross-entropy with L2 weight decay, seeded: the same data and seed give the same model.
use std::cmp::Ordering;
use std::path::Path;

use anyhow::{bail, Context as _};
use serde::{Deserialize, Serialize};

/// Format tag of the model file.
pub const FORMAT: &str = "aim-id-mlp-2";

/// A dense layer: `out = W x + b`, `weights[o][i]`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Layer {
    /// Weights, one row per output.
    pub weights: Vec<Vec<f32>>,
    /// Biases, one per output.
    pub bias: Vec<f32>,
}

impl Layer {
    fn forward(&self, x: &[f32], out: &mut Vec<f32>) {
        out.clear();
        out.extend(
            self.weights
                .iter()
                .zip(&self.bias)
                .map(|(w, b)| b + w.iter().zip(x).map(|(a, b)| a * b).sum::<f32>()),
        );
    }
}

/// One network: a tanh hidden layer and a softmax output layer.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Net {
    /// Hidden layer (tanh).
    pub hidden: Layer,
    /// Output layer (softmax).
    pub output: Layer,
}

impl Net {
    /// Class probabilities of a standardised feature vector.
    fn predict(&self, xs: &[f32]) -> Vec<f32> {
        let mut h = Vec::new();
        self.hidden.forward(xs, &mut h);
        h.iter_mut().for_each(|v| *v = v.tanh());
        let mut out = Vec::new();
        self.output.forward(&h, &mut out);
        softmax(&mut out);
        out
    }
}

/// A trained classifier.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Model {
    /// [`FORMAT`].
    pub format: String,
    /// Feature names, in input order (`clip::names`).
    pub features: Vec<String>,
    /// Class names, in output order.
    pub classes: Vec<String>,
    /// Feature means of the training set (standardisation).
    pub mean: Vec<f32>,
    /// Feature standard deviations of the training set (standardisation).
    pub scale: Vec<f32>,
    /// The ensemble's networks; the model's probabilities are the mean of theirs.
    pub members: Vec<Net>,
    /// How it was trained (clips, epochs, seed), for the record.
    pub training: Training,
    /// Drone probability (1 − P(none)) above which a decision names a drone ([`Model::decide`]),
    /// set by `aim id eval --set-threshold` for a stated false-alarm rate on recordings of the
    /// user's choosing; absent: the most probable class.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drone_threshold: Option<f32>,
}

/// Training settings.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub struct Training {
    /// Networks in the ensemble (member i starts from seed `seed + i`).
    pub members: usize,
    /// Hidden units.
    pub hidden_units: usize,
    /// Passes over the training set.
    pub epochs: usize,
    /// Clips per mini-batch.
    pub batch: usize,
    /// Adam step size.
    pub learning_rate: f32,
    /// L2 weight decay.
    pub weight_decay: f32,
    /// Seed of the initial weights and the batch order.
    pub seed: u64,
    /// Clips trained on.
    pub clips: usize,
}

impl Default for Training {
    fn default() -> Self {
        Self {
            members: 3,
            hidden_units: 48,
            epochs: 200,
            batch: 32,
            learning_rate: 3e-3,
            weight_decay: 1e-4,
            seed: 1,
            clips: 0,
        }
    }
}

/// xorshift64*: the seeded generator of the initial weights and the batch order.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [−1, 1).
    fn sym(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 23) as f32 - 1.0
    }
}

fn softmax(z: &mut [f32]) {
    let m = z.iter().cloned().fold(f32::MIN, f32::max);
    let mut s = 0.0;
    for v in z.iter_mut() {
        *v = (*v - m).exp();
        s += *v;
    }
    z.iter_mut().for_each(|v| *v /= s);
}

/// Adam state of one parameter array.
struct Adam {
    m: Vec<f32>,
    v: Vec<f32>,
}

impl Adam {
    fn new(n: usize) -> Self {
        Self { m: vec![0.0; n], v: vec![0.0; n] }
    }
    fn step(&mut self, p: &mut [f32], g: &[f32], lr: f32, t: i32) {
        let (b1, b2) = (0.9f32, 0.999f32);
        let (c1, c2) = (1.0 - b1.powi(t), 1.0 - b2.powi(t));
        for i in 0..p.len() {
            self.m[i] = b1 * self.m[i] + (1.0 - b1) * g[i];
            self.v[i] = b2 * self.v[i] + (1.0 - b2) * g[i] * g[i];
            p[i] -= lr * (self.m[i] / c1) / ((self.v[i] / c2).sqrt() + 1e-8);
        }
    }
}

/// Trains one network on standardised vectors `xs` (mini-batch Adam, module docs).
fn train_net(xs: &[Vec<f32>], y: &[usize], d: usize, k: usize, t: &Training, seed: u64) -> Net {
    let h = t.hidden_units;
    let mut rng = Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
    let (a1, a2) = ((6.0 / (d + h) as f32).sqrt(), (6.0 / (h + k) as f32).sqrt());
    let mut w1: Vec<f32> = (0..h * d).map(|_| a1 * rng.sym()).collect();
    let mut b1 = vec![0.0f32; h];
    let mut w2: Vec<f32> = (0..k * h).map(|_| a2 * rng.sym()).collect();
    let mut b2 = vec![0.0f32; k];
    let (mut o_w1, mut o_b1, mut o_w2, mut o_b2) =
        (Adam::new(h * d), Adam::new(h), Adam::new(k * h), Adam::new(k));
    let mut order: Vec<usize> = (0..xs.len()).collect();
    let mut step = 0;
    let (mut g_w1, mut g_b1) = (vec![0.0f32; h * d], vec![0.0f32; h]);
    let (mut g_w2, mut g_b2) = (vec![0.0f32; k * h], vec![0.0f32; k]);
    let (mut hid, mut out, mut dh) = (vec![0.0f32; h], vec![0.0f32; k], vec![0.0f32; h]);
    for _ in 0..t.epochs {
        for i in (1..order.len()).rev() {
            order.swap(i, (rng.next() % (i as u64 + 1)) as usize);
        }
        for batch in order.chunks(t.batch.max(1)) {
            g_w1.fill(0.0);
            g_b1.fill(0.0);
            g_w2.fill(0.0);
            g_b2.fill(0.0);
            for &s in batch {
                let xv = &xs[s];
                for u in 0..h {
                    let z: f32 = b1[u]
                        + w1[u * d..(u + 1) * d].iter().zip(xv).map(|(a, b)| a * b).sum::<f32>();
                    hid[u] = z.tanh();
                }
                for c in 0..k {
                    out[c] = b2[c]
                        + w2[c * h..(c + 1) * h].iter().zip(&hid).map(|(a, b)| a * b).sum::<f32>();
                }
                softmax(&mut out);
                out[y[s]] -= 1.0; // dL/dz of the cross-entropy
                dh.fill(0.0);
                for c in 0..k {
                    g_b2[c] += out[c];
                    for u in 0..h {
                        g_w2[c * h + u] += out[c] * hid[u];
                        dh[u] += out[c] * w2[c * h + u];
                    }
                }
                for u in 0..h {
                    let gz = dh[u] * (1.0 - hid[u] * hid[u]);
                    g_b1[u] += gz;
                    for (g, xi) in g_w1[u * d..(u + 1) * d].iter_mut().zip(xv) {
                        *g += gz * xi;
                    }
                }
            }
            let bn = batch.len() as f32;
            for (g, w) in g_w1.iter_mut().zip(&w1) {
                *g = *g / bn + t.weight_decay * w;
            }
            for (g, w) in g_w2.iter_mut().zip(&w2) {
                *g = *g / bn + t.weight_decay * w;
            }
            g_b1.iter_mut().for_each(|g| *g /= bn);
            g_b2.iter_mut().for_each(|g| *g /= bn);
            step += 1;
            o_w1.step(&mut w1, &g_w1, t.learning_rate, step);
            o_b1.step(&mut b1, &g_b1, t.learning_rate, step);
            o_w2.step(&mut w2, &g_w2, t.learning_rate, step);
            o_b2.step(&mut b2, &g_b2, t.learning_rate, step);
        }
    }
    let rows = |w: &[f32], cols: usize| w.chunks(cols).map(|r| r.to_vec()).collect();
    Net {
        hidden: Layer { weights: rows(&w1, d), bias: b1 },
        output: Layer { weights: rows(&w2, h), bias: b2 },
    }
}

/// The ensemble's members (member i from seed `t.seed + i`), `threads` at a time: each is
/// seeded by its index alone, so the members are the same on any number of threads.
fn train_members(
    xs: &[Vec<f32>],
    y: &[usize],
    d: usize,
    k: usize,
    t: &Training,
    threads: usize,
) -> Vec<Net> {
    let seeds: Vec<u64> = (0..t.members.max(1)).map(|i| t.seed.wrapping_add(i as u64)).collect();
    let mut members = Vec::with_capacity(seeds.len());
    for chunk in seeds.chunks(threads.max(1)) {
        std::thread::scope(|s| {
            let nets: Vec<_> =
                chunk.iter().map(|&sd| s.spawn(move || train_net(xs, y, d, k, t, sd))).collect();
            for n in nets {
                members.push(n.join().unwrap_or_else(|p| std::panic::resume_unwind(p)));
            }
        });
    }
    members
}

impl Model {
    /// Trains on feature vectors `x` with labels `y` (indices into `classes`).
    pub fn train(
        features: Vec<String>,
        classes: Vec<String>,
        x: &[Vec<f32>],
        y: &[usize],
        mut t: Training,
    ) -> anyhow::Result<Self> {
        let d = features.len();
        let k = classes.len();
        if k < 2 {
            bail!("training needs at least two classes, got {k}");
        }
        if x.is_empty() || x.len() != y.len() || x.iter().any(|v| v.len() != d) {
            bail!("training data: {} vectors of {d} features and {} labels", x.len(), y.len());
        }
        t.clips = x.len();
        let n = x.len() as f32;
        let mean: Vec<f32> = (0..d).map(|j| x.iter().map(|v| v[j]).sum::<f32>() / n).collect();
        let scale: Vec<f32> = (0..d)
            .map(|j| {
                let var = x.iter().map(|v| (v[j] - mean[j]).powi(2)).sum::<f32>() / n;
                if var > 1e-12 {
                    var.sqrt()
                } else {
                    1.0
                }
            })
            .collect();
        let xs: Vec<Vec<f32>> = x
            .iter()
            .map(|v| v.iter().zip(&mean).zip(&scale).map(|((a, m), s)| (a - m) / s).collect())
            .collect();
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
        let members = train_members(&xs, y, d, k, &t, threads);
        Ok(Self {
            format: FORMAT.into(),
            features,
            classes,
            mean,
            scale,
            members,
            training: t,
            drone_threshold: None,
        })
    }

    /// Class probabilities of one feature vector (in `classes` order).
    pub fn predict(&self, x: &[f32]) -> Vec<f32> {
        let xs: Vec<f32> =
            x.iter().zip(&self.mean).zip(&self.scale).map(|((a, m), s)| (a - m) / s).collect();
        let mut p = vec![0.0f32; self.classes.len()];
        for m in &self.members {
            for (a, b) in p.iter_mut().zip(m.predict(&xs)) {
                *a += b;
            }
        }
        let n = self.members.len().max(1) as f32;
        p.iter_mut().for_each(|v| *v /= n);
        p
    }

    /// Index of the `none` class, if the model has one.
    pub fn none_index(&self) -> Option<usize> {
        self.classes.iter().position(|c| c == super::NONE_CLASS)
    }

    /// Probability that a drone is present: 1 − P(none) (1 without a `none` class).
    pub fn drone_probability(&self, p: &[f32]) -> f32 {
        self.none_index().map_or(1.0, |i| 1.0 - p[i])
    }

    /// The class decided from probabilities `p` (model class order): without a
    /// [`Model::drone_threshold`] or a `none` class, the most probable; with one, the most
    /// probable drone class when the drone probability is above the threshold (as the ROC of
    /// `aim id eval` counts a detection), else `none` (also for a NaN probability).
    pub fn decide(&self, p: &[f32]) -> usize {
        match (self.drone_threshold, self.none_index()) {
            (Some(t), Some(none))
                if self.drone_probability(p).partial_cmp(&t) != Some(Ordering::Greater) =>
            {
                none
            }
            (Some(_), none) => self.most_probable(p, none),
            _ => self.most_probable(p, None),
        }
    }

    /// The most probable class of `p` (model class order), leaving out class `except` if
    /// given (0 when no class is left).
    pub fn most_probable(&self, p: &[f32], except: Option<usize>) -> usize {
        (0..p.len())
            .filter(|&c| Some(c) != except)
            .max_by(|&a, &b| p[a].total_cmp(&p[b]))
            .unwrap_or(0)
    }

    /// Writes the model as JSON.
    pub fn save(&self, path: &Path) -> anyhow::Result<()> {
        let json = serde_json::to_string(self)?;
        std::fs::write(path, json).with_context(|| format!("cannot write {}", path.display()))
    }

    /// Reads and checks a model file.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read model {}", path.display()))?;
        Self::from_json(&text, path)
    }

    /// Whether the model reads the chip's `Mfcc` windows ([`super::chip`]) rather than the
    /// 16 kHz clip features ([`super::clip`]).
    pub fn reads_chip_frames(&self) -> bool {
        self.features == super::chip::names()
    }

    /// Parses and checks a model's JSON text (`path`: named in errors).
    pub fn from_json(text: &str, path: &Path) -> anyhow::Result<Self> {
        let m: Model = serde_json::from_str(text)
            .with_context(|| format!("{}: not an aim id model", path.display()))?;
        if m.format != FORMAT {
            bail!("{}: model format `{}`, this aim reads `{FORMAT}`", path.display(), m.format);
        }
        let (d, k) = (m.features.len(), m.classes.len());
        let h = m.members.first().map_or(0, |n| n.hidden.bias.len());
        let ok = m.mean.len() == d
            && m.scale.len() == d
            && !m.members.is_empty()
            && m.members.iter().all(|n| {
                let h = n.hidden.bias.len();
                n.hidden.weights.len() == h
                    && n.hidden.weights.iter().all(|r| r.len() == d)
                    && n.output.bias.len() == k
                    && n.output.weights.len() == k
                    && n.output.weights.iter().all(|r| r.len() == h)
            })
            && k >= 2;
        if !ok {
            bail!(
                "{}: layer sizes do not match ({d} features, {h} hidden, {k} classes)",
                path.display()
            );
        }
        // Numbers a hand-edited or damaged file may hold that the sizes do not catch: a zero
        // or NaN scale makes every probability NaN.
        if !m.scale.iter().all(|s| s.is_finite() && *s > 0.0) {
            bail!("{}: every feature scale must be a positive number", path.display());
        }
        let weights = m.members.iter().flat_map(|n| {
            let layers = [&n.hidden, &n.output];
            layers.into_iter().flat_map(|l| l.weights.iter().flatten().chain(&l.bias))
        });
        if !m.mean.iter().chain(weights).all(|v| v.is_finite()) {
            bail!("{}: a mean or weight is not a finite number", path.display());
        }
        for (i, c) in m.classes.iter().enumerate() {
            if c.trim().is_empty() || m.classes[..i].contains(c) {
                bail!("{}: class name `{c}` is empty or appears twice", path.display());
            }
        }
        if let Some(t) = m.drone_threshold {
            if !(0.0..=1.0).contains(&t) {
                bail!("{}: drone_threshold {t} is not a probability (0..=1)", path.display());
            }
        }
        if m.features != super::clip::names() && m.features != super::chip::names() {
            bail!(
                "{}: model made for other features ({} of them); retrain with this aim",
                path.display(),
                d
            );
        }
        Ok(m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three Gaussian blobs in 2-D, well apart: the model separates them and the file round
    /// trips.
    #[test]
    fn separates_blobs_and_round_trips() {
        let mut rng = Rng(5);
        let centres = [(0.0, 0.0), (4.0, 0.0), (0.0, 4.0)];
        let (mut x, mut y) = (Vec::new(), Vec::new());
        for i in 0..300 {
            let c = i % 3;
            x.push(vec![centres[c].0 + rng.sym(), centres[c].1 + rng.sym()]);
            y.push(c);
        }
        let names = vec!["a".to_string(), "b".to_string()];
        let classes = vec!["p".into(), "q".into(), "none".into()];
        let t = Training { epochs: 50, ..Training::default() };
        let m = Model::train(names, classes, &x, &y, t).unwrap();
        let right = x.iter().zip(&y).filter(|(v, &c)| {
            let p = m.predict(v);
            (0..3).max_by(|&a, &b| p[a].total_cmp(&p[b])) == Some(c)
        });
        assert_eq!(right.count(), 300);
        let p = m.predict(&[0.0, 4.0]);
        assert!((p.iter().sum::<f32>() - 1.0).abs() < 1e-5);
        assert!(m.drone_probability(&p) < 0.1);
        let json = serde_json::to_string(&m).unwrap();
        let back: Model = serde_json::from_str(&json).unwrap();
        assert_eq!(back, m);
        // Same data, same seed: the same model.
        let again = Model::train(m.features.clone(), m.classes.clone(), &x, &y, t).unwrap();
        assert_eq!(again, m);
        // The members trained one at a time are those trained side by side.
        let xs: Vec<Vec<f32>> = x
            .iter()
            .map(|v| v.iter().zip(&m.mean).zip(&m.scale).map(|((a, u), s)| (a - u) / s).collect())
            .collect();
        assert_eq!(train_members(&xs, &y, 2, 3, &t, 1), m.members);
        assert_eq!(train_members(&xs, &y, 2, 3, &t, 3), m.members);
        assert!(Model::train(vec!["a".into()], vec!["p".into()], &[vec![1.0]], &[0], t).is_err());
        // A damaged file is refused before it gives NaN probabilities or loses a class.
        let refused = |bad: &Model| {
            let text = serde_json::to_string(bad).unwrap();
            Model::from_json(&text, Path::new("m.json")).unwrap_err().to_string()
        };
        let zero = Model { scale: vec![0.0; 2], ..m.clone() };
        assert!(refused(&zero).contains("scale"), "{}", refused(&zero));
        let twice = Model { classes: vec!["p".into(), "p".into(), "none".into()], ..m.clone() };
        assert!(refused(&twice).contains("appears twice"), "{}", refused(&twice));
    }
}
