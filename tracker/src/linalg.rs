//! The filters' matrices: nalgebra's fixed-size types, and the two covariance helpers nalgebra
//! does not have.
//!
//! Every matrix of the filters has a size known at compile time (the 9-state EKF's 9×9
//! covariance, 1–3 dimensional measurements, the 3×3 position covariance), so they live on the
//! stack as [`nalgebra::SMatrix`]; products sum in the same order the hand-written matrices of
//! earlier versions did (column by column, k ascending), only the 2×2 and 3×3 inverses and
//! determinants are nalgebra's closed forms.

use nalgebra::{SMatrix, SVector};

/// The `N × N` matrix with `diag` on its diagonal, zeros elsewhere.
pub fn diagonal<const N: usize>(diag: [f64; N]) -> SMatrix<f64, N, N> {
    SMatrix::from_diagonal(&SVector::from(diag))
}

/// `(m + mᵀ) / 2`: removes the asymmetry rounding leaves in a covariance (the diagonal is
/// unchanged).
pub fn symmetrized<const N: usize>(m: &SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    (m + m.transpose()) * 0.5
}

/// Largest absolute difference between `m` and its transpose.
pub fn asymmetry<const N: usize>(m: &SMatrix<f64, N, N>) -> f64 {
    (m - m.transpose()).amax()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;

    #[test]
    fn symmetrized_averages_the_off_diagonal_and_keeps_the_diagonal() {
        let a = Matrix3::new(4.0, 1.0, 0.5, 3.0, 3.0, 0.2, 0.5, -0.2, 2.0);
        assert_eq!(asymmetry(&a), 2.0);
        let s = symmetrized(&a);
        assert_eq!(s, Matrix3::new(4.0, 2.0, 0.5, 2.0, 3.0, 0.0, 0.5, 0.0, 2.0));
        assert_eq!(asymmetry(&s), 0.0);
    }

    #[test]
    fn diagonal_puts_the_values_on_the_diagonal() {
        let d = diagonal([1.0, 2.0, 3.0]);
        assert_eq!(d, Matrix3::new(1.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 3.0));
        // Inverse and determinant (nalgebra's) of the filters' innovation covariances.
        let a = Matrix3::<f64>::new(4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0);
        let p = a * a.try_inverse().unwrap();
        assert!((p - Matrix3::identity()).amax() < 1e-12);
        // det by cofactor expansion: 4(6-0.04) - 1(2-0.1) + 0.5(0.2-1.5)
        assert!((a.determinant() - (4.0 * 5.96 - 1.9 + 0.5 * -1.3)).abs() < 1e-12);
        assert!(Matrix3::new(1.0, 2.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, 1.0).cholesky().is_none());
    }
}
