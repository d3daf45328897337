//! Shoebox room and its image sources (Allen & Berkley 1979).
//!
//! The room spans `[0, Lx] × [0, Ly] × [0, Lz]` in the world frame (ENU m); the floor is z = 0.
//! An image source of order k is the source mirrored k times in the walls; the straight line
//! from an image to a microphone, folded back into the room, is a reflected path. Walls reflect
//! pressure with `β = sqrt(1 − α)` for energy absorption α, the same at all frequencies.
//! Reflections above the simulated order can be added statistically (`reverb`).
use nalgebra::Vector3;

/// Highest reflection order a scenario may ask for (order 12 has 2625 image sources).
pub const MAX_REFLECTION_ORDER: u32 = 12;

/// A shoebox room.
#[derive(Clone, Debug, PartialEq)]
pub struct Room {
    /// Inner dimensions (x, y, z), m.
    pub size_m: [f64; 3],
    /// Energy absorption coefficients of the walls x = 0, x = Lx, y = 0, y = Ly, floor, ceiling.
    pub absorption: [f64; 6],
    /// Highest reflection order simulated exactly (0: direct path only).
    pub reflection_order: u32,
    /// Whether the statistical late tail (`reverb`) adds the reflections above that order.
    pub late_tail: bool,
}

/// One image source: `p' = sign ∘ p + offset`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Image {
    /// Per-axis sign (±1) of the mirroring.
    pub sign: [f64; 3],
    /// Per-axis offset, m.
    pub offset: [f64; 3],
    /// Product of the walls' pressure reflection coefficients along the path.
    pub reflection_gain: f64,
    /// Number of reflections.
    pub order: u32,
    /// Index of the mirrored room (cell) the image lies in, per axis.
    pub cell: [i32; 3],
}

impl Image {
    /// The direct path: no mirroring.
    pub const DIRECT: Image =
        Image { sign: [1.0; 3], offset: [0.0; 3], reflection_gain: 1.0, order: 0, cell: [0; 3] };

    /// The image of point `p`.
    #[inline]
    pub fn apply(&self, p: &Vector3<f64>) -> Vector3<f64> {
        Vector3::new(
            self.sign[0] * p.x + self.offset[0],
            self.sign[1] * p.y + self.offset[1],
            self.sign[2] * p.z + self.offset[2],
        )
    }
}

impl Room {
    /// Checks dimensions and coefficients; names the bad field.
    pub fn validate(&self) -> Result<(), String> {
        if self.size_m.iter().any(|&l| !(l.is_finite() && l > 0.0)) {
            return Err(format!(
                "room.size_m must be three positive lengths, got {:?}",
                self.size_m
            ));
        }
        if self.absorption.iter().any(|&a| !(0.0..=1.0).contains(&a)) {
            return Err(format!("room.absorption must lie in 0..=1, got {:?}", self.absorption));
        }
        if self.reflection_order > MAX_REFLECTION_ORDER {
            return Err(format!(
                "room.reflection_order {} is more than the simulator's limit of {MAX_REFLECTION_ORDER}",
                self.reflection_order
            ));
        }
        Ok(())
    }

    /// Whether `p` lies inside the room (boundary included).
    pub fn contains(&self, p: &Vector3<f64>) -> bool {
        (0..3).all(|i| p[i] >= 0.0 && p[i] <= self.size_m[i])
    }

    /// All image sources up to `reflection_order`, the direct path first.
    pub fn images(&self) -> Vec<Image> {
        let order = self.reflection_order as i32;
        let beta: Vec<f64> = self.absorption.iter().map(|a| (1.0 - a).sqrt()).collect();
        // Per axis: (sign, offset, reflections at the low wall, at the high wall, cell).
        let axis = |ax: usize| {
            let l = self.size_m[ax];
            let mut v = Vec::new();
            for n in -order..=order {
                for u in 0..2 {
                    let low = (n - u).unsigned_abs();
                    let high = n.unsigned_abs();
                    if (low + high) as i32 > order {
                        continue;
                    }
                    let sign = if u == 0 { 1.0 } else { -1.0 };
                    let cell = if u == 0 { 2 * n } else { 2 * n - 1 };
                    v.push((sign, 2.0 * n as f64 * l, low, high, cell));
                }
            }
            v
        };
        let (ax, ay, az) = (axis(0), axis(1), axis(2));
        let mut images = Vec::new();
        for x in &ax {
            for y in &ay {
                for z in &az {
                    let order = x.2 + x.3 + y.2 + y.3 + z.2 + z.3;
                    if order > self.reflection_order {
                        continue;
                    }
                    let reflection_gain = beta[0].powi(x.2 as i32)
                        * beta[1].powi(x.3 as i32)
                        * beta[2].powi(y.2 as i32)
                        * beta[3].powi(y.3 as i32)
                        * beta[4].powi(z.2 as i32)
                        * beta[5].powi(z.3 as i32);
                    images.push(Image {
                        sign: [x.0, y.0, z.0],
                        offset: [x.1, y.1, z.1],
                        reflection_gain,
                        order,
                        cell: [x.4, y.4, z.4],
                    });
                }
            }
        }
        images.sort_by_key(|i| i.order);
        images
    }

    /// Folds a point of the unfolded (mirrored) space back into the real room.
    pub fn fold(&self, p: &Vector3<f64>) -> Vector3<f64> {
        let mut out = Vector3::zeros();
        for i in 0..3 {
            let l = self.size_m[i];
            let c = (p[i] / l).floor();
            let local = p[i] - c * l;
            out[i] = if (c as i64).rem_euclid(2) == 0 { local } else { l - local };
        }
        out
    }

    /// The pieces, in the real room, of the unfolded straight segment `a → b`: it is cut where it
    /// crosses a wall plane and each piece is folded back. Used to test reflected paths against
    /// obstacles.
    pub fn folded_pieces(
        &self,
        a: &Vector3<f64>,
        b: &Vector3<f64>,
    ) -> Vec<(Vector3<f64>, Vector3<f64>)> {
        let d = b - a;
        let mut cuts = vec![0.0, 1.0];
        for i in 0..3 {
            if d[i].abs() < 1e-15 {
                continue;
            }
            let l = self.size_m[i];
            let (lo, hi) = (a[i].min(b[i]), a[i].max(b[i]));
            let mut k = (lo / l).ceil();
            while k * l < hi {
                let t = (k * l - a[i]) / d[i];
                if t > 0.0 && t < 1.0 {
                    cuts.push(t);
                }
                k += 1.0;
            }
        }
        cuts.sort_by(|x, y| x.total_cmp(y));
        cuts.windows(2)
            .filter(|w| w[1] - w[0] > 1e-12)
            .map(|w| {
                let mid = a + d * ((w[0] + w[1]) / 2.0);
                // Fold both ends with the mirror of the piece's own cell (the midpoint's cell).
                let fold_in = |p: Vector3<f64>| {
                    let mut out = Vector3::zeros();
                    for i in 0..3 {
                        let l = self.size_m[i];
                        let c = (mid[i] / l).floor();
                        let local = p[i] - c * l;
                        out[i] = if (c as i64).rem_euclid(2) == 0 { local } else { l - local };
                    }
                    out
                };
                (fold_in(a + d * w[0]), fold_in(a + d * w[1]))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn room(order: u32) -> Room {
        Room {
            size_m: [5.0, 4.0, 3.0],
            absorption: [0.19; 6],
            reflection_order: order,
            late_tail: false,
        }
    }

    #[test]
    fn image_counts_match_the_lattice() {
        // Number of lattice images of order ≤ k in 3-D: 1, 7, 25, 63 (octahedral numbers).
        for (k, n) in [(0, 1), (1, 7), (2, 25), (3, 63)] {
            assert_eq!(room(k).images().len(), n, "order {k}");
        }
    }

    #[test]
    fn first_order_images_mirror_in_each_wall() {
        let r = room(1);
        let s = Vector3::new(1.0, 1.5, 2.0);
        let mut got: Vec<Vector3<f64>> =
            r.images().iter().filter(|i| i.order == 1).map(|i| i.apply(&s)).collect();
        let mut want = vec![
            Vector3::new(-1.0, 1.5, 2.0),
            Vector3::new(9.0, 1.5, 2.0),
            Vector3::new(1.0, -1.5, 2.0),
            Vector3::new(1.0, 6.5, 2.0),
            Vector3::new(1.0, 1.5, -2.0),
            Vector3::new(1.0, 1.5, 4.0),
        ];
        let key = |v: &Vector3<f64>| {
            (v.x * 1e3) as i64 * 1_000_000 + (v.y * 1e3) as i64 * 1000 + (v.z * 1e3) as i64
        };
        got.sort_by_key(key);
        want.sort_by_key(key);
        assert_eq!(got, want);
        for i in r.images().iter().filter(|i| i.order == 1) {
            assert!((i.reflection_gain - 0.9).abs() < 1e-12);
            // The image lies in the cell the lattice index says.
            let p = i.apply(&s);
            for ax in 0..3 {
                assert_eq!((p[ax] / r.size_m[ax]).floor() as i32, i.cell[ax]);
            }
        }
    }

    #[test]
    fn folded_pieces_reflect_off_the_wall() {
        let r = room(1);
        let m = Vector3::new(4.0, 2.0, 1.0);
        // Image of (4, 2, 1) in the wall x = 5 is (6, 2, 1): the path hits the wall at x = 5.
        let image = Vector3::new(6.0, 2.0, 1.0);
        let pieces = r.folded_pieces(&image, &m);
        assert_eq!(pieces.len(), 2);
        for (a, b) in &pieces {
            assert!(r.contains(a) && r.contains(b));
        }
        assert!((pieces[0].0 - Vector3::new(4.0, 2.0, 1.0)).norm() < 1e-12);
        assert!((pieces[0].1 - Vector3::new(5.0, 2.0, 1.0)).norm() < 1e-12);
    }
}
