//! Small dense linear algebra for the filter's static sizes: a Cholesky
//! factorisation and the solves built on it.
//!
//! nalgebra's own versions are generic over storage and are not inlined into
//! the filter's step; for 2x2 to 8x8 matrices these plain loops, fully
//! unrolled by the compiler, are several times faster. Only what the filter
//! needs is here.

use nalgebra::SMatrix;

/// The lower-triangular Cholesky factor `L` of a symmetric matrix `a`
/// (`a = L L^T`), or `None` if `a` is not positive definite (or holds a
/// non-finite number). Only the lower triangle of `a` is read.
#[inline]
pub fn cholesky<const M: usize>(a: &SMatrix<f64, M, M>) -> Option<SMatrix<f64, M, M>> {
    let mut l = SMatrix::<f64, M, M>::zeros();
    for j in 0..M {
        let mut d = a[(j, j)];
        for k in 0..j {
            d -= l[(j, k)] * l[(j, k)];
        }
        // Written so that NaN fails too.
        if !(d > 0.0 && d.is_finite()) {
            return None;
        }
        let d = d.sqrt();
        l[(j, j)] = d;
        let inv = 1.0 / d;
        for i in j + 1..M {
            let mut s = a[(i, j)];
            for k in 0..j {
                s -= l[(i, k)] * l[(j, k)];
            }
            l[(i, j)] = s * inv;
        }
    }
    Some(l)
}

/// `a b`, as plain loops the compiler unrolls (nalgebra's generic product is
/// not inlined at these sizes).
#[inline(always)]
pub fn mul<const R: usize, const K: usize, const C: usize>(
    a: &SMatrix<f64, R, K>,
    b: &SMatrix<f64, K, C>,
) -> SMatrix<f64, R, C> {
    let mut out = SMatrix::<f64, R, C>::zeros();
    for c in 0..C {
        for k in 0..K {
            let bkc = b[(k, c)];
            for r in 0..R {
                out[(r, c)] += a[(r, k)] * bkc;
            }
        }
    }
    out
}

/// `a b^T` without forming the transpose.
#[inline(always)]
pub fn mul_t<const R: usize, const K: usize, const C: usize>(
    a: &SMatrix<f64, R, K>,
    b: &SMatrix<f64, C, K>,
) -> SMatrix<f64, R, C> {
    let mut out = SMatrix::<f64, R, C>::zeros();
    for c in 0..C {
        for k in 0..K {
            let bck = b[(c, k)];
            for r in 0..R {
                out[(r, c)] += a[(r, k)] * bck;
            }
        }
    }
    out
}

/// A structural zero pattern: `true` where an entry may be non-zero. Models
/// declare the patterns of their Jacobians as constants, and the products
/// below skip the known zeros; once inlined and unrolled the compiler drops
/// them entirely, so the seed's sparse Jacobians cost a fraction of dense ones.
pub type Pattern<const R: usize, const C: usize> = [[bool; C]; R];

/// A pattern with every entry possibly non-zero.
pub const fn dense<const R: usize, const C: usize>() -> Pattern<R, C> {
    [[true; C]; R]
}

/// The identity pattern.
pub const fn diagonal<const N: usize>() -> Pattern<N, N> {
    let mut p = [[false; N]; N];
    let mut i = 0;
    while i < N {
        p[i][i] = true;
        i += 1;
    }
    p
}

/// `a b` where `a` has the structural zero pattern `pa`.
#[inline(always)]
pub fn mul_sparse_left<const R: usize, const K: usize, const C: usize>(
    a: &SMatrix<f64, R, K>,
    pa: &Pattern<R, K>,
    b: &SMatrix<f64, K, C>,
) -> SMatrix<f64, R, C> {
    let mut out = SMatrix::<f64, R, C>::zeros();
    for c in 0..C {
        for k in 0..K {
            let bkc = b[(k, c)];
            for r in 0..R {
                if pa[r][k] {
                    out[(r, c)] += a[(r, k)] * bkc;
                }
            }
        }
    }
    out
}

/// `a b` where `b` has the structural zero pattern `pb`.
#[inline(always)]
pub fn mul_sparse_right<const R: usize, const K: usize, const C: usize>(
    a: &SMatrix<f64, R, K>,
    b: &SMatrix<f64, K, C>,
    pb: &Pattern<K, C>,
) -> SMatrix<f64, R, C> {
    let mut out = SMatrix::<f64, R, C>::zeros();
    for c in 0..C {
        for k in 0..K {
            if !pb[k][c] {
                continue;
            }
            let bkc = b[(k, c)];
            for r in 0..R {
                out[(r, c)] += a[(r, k)] * bkc;
            }
        }
    }
    out
}

/// `a b^T` for a product known to be symmetric (such as `A P A^T` given
/// `a = A P`), where `b` has the pattern `pb`: computes the lower triangle
/// and mirrors it, so the result is exactly symmetric.
#[inline(always)]
pub fn sym_mul_t_sparse<const N: usize, const K: usize>(
    a: &SMatrix<f64, N, K>,
    b: &SMatrix<f64, N, K>,
    pb: &Pattern<N, K>,
) -> SMatrix<f64, N, N> {
    let mut out = SMatrix::<f64, N, N>::zeros();
    for c in 0..N {
        for k in 0..K {
            if !pb[c][k] {
                continue;
            }
            let bck = b[(c, k)];
            for r in c..N {
                out[(r, c)] += a[(r, k)] * bck;
            }
        }
    }
    for c in 0..N {
        for r in c + 1..N {
            out[(c, r)] = out[(r, c)];
        }
    }
    out
}

/// Solves `L y = b` for lower-triangular `L`, column by column.
#[inline]
pub fn solve_lower<const M: usize, const C: usize>(
    l: &SMatrix<f64, M, M>,
    b: &SMatrix<f64, M, C>,
) -> SMatrix<f64, M, C> {
    let inv_diag: [f64; M] = std::array::from_fn(|i| 1.0 / l[(i, i)]);
    let mut y = *b;
    for c in 0..C {
        for i in 0..M {
            let mut s = y[(i, c)];
            for k in 0..i {
                s -= l[(i, k)] * y[(k, c)];
            }
            y[(i, c)] = s * inv_diag[i];
        }
    }
    y
}

/// Solves `L^T x = y` for lower-triangular `L`, column by column.
#[inline]
pub fn solve_upper_transposed<const M: usize, const C: usize>(
    l: &SMatrix<f64, M, M>,
    y: &SMatrix<f64, M, C>,
) -> SMatrix<f64, M, C> {
    let inv_diag: [f64; M] = std::array::from_fn(|i| 1.0 / l[(i, i)]);
    let mut x = *y;
    for c in 0..C {
        for i in (0..M).rev() {
            let mut s = x[(i, c)];
            for k in i + 1..M {
                s -= l[(k, i)] * x[(k, c)];
            }
            x[(i, c)] = s * inv_diag[i];
        }
    }
    x
}

/// Solves `A x = b` given the Cholesky factor `L` of `A`.
#[inline]
pub fn cholesky_solve<const M: usize, const C: usize>(
    l: &SMatrix<f64, M, M>,
    b: &SMatrix<f64, M, C>,
) -> SMatrix<f64, M, C> {
    solve_upper_transposed(l, &solve_lower(l, b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix4, Vector4};
    use proptest::prelude::*;

    proptest! {
        /// Against nalgebra's own factorisation and solve on random SPD matrices.
        #[test]
        fn matches_nalgebra(entries in proptest::collection::vec(-3.0f64..3.0, 16), rhs in proptest::collection::vec(-5.0f64..5.0, 4)) {
            let g = Matrix4::from_iterator(entries);
            let a = g * g.transpose() + Matrix4::identity() * 0.1;
            let l = cholesky(&a).unwrap();
            let reference = nalgebra::Cholesky::new(a).unwrap();
            prop_assert!((l - reference.l()).amax() < 1e-9);
            let b = Vector4::from_iterator(rhs);
            let x = cholesky_solve(&l, &b);
            prop_assert!((a * x - b).amax() < 1e-7 * (1.0 + b.amax()));
        }
    }

    #[test]
    fn products_match_nalgebra() {
        let a = nalgebra::SMatrix::<f64, 3, 4>::from_fn(|i, j| (i * 7 + j * 3) as f64 - 4.5);
        let b = nalgebra::SMatrix::<f64, 4, 2>::from_fn(|i, j| (i * 2 + j * 5) as f64 * 0.3 - 1.0);
        let c = nalgebra::SMatrix::<f64, 2, 4>::from_fn(|i, j| (i + j * j) as f64 - 2.0);
        assert!((mul(&a, &b) - a * b).amax() < 1e-12);
        assert!((mul_t(&a, &c) - a * c.transpose()).amax() < 1e-12);
        let mut pa = dense::<3, 4>();
        let mut a0 = a;
        pa[1][2] = false;
        a0[(1, 2)] = 0.0;
        assert!((mul_sparse_left(&a0, &pa, &b) - a0 * b).amax() < 1e-12);
        let mut pb = dense::<4, 2>();
        let mut b0 = b;
        pb[3][0] = false;
        b0[(3, 0)] = 0.0;
        assert!((mul_sparse_right(&a, &b0, &pb) - a * b0).amax() < 1e-12);
        let g = nalgebra::SMatrix::<f64, 3, 3>::from_fn(|i, j| (i * 3 + j) as f64 * 0.7 - 2.0);
        let pm = nalgebra::SMatrix::<f64, 3, 3>::from_fn(|i, j| if i == j { 2.0 } else { 0.5 });
        let sym = sym_mul_t_sparse(&(g * pm), &g, &dense());
        assert!((sym - g * pm * g.transpose()).amax() < 1e-12);
        assert_eq!(sym, sym.transpose());
        assert!(diagonal::<3>()[1][1] && !diagonal::<3>()[0][1]);
    }

    #[test]
    fn refuses_what_is_not_positive_definite() {
        let mut a = Matrix4::<f64>::identity();
        a[(2, 2)] = -1.0;
        assert!(cholesky(&a).is_none());
        a[(2, 2)] = f64::NAN;
        assert!(cholesky(&a).is_none());
        assert!(cholesky(&Matrix4::<f64>::zeros()).is_none());
    }
}
