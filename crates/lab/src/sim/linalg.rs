//! Small dense linear algebra for the rotor model (row-major `Vec<f64>` square matrices):
//! solve, inverse, Cholesky and the symmetric eigenproblem (cyclic Jacobi). Sizes are tens
//! of unknowns, built once per simulation, so clarity beats speed here.

/// A dense square matrix, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Mat {
    pub n: usize,
    pub a: Vec<f64>,
}

impl Mat {
    pub fn zeros(n: usize) -> Mat {
        Mat {
            n,
            a: vec![0.0; n * n],
        }
    }

    pub fn identity(n: usize) -> Mat {
        let mut m = Mat::zeros(n);
        for i in 0..n {
            m[(i, i)] = 1.0;
        }
        m
    }

    pub fn mul(&self, b: &Mat) -> Mat {
        let n = self.n;
        let mut c = Mat::zeros(n);
        for i in 0..n {
            for k in 0..n {
                let aik = self[(i, k)];
                if aik != 0.0 {
                    for j in 0..n {
                        c.a[i * n + j] += aik * b.a[k * n + j];
                    }
                }
            }
        }
        c
    }

    pub fn transpose(&self) -> Mat {
        let n = self.n;
        let mut t = Mat::zeros(n);
        for i in 0..n {
            for j in 0..n {
                t[(j, i)] = self[(i, j)];
            }
        }
        t
    }

    pub fn mul_vec(&self, x: &[f64]) -> Vec<f64> {
        (0..self.n)
            .map(|i| (0..self.n).map(|j| self[(i, j)] * x[j]).sum())
            .collect()
    }

    /// Solve `self * x = b` by Gaussian elimination with partial pivoting.
    pub fn solve(&self, b: &[f64]) -> Option<Vec<f64>> {
        let n = self.n;
        let mut m = self.a.clone();
        let mut x = b.to_vec();
        for c in 0..n {
            let p = (c..n).max_by(|&i, &j| m[i * n + c].abs().total_cmp(&m[j * n + c].abs()))?;
            if m[p * n + c].abs() < 1e-300 {
                return None;
            }
            if p != c {
                for j in 0..n {
                    m.swap(p * n + j, c * n + j);
                }
                x.swap(p, c);
            }
            for r in c + 1..n {
                let f = m[r * n + c] / m[c * n + c];
                if f != 0.0 {
                    for j in c..n {
                        m[r * n + j] -= f * m[c * n + j];
                    }
                    x[r] -= f * x[c];
                }
            }
        }
        for c in (0..n).rev() {
            let s: f64 = (c + 1..n).map(|j| m[c * n + j] * x[j]).sum();
            x[c] = (x[c] - s) / m[c * n + c];
        }
        Some(x)
    }

    pub fn inverse(&self) -> Option<Mat> {
        let n = self.n;
        let mut inv = Mat::zeros(n);
        for j in 0..n {
            let mut e = vec![0.0; n];
            e[j] = 1.0;
            let col = self.solve(&e)?;
            for i in 0..n {
                inv[(i, j)] = col[i];
            }
        }
        Some(inv)
    }

    /// Lower Cholesky factor of a symmetric positive definite matrix.
    pub fn cholesky(&self) -> Option<Mat> {
        let n = self.n;
        let mut l = Mat::zeros(n);
        for i in 0..n {
            for j in 0..=i {
                let s: f64 = (0..j).map(|k| l[(i, k)] * l[(j, k)]).sum();
                if i == j {
                    let d = self[(i, i)] - s;
                    if d <= 0.0 {
                        return None;
                    }
                    l[(i, j)] = d.sqrt();
                } else {
                    l[(i, j)] = (self[(i, j)] - s) / l[(j, j)];
                }
            }
        }
        Some(l)
    }
}

impl std::ops::Index<(usize, usize)> for Mat {
    type Output = f64;
    fn index(&self, (i, j): (usize, usize)) -> &f64 {
        &self.a[i * self.n + j]
    }
}

impl std::ops::IndexMut<(usize, usize)> for Mat {
    fn index_mut(&mut self, (i, j): (usize, usize)) -> &mut f64 {
        &mut self.a[i * self.n + j]
    }
}

/// Eigenvalues (ascending) and eigenvectors (columns) of a symmetric matrix (cyclic Jacobi).
pub fn symmetric_eigen(s: &Mat) -> (Vec<f64>, Mat) {
    let n = s.n;
    let mut a = s.clone();
    let mut v = Mat::identity(n);
    for _sweep in 0..100 {
        let off: f64 = (0..n)
            .flat_map(|i| (0..n).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| a[(i, j)].powi(2))
            .sum();
        let diag: f64 = (0..n).map(|i| a[(i, i)].powi(2)).sum();
        if off <= 1e-30 * diag.max(1e-300) {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                let apq = a[(p, q)];
                if apq.abs() < 1e-300 {
                    continue;
                }
                let theta = (a[(q, q)] - a[(p, p)]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let sn = t * c;
                for k in 0..n {
                    let akp = a[(k, p)];
                    let akq = a[(k, q)];
                    a[(k, p)] = c * akp - sn * akq;
                    a[(k, q)] = sn * akp + c * akq;
                }
                for k in 0..n {
                    let apk = a[(p, k)];
                    let aqk = a[(q, k)];
                    a[(p, k)] = c * apk - sn * aqk;
                    a[(q, k)] = sn * apk + c * aqk;
                }
                for k in 0..n {
                    let vkp = v[(k, p)];
                    let vkq = v[(k, q)];
                    v[(k, p)] = c * vkp - sn * vkq;
                    v[(k, q)] = sn * vkp + c * vkq;
                }
            }
        }
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&i, &j| a[(i, i)].total_cmp(&a[(j, j)]));
    let vals = order.iter().map(|&i| a[(i, i)]).collect();
    let mut vecs = Mat::zeros(n);
    for (c, &i) in order.iter().enumerate() {
        for k in 0..n {
            vecs[(k, c)] = v[(k, i)];
        }
    }
    (vals, vecs)
}

/// Generalised symmetric-definite eigenproblem K phi = lambda M phi: eigenvalues ascending,
/// M-normalised eigenvectors as columns.
pub fn generalized_eigen(k: &Mat, m: &Mat) -> Option<(Vec<f64>, Mat)> {
    let l = m.cholesky()?;
    let li = l.inverse()?;
    let s = li.mul(k).mul(&li.transpose());
    let mut sym = s.clone();
    for i in 0..s.n {
        for j in 0..s.n {
            sym[(i, j)] = 0.5 * (s[(i, j)] + s[(j, i)]);
        }
    }
    let (vals, y) = symmetric_eigen(&sym);
    Some((vals, li.transpose().mul(&y)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_mass_chain_eigenvalues() {
        // m = 1, k = 1: masses on springs ground-1-2 -> lambda = (3 -+ sqrt 5) / 2
        let k = Mat {
            n: 2,
            a: vec![2.0, -1.0, -1.0, 1.0],
        };
        let m = Mat::identity(2);
        let (vals, vecs) = generalized_eigen(&k, &m).unwrap();
        assert!((vals[0] - (3.0 - 5f64.sqrt()) / 2.0).abs() < 1e-12);
        assert!((vals[1] - (3.0 + 5f64.sqrt()) / 2.0).abs() < 1e-12);
        let kv = k.mul_vec(&[vecs[(0, 0)], vecs[(1, 0)]]);
        assert!((kv[0] - vals[0] * vecs[(0, 0)]).abs() < 1e-12);
    }

    #[test]
    fn solve_and_inverse() {
        let a = Mat {
            n: 3,
            a: vec![4.0, 1.0, 0.0, 1.0, 3.0, 1.0, 0.0, 1.0, 2.0],
        };
        let x = a.solve(&[1.0, 2.0, 3.0]).unwrap();
        let b = a.mul_vec(&x);
        for (bi, ei) in b.iter().zip([1.0, 2.0, 3.0]) {
            assert!((bi - ei).abs() < 1e-12);
        }
        let p = a.mul(&a.inverse().unwrap());
        for i in 0..3 {
            for j in 0..3 {
                assert!((p[(i, j)] - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12);
            }
        }
    }
}
