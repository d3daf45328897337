//! DoA-ray triangulation, the paper's baseline (Fig. 23): the point closest, in the weighted
//! least-squares sense, to the rays from several arrays along their DoA.
//!
//! For rays through oᵢ along unit dᵢ with weights wᵢ the point minimises
//! Σ wᵢ |(I − dᵢdᵢᵀ)(x − oᵢ)|², i.e. solves Σ wᵢ(I − dᵢdᵢᵀ)·x = Σ wᵢ(I − dᵢdᵢᵀ)·oᵢ. Near-parallel
//! rays make that system singular along the rays: refused when no two rays are more than the
//! given angle apart.

use nalgebra::{Matrix3, Vector3};

use crate::site::ArrayPose;

/// A ray from an array along its DoA.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Array centre, world m.
    pub origin: [f64; 3],
    /// Unit direction towards the source, world frame.
    pub direction: [f64; 3],
    /// Relative weight (e.g. 1/σ² of the bearing, rad⁻²), > 0.
    pub weight: f64,
}

/// The ray of an array's DoA (azimuth from the array's +x towards +y, zenith from its normal,
/// rad), turned into the world by the site's pose, like the filters' bearings
/// ([`crate::filter::world_direction`]).
pub fn ray_from_doa(array: &ArrayPose, azimuth_rad: f64, zenith_rad: f64, weight: f64) -> Ray {
    Ray {
        origin: array.position,
        direction: array.to_world(crate::observation::unit_vector(azimuth_rad, zenith_rad)),
        weight,
    }
}

/// A triangulated point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangulation {
    /// The closest point, world m.
    pub position: [f64; 3],
    /// Rms distance of the point from the rays (lines), m.
    pub rms_distance_m: f64,
    /// Largest angle between two rays, rad.
    pub max_angle_rad: f64,
    /// Rays the point lies behind (their array looks away from it): a sign of a wrong DoA.
    pub behind: usize,
}

/// Why there is no point.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum TriangulationError {
    /// Fewer than two usable rays (finite, weight > 0, non-zero direction).
    #[error("{0} usable rays: two are needed")]
    TooFewRays(usize),
    /// No two rays are more than the minimum angle apart.
    #[error("rays nearly parallel: at most {max_angle_rad} rad apart")]
    NearlyParallel {
        /// Largest angle between two rays, rad.
        max_angle_rad: f64,
    },
}

/// Least-squares closest point of `rays`; refused if no two rays are more than `min_angle_rad`
/// (rad) apart.
pub fn triangulate(rays: &[Ray], min_angle_rad: f64) -> Result<Triangulation, TriangulationError> {
    let usable: Vec<(Vector3<f64>, Vector3<f64>, f64)> = rays
        .iter()
        .filter(|r| {
            r.origin.iter().chain(&r.direction).all(|v| v.is_finite())
                && r.weight.is_finite()
                && r.weight > 0.0
        })
        .filter_map(|r| {
            let d = Vector3::from(r.direction);
            let n = d.norm();
            (n > 0.0).then(|| (Vector3::from(r.origin), d / n, r.weight))
        })
        .collect();
    if usable.len() < 2 {
        return Err(TriangulationError::TooFewRays(usable.len()));
    }
    let mut max_angle: f64 = 0.0;
    for (i, a) in usable.iter().enumerate() {
        for b in &usable[i + 1..] {
            // Angle between the lines (a DoA ray and its opposite are the same line).
            max_angle = max_angle.max(a.1.dot(&b.1).abs().min(1.0).acos());
        }
    }
    if max_angle <= min_angle_rad {
        return Err(TriangulationError::NearlyParallel { max_angle_rad: max_angle });
    }
    let mut a = Matrix3::zeros();
    let mut b = Vector3::zeros();
    for (o, d, w) in &usable {
        let p = Matrix3::identity() - d * d.transpose();
        a += *w * p;
        b += *w * p * o;
    }
    let x =
        a.try_inverse().ok_or(TriangulationError::NearlyParallel { max_angle_rad: max_angle })? * b;
    let (mut ss, mut behind) = (0.0, 0);
    for (o, d, _) in &usable {
        let v = x - o;
        let along = v.dot(d);
        ss += (v - along * d).norm_squared();
        behind += usize::from(along < 0.0);
    }
    Ok(Triangulation {
        position: x.into(),
        rms_distance_m: (ss / usable.len() as f64).sqrt(),
        max_angle_rad: max_angle,
        behind,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::observation::angles_of;

    const SOURCE: [f64; 3] = [4.0, 6.0, 1.8];

    /// Arrays at several poses (yawed, one tilted) seeing the source with exact DoAs in their
    /// own frames: the rays meet at the source.
    #[test]
    fn exact_doas_meet_at_the_source() {
        let poses = [
            ArrayPose::new(1, [0.0, 0.0, 0.5], 0.3, 0.0, 0.0),
            ArrayPose::new(2, [10.0, 0.0, 2.5], -1.2, 0.1, 0.0),
            ArrayPose::new(3, [10.0, 10.0, 0.4], 2.0, 0.0, -0.2),
        ];
        let rays: Vec<Ray> = poses
            .iter()
            .map(|p| {
                let v = [
                    SOURCE[0] - p.position[0],
                    SOURCE[1] - p.position[1],
                    SOURCE[2] - p.position[2],
                ];
                let (az, zen) = angles_of(p.to_array(v));
                ray_from_doa(p, az, zen, 1.0)
            })
            .collect();
        let t = triangulate(&rays, 2f64.to_radians()).unwrap();
        assert!((Vector3::from(t.position) - Vector3::from(SOURCE)).norm() < 1e-9, "{t:?}");
        assert!(t.rms_distance_m < 1e-9 && t.behind == 0);
    }

    /// Two skew lines: the point is the midpoint of their common perpendicular, at the oracle
    /// distance from each.
    #[test]
    fn skew_rays_give_the_midpoint_of_the_common_perpendicular() {
        let rays = [
            Ray { origin: [0.0, 0.0, 0.0], direction: [1.0, 0.0, 0.0], weight: 1.0 },
            Ray { origin: [5.0, -3.0, 2.0], direction: [0.0, 1.0, 0.0], weight: 1.0 },
        ];
        let t = triangulate(&rays, 0.01).unwrap();
        assert!((Vector3::from(t.position) - Vector3::new(5.0, 0.0, 1.0)).norm() < 1e-12, "{t:?}");
        assert!((t.rms_distance_m - 1.0).abs() < 1e-12);
        assert!((t.max_angle_rad - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        // Weights pull the point towards the heavier ray: w₁ / (w₁ + w₂) of the way.
        let heavy = [rays[0], Ray { weight: 3.0, ..rays[1] }];
        let t = triangulate(&heavy, 0.01).unwrap();
        assert!((t.position[2] - 1.5).abs() < 1e-12, "{t:?}");
        // The first ray reversed: the point lies behind it.
        let back = [Ray { direction: [-1.0, 0.0, 0.0], ..rays[0] }, rays[1]];
        assert_eq!(triangulate(&back, 0.01).unwrap().behind, 1);
    }

    #[test]
    fn near_parallel_rays_are_refused() {
        let d = |deg: f64| [deg.to_radians().cos(), deg.to_radians().sin(), 0.0];
        let rays = [
            Ray { origin: [0.0, 0.0, 1.0], direction: d(40.0), weight: 1.0 },
            Ray { origin: [0.5, 0.0, 1.0], direction: d(40.5), weight: 1.0 },
            Ray { origin: [1.0, 0.0, 1.0], direction: d(220.2), weight: 1.0 },
        ];
        let e = triangulate(&rays, 1f64.to_radians()).unwrap_err();
        let TriangulationError::NearlyParallel { max_angle_rad } = e else { panic!("{e:?}") };
        assert!((max_angle_rad - 0.5f64.to_radians()).abs() < 1e-9, "{max_angle_rad}");
        assert_eq!(triangulate(&rays[..1], 0.01), Err(TriangulationError::TooFewRays(1)));
        let nan = Ray { weight: f64::NAN, ..rays[0] };
        assert_eq!(triangulate(&[nan, rays[1]], 0.01), Err(TriangulationError::TooFewRays(1)));
    }
}
