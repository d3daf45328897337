//! Obstacles: axis-aligned boxes (shelves, cabinets) that block sound paths.
//!
//! A path that crosses a box loses the box's transmission loss (`loss_db`, broadband). When the
//! direct path is blocked, sound also bends around the box: the simulator adds one diffracted
//! path over the top or around a vertical edge, whichever is shortest, with Maekawa's barrier
//! attenuation `10 log10(3 + 20 N)` dB, N = 2 δ f / c the Fresnel number of the detour δ at the
//! reference frequency `f` (one broadband value: harmonics above it are attenuated too little).
use nalgebra::Vector3;

/// An axis-aligned box, world frame (ENU m).
#[derive(Clone, Debug, PartialEq)]
pub struct Obstacle {
    /// Name, for messages and the site file.
    pub name: String,
    /// Lowest corner, m.
    pub min: Vector3<f64>,
    /// Highest corner, m.
    pub max: Vector3<f64>,
    /// Transmission loss of a path through the box, dB.
    pub loss_db: f64,
}

/// Margin by which diffraction points sit outside the box, m.
const EDGE_MARGIN_M: f64 = 1e-3;

impl Obstacle {
    /// Checks the box; names the problem, starting with the key at fault (`min`, `loss_db`).
    pub fn validate(&self) -> Result<(), String> {
        if (0..3).any(|i| {
            !(self.min[i].is_finite() && self.max[i].is_finite() && self.min[i] < self.max[i])
        }) {
            return Err(format!("min must be below max on every axis (obstacle `{}`)", self.name));
        }
        if !(self.loss_db.is_finite() && self.loss_db >= 0.0) {
            return Err(format!("loss_db must be zero or positive (obstacle `{}`)", self.name));
        }
        Ok(())
    }

    /// Whether `p` lies strictly inside.
    pub fn contains(&self, p: &Vector3<f64>) -> bool {
        (0..3).all(|i| p[i] > self.min[i] && p[i] < self.max[i])
    }

    /// Parameter interval `(t_in, t_out)` ⊂ (0, 1) of the segment `a → b` inside the box, if the
    /// segment passes through its interior (slab method). Touching a face does not count.
    pub fn clip(&self, a: &Vector3<f64>, b: &Vector3<f64>) -> Option<(f64, f64)> {
        let d = b - a;
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for i in 0..3 {
            if d[i].abs() < 1e-15 {
                if a[i] <= self.min[i] || a[i] >= self.max[i] {
                    return None;
                }
                continue;
            }
            let ta = (self.min[i] - a[i]) / d[i];
            let tb = (self.max[i] - a[i]) / d[i];
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
        }
        (t1 - t0 > 1e-9).then_some((t0, t1))
    }

    /// Candidate detours for a blocked segment `a → b` with in-box interval `(t_in, t_out)`:
    /// over the top (up at the entry edge, across, down at the exit edge) and around the sides
    /// past one vertical edge or two adjacent ones. Each is the list of its corner points.
    fn detours(
        &self,
        a: &Vector3<f64>,
        b: &Vector3<f64>,
        t_in: f64,
        t_out: f64,
    ) -> Vec<Vec<Vector3<f64>>> {
        let d = b - a;
        let lift = |t: f64| {
            let p = a + d * t;
            Vector3::new(p.x, p.y, self.max.z + EDGE_MARGIN_M)
        };
        let mut out = vec![vec![lift(t_in - 1e-9), lift(t_out + 1e-9)]];
        let centre = (self.min + self.max) / 2.0;
        let corners = [
            (self.min.x, self.min.y),
            (self.max.x, self.min.y),
            (self.max.x, self.max.y),
            (self.min.x, self.max.y),
        ];
        let edge = |(x, y): (f64, f64)| {
            // Height of the straight path where it passes closest to the edge, kept on the edge.
            let dd = d.x * d.x + d.y * d.y;
            let t = if dd > 0.0 {
                (((x - a.x) * d.x + (y - a.y) * d.y) / dd).clamp(0.0, 1.0)
            } else {
                0.5
            };
            let z = (a.z + d.z * t).clamp(self.min.z, self.max.z);
            let outward = Vector3::new(x - centre.x, y - centre.y, 0.0).normalize() * EDGE_MARGIN_M;
            Vector3::new(x, y, z) + outward
        };
        for i in 0..4 {
            out.push(vec![edge(corners[i])]);
            let j = (i + 1) % 4;
            out.push(vec![edge(corners[i]), edge(corners[j])]);
            out.push(vec![edge(corners[j]), edge(corners[i])]);
        }
        out
    }
}

/// What the obstacles do to the straight segment `a → b`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Blocking {
    /// Sum of the transmission losses of the boxes crossed, dB (0: clear line of sight).
    pub loss_db: f64,
    /// Index of the first box crossed, if any.
    pub first: Option<usize>,
}

/// Boxes crossed by `a → b`.
pub fn blocking(obstacles: &[Obstacle], a: &Vector3<f64>, b: &Vector3<f64>) -> Blocking {
    let mut out = Blocking { loss_db: 0.0, first: None };
    let mut first_t = f64::INFINITY;
    for (i, o) in obstacles.iter().enumerate() {
        if let Some((t0, _)) = o.clip(a, b) {
            out.loss_db += o.loss_db;
            if t0 < first_t {
                first_t = t0;
                out.first = Some(i);
            }
        }
    }
    out
}

/// A diffracted path around a box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Diffraction {
    /// The first diffracting edge point, m (where the sound seems to come from, seen from `a`).
    pub edge: Vector3<f64>,
    /// Path length source → edge(s) → receiver, m.
    pub length_m: f64,
    /// Pressure gain from Maekawa's attenuation and any boxes the detour itself crosses.
    pub gain: f64,
}

/// The shortest diffracted path from `a` to `b` around the first box blocking it, if the
/// segment is blocked and some detour is clear of that box. `ref_hz` and `c_mps` set the
/// Fresnel number.
pub fn diffraction(
    obstacles: &[Obstacle],
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    ref_hz: f64,
    c_mps: f64,
) -> Option<Diffraction> {
    let first = blocking(obstacles, a, b).first?;
    let o = &obstacles[first];
    let (t0, t1) = o.clip(a, b)?;
    let direct = (b - a).norm();
    let mut best: Option<(f64, Vec<Vector3<f64>>)> = None;
    for corners in o.detours(a, b, t0, t1) {
        let mut pts = Vec::with_capacity(corners.len() + 2);
        pts.push(*a);
        pts.extend_from_slice(&corners);
        pts.push(*b);
        if pts.windows(2).any(|w| o.clip(&w[0], &w[1]).is_some()) {
            continue;
        }
        let length_m: f64 = pts.windows(2).map(|w| (w[1] - w[0]).norm()).sum();
        if best.as_ref().is_none_or(|(l, _)| length_m < *l) {
            best = Some((length_m, pts));
        }
    }
    let (length_m, pts) = best?;
    let fresnel = 2.0 * (length_m - direct).max(0.0) * ref_hz / c_mps;
    let maekawa_db = 10.0 * (3.0 + 20.0 * fresnel).log10();
    // Other boxes a detour leg crosses (never `o`: the legs were checked against it).
    let others: f64 = pts.windows(2).map(|w| blocking(obstacles, &w[0], &w[1]).loss_db).sum();
    Some(Diffraction { edge: pts[1], length_m, gain: 10f64.powf(-(maekawa_db + others) / 20.0) })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shelf() -> Obstacle {
        Obstacle {
            name: "shelf".into(),
            min: Vector3::new(-2.0, 1.0, 0.0),
            max: Vector3::new(2.0, 1.5, 2.0),
            loss_db: 20.0,
        }
    }

    #[test]
    fn box_blocks_the_segment_through_it_only() {
        let o = [shelf()];
        let a = Vector3::new(0.0, 0.0, 0.5);
        assert_eq!(blocking(&o, &a, &Vector3::new(0.0, 3.0, 1.0)).loss_db, 20.0);
        // Passing above the shelf, and beside it.
        assert_eq!(blocking(&o, &a, &Vector3::new(0.0, 3.0, 6.0)).first, None);
        assert_eq!(blocking(&o, &a, &Vector3::new(6.0, 3.0, 1.0)).first, None);
    }

    #[test]
    fn diffraction_goes_over_the_top_with_maekawa_loss() {
        let o = [shelf()];
        let a = Vector3::new(0.0, 0.0, 1.0);
        let b = Vector3::new(0.0, 2.5, 1.0);
        let d = diffraction(&o, &a, &b, 500.0, 343.0).unwrap();
        // Over the top: up to the near top edge (y = 1, z = 2), across, down from the far one.
        let want = 2.0 * 2f64.sqrt() + 0.5;
        assert!((d.length_m - want).abs() < 5e-3, "{} vs {want}", d.length_m);
        let n = 2.0 * (d.length_m - 2.5) * 500.0 / 343.0;
        let want_gain = 10f64.powf(-10.0 * (3.0 + 20.0 * n).log10() / 20.0);
        assert!((d.gain - want_gain).abs() < 1e-9);
    }
}
