//! Small dense matrices for the filters (6×6 states, 1–3 dimensional measurements).
//!
//! The filters need products, transposes and the inverse of a small innovation covariance;
//! a row-major `Vec<f64>` is plenty at tens of updates per second and keeps the crate free of
//! a linear-algebra dependency.

use std::ops::{Add, Mul, Sub};

/// A dense row-major matrix of `f64`.
#[derive(Clone, Debug, PartialEq)]
pub struct Mat {
    rows: usize,
    cols: usize,
    data: Vec<f64>,
}

impl Mat {
    /// The `rows × cols` zero matrix.
    pub fn zeros(rows: usize, cols: usize) -> Self {
        Self { rows, cols, data: vec![0.0; rows * cols] }
    }

    /// The `n × n` identity.
    pub fn identity(n: usize) -> Self {
        let mut m = Self::zeros(n, n);
        for i in 0..n {
            m[(i, i)] = 1.0;
        }
        m
    }

    /// A diagonal matrix with `diag` on its diagonal.
    pub fn diagonal(diag: &[f64]) -> Self {
        let mut m = Self::zeros(diag.len(), diag.len());
        for (i, d) in diag.iter().enumerate() {
            m[(i, i)] = *d;
        }
        m
    }

    /// A column vector.
    pub fn column(values: &[f64]) -> Self {
        Self { rows: values.len(), cols: 1, data: values.to_vec() }
    }

    /// A matrix from rows (all of the same length).
    pub fn from_rows(rows: &[&[f64]]) -> Self {
        let cols = rows.first().map_or(0, |r| r.len());
        let mut data = Vec::with_capacity(rows.len() * cols);
        for r in rows {
            assert_eq!(r.len(), cols, "ragged rows");
            data.extend_from_slice(r);
        }
        Self { rows: rows.len(), cols, data }
    }

    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Number of columns.
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// The elements, row-major.
    pub fn as_slice(&self) -> &[f64] {
        &self.data
    }

    /// The transpose.
    pub fn t(&self) -> Self {
        let mut m = Self::zeros(self.cols, self.rows);
        for i in 0..self.rows {
            for j in 0..self.cols {
                m[(j, i)] = self[(i, j)];
            }
        }
        m
    }

    /// `(self + selfᵀ) / 2`: removes the asymmetry rounding leaves in a covariance.
    pub fn symmetrized(&self) -> Self {
        let mut m = self.clone();
        for i in 0..self.rows {
            for j in 0..i {
                let v = 0.5 * (self[(i, j)] + self[(j, i)]);
                m[(i, j)] = v;
                m[(j, i)] = v;
            }
        }
        m
    }

    /// The matrix times a scalar.
    pub fn scaled(&self, k: f64) -> Self {
        Self { rows: self.rows, cols: self.cols, data: self.data.iter().map(|v| v * k).collect() }
    }

    /// The inverse of a square matrix by Gauss–Jordan elimination with partial pivoting,
    /// or `None` if it is singular to working precision.
    pub fn inverse(&self) -> Option<Self> {
        assert_eq!(self.rows, self.cols, "inverse of a non-square matrix");
        let n = self.rows;
        let mut a = self.clone();
        let mut inv = Self::identity(n);
        let scale = self.data.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(f64::MIN_POSITIVE);
        for col in 0..n {
            let pivot = (col..n)
                .max_by(|&i, &j| a[(i, col)].abs().total_cmp(&a[(j, col)].abs()))
                .unwrap_or(col);
            if a[(pivot, col)].abs() <= 1e-14 * scale {
                return None;
            }
            for k in 0..n {
                a.data.swap(col * n + k, pivot * n + k);
                inv.data.swap(col * n + k, pivot * n + k);
            }
            let d = a[(col, col)];
            for k in 0..n {
                a[(col, k)] /= d;
                inv[(col, k)] /= d;
            }
            for i in 0..n {
                if i != col {
                    let f = a[(i, col)];
                    if f != 0.0 {
                        for k in 0..n {
                            a[(i, k)] -= f * a[(col, k)];
                            inv[(i, k)] -= f * inv[(col, k)];
                        }
                    }
                }
            }
        }
        Some(inv)
    }

    /// The lower Cholesky factor of a symmetric positive-definite matrix, or `None` if the
    /// matrix is not positive definite.
    pub fn cholesky(&self) -> Option<Self> {
        assert_eq!(self.rows, self.cols, "Cholesky of a non-square matrix");
        let n = self.rows;
        let mut l = Self::zeros(n, n);
        for i in 0..n {
            for j in 0..=i {
                let mut s = self[(i, j)];
                for k in 0..j {
                    s -= l[(i, k)] * l[(j, k)];
                }
                if i == j {
                    if s <= 0.0 || !s.is_finite() {
                        return None;
                    }
                    l[(i, i)] = s.sqrt();
                } else {
                    l[(i, j)] = s / l[(j, j)];
                }
            }
        }
        Some(l)
    }

    /// The determinant of a square matrix (by elimination).
    pub fn determinant(&self) -> f64 {
        assert_eq!(self.rows, self.cols, "determinant of a non-square matrix");
        let n = self.rows;
        let mut a = self.clone();
        let mut det = 1.0;
        for col in 0..n {
            let pivot = (col..n)
                .max_by(|&i, &j| a[(i, col)].abs().total_cmp(&a[(j, col)].abs()))
                .unwrap_or(col);
            if a[(pivot, col)] == 0.0 {
                return 0.0;
            }
            if pivot != col {
                for k in 0..n {
                    a.data.swap(col * n + k, pivot * n + k);
                }
                det = -det;
            }
            let d = a[(col, col)];
            det *= d;
            for i in col + 1..n {
                let f = a[(i, col)] / d;
                for k in col..n {
                    a[(i, k)] -= f * a[(col, k)];
                }
            }
        }
        det
    }

    /// Largest absolute difference between the matrix and its transpose.
    pub fn asymmetry(&self) -> f64 {
        let mut worst = 0.0f64;
        for i in 0..self.rows {
            for j in 0..self.cols {
                worst = worst.max((self[(i, j)] - self[(j, i)]).abs());
            }
        }
        worst
    }
}

impl std::ops::Index<(usize, usize)> for Mat {
    type Output = f64;
    fn index(&self, (i, j): (usize, usize)) -> &f64 {
        debug_assert!(i < self.rows && j < self.cols);
        &self.data[i * self.cols + j]
    }
}

impl std::ops::IndexMut<(usize, usize)> for Mat {
    fn index_mut(&mut self, (i, j): (usize, usize)) -> &mut f64 {
        debug_assert!(i < self.rows && j < self.cols);
        &mut self.data[i * self.cols + j]
    }
}

impl Mul for &Mat {
    type Output = Mat;
    fn mul(self, rhs: &Mat) -> Mat {
        assert_eq!(self.cols, rhs.rows, "matrix product of mismatched shapes");
        let mut m = Mat::zeros(self.rows, rhs.cols);
        for i in 0..self.rows {
            for k in 0..self.cols {
                let a = self[(i, k)];
                if a != 0.0 {
                    for j in 0..rhs.cols {
                        m.data[i * rhs.cols + j] += a * rhs[(k, j)];
                    }
                }
            }
        }
        m
    }
}

impl Add for &Mat {
    type Output = Mat;
    fn add(self, rhs: &Mat) -> Mat {
        assert_eq!((self.rows, self.cols), (rhs.rows, rhs.cols), "sum of mismatched shapes");
        let data = self.data.iter().zip(&rhs.data).map(|(a, b)| a + b).collect();
        Mat { rows: self.rows, cols: self.cols, data }
    }
}

impl Sub for &Mat {
    type Output = Mat;
    fn sub(self, rhs: &Mat) -> Mat {
        assert_eq!((self.rows, self.cols), (rhs.rows, rhs.cols), "difference of mismatched shapes");
        let data = self.data.iter().zip(&rhs.data).map(|(a, b)| a - b).collect();
        Mat { rows: self.rows, cols: self.cols, data }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_times_matrix_is_identity() {
        let a = Mat::from_rows(&[&[4.0, 1.0, 0.5], &[1.0, 3.0, 0.2], &[0.5, 0.2, 2.0]]);
        let p = &a * &a.inverse().unwrap();
        for i in 0..3 {
            for j in 0..3 {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((p[(i, j)] - want).abs() < 1e-12);
            }
        }
        // det by cofactor expansion: 4(6-0.04) - 1(2-0.1) + 0.5(0.2-1.5)
        assert!((a.determinant() - (4.0 * 5.96 - 1.9 + 0.5 * -1.3)).abs() < 1e-12);
    }

    #[test]
    fn singular_and_indefinite_are_refused() {
        let s = Mat::from_rows(&[&[1.0, 2.0], &[2.0, 4.0]]);
        assert!(s.inverse().is_none());
        assert!(Mat::from_rows(&[&[1.0, 2.0], &[2.0, 1.0]]).cholesky().is_none());
        let l = Mat::from_rows(&[&[4.0, 2.0], &[2.0, 3.0]]).cholesky().unwrap();
        assert_eq!(l.as_slice(), &[2.0, 0.0, 1.0, 2.0f64.sqrt()]);
    }
}
