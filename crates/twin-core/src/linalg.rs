//! Small dense linear algebra for the filter's static sizes: Cholesky and
//! square-root-free `L D L^T` factorisations and the solves built on them,
//! small inverses, and products that skip structural zeros.
//!
//! nalgebra's own versions are generic over storage and are not inlined into
//! the filter's step; for 2x2 to 8x8 matrices these plain loops, unrolled by
//! the compiler, are several times faster. Only what the filter needs is
//! here.
//!
//! The products sum each column of their result in a local array and write
//! it once. Summed in the result matrix instead, the 8 x 8 products (whose
//! outer loop the compiler keeps rolled) stored and reloaded every partial
//! sum: about 7 % more instructions per step of the extended twin.

use nalgebra::{SMatrix, SVector};

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

/// The factorisation `a = L D L^T` of a symmetric positive definite matrix
/// (`L` unit lower triangular, `D` diagonal and positive), kept with the
/// reciprocals of `D`: the square-root-free Cholesky. The filter factorises
/// its innovation covariance with it once per step and solves with it
/// several times; without square roots, and with every division done once
/// while factorising, the chain of dependent operations is short.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ldl<const M: usize> {
    /// `L` below the diagonal (the unit diagonal is implied; the upper
    /// triangle is zero).
    pub l: SMatrix<f64, M, M>,
    /// `D`.
    pub d: [f64; M],
    /// `1 / D`.
    pub inv_d: [f64; M],
}

/// The `L D L^T` factorisation of a symmetric matrix `a`, or `None` if `a` is
/// not positive definite (or holds a non-finite number): exactly when
/// [`cholesky`] refuses it. Only the lower triangle of `a` is read.
#[inline(always)]
pub fn ldl<const M: usize>(a: &SMatrix<f64, M, M>) -> Option<Ldl<M>> {
    let mut l = SMatrix::<f64, M, M>::zeros();
    // `w[i][k] = L[i][k] D[k]`, kept to save multiplications.
    let mut w = SMatrix::<f64, M, M>::zeros();
    let mut d = [0.0; M];
    let mut inv_d = [0.0; M];
    for j in 0..M {
        let mut dj = a[(j, j)];
        for k in 0..j {
            dj -= w[(j, k)] * l[(j, k)];
        }
        // Two comparisons, so that NaN and +-inf fail too (cheaper here than
        // `is_finite`, which compiles to integer tests).
        if !(dj > 0.0 && dj < f64::INFINITY) {
            return None;
        }
        let inv = 1.0 / dj;
        d[j] = dj;
        inv_d[j] = inv;
        for i in j + 1..M {
            let mut s = a[(i, j)];
            for k in 0..j {
                s -= w[(i, k)] * l[(j, k)];
            }
            w[(i, j)] = s;
            l[(i, j)] = s * inv;
        }
    }
    Some(Ldl { l, d, inv_d })
}

impl<const M: usize> Ldl<M> {
    /// Solves `L z = b` (unit diagonal).
    #[inline(always)]
    fn forward<const C: usize>(&self, b: &SMatrix<f64, M, C>) -> SMatrix<f64, M, C> {
        let mut z = *b;
        for c in 0..C {
            for i in 0..M {
                let mut s = z[(i, c)];
                for k in 0..i {
                    s -= self.l[(i, k)] * z[(k, c)];
                }
                z[(i, c)] = s;
            }
        }
        z
    }

    /// Solves `a x = b`.
    #[inline(always)]
    pub fn solve<const C: usize>(&self, b: &SMatrix<f64, M, C>) -> SMatrix<f64, M, C> {
        let mut x = self.forward(b);
        for c in 0..C {
            for i in (0..M).rev() {
                let mut s = x[(i, c)] * self.inv_d[i];
                for k in i + 1..M {
                    s -= self.l[(k, i)] * x[(k, c)];
                }
                x[(i, c)] = s;
            }
        }
        x
    }

    /// `b^T a^-1 b` for a vector `b`, from the forward half alone:
    /// `sum z_i^2 / D_i` with `L z = b`.
    #[inline(always)]
    pub fn quadratic_form(&self, b: &SVector<f64, M>) -> f64 {
        let z = self.forward(b);
        let mut sum = 0.0;
        for i in 0..M {
            sum += z[i] * z[i] * self.inv_d[i];
        }
        sum
    }
}

/// The inverse of a small general square matrix: closed forms for 1 x 1 and
/// 2 x 2 (one division, no branches), Gaussian elimination with partial
/// pivoting above; `None` if `a` is singular or not finite.
#[inline(always)]
pub fn inverse_small<const P: usize>(a: &SMatrix<f64, P, P>) -> Option<SMatrix<f64, P, P>> {
    let inv = match P {
        1 => SMatrix::<f64, P, P>::from_element(1.0 / a[(0, 0)]),
        2 => {
            let det = a[(0, 0)] * a[(1, 1)] - a[(0, 1)] * a[(1, 0)];
            let r = 1.0 / det;
            let mut inv = SMatrix::<f64, P, P>::zeros();
            inv[(0, 0)] = a[(1, 1)] * r;
            inv[(0, 1)] = -a[(0, 1)] * r;
            inv[(1, 0)] = -a[(1, 0)] * r;
            inv[(1, 1)] = a[(0, 0)] * r;
            inv
        }
        _ => return solve_general(a, &SMatrix::<f64, P, P>::identity()),
    };
    // A zero determinant gives infinities, a NaN anywhere NaN.
    let mut check = 0.0;
    for v in inv.iter() {
        check += v * 0.0;
    }
    (check == 0.0).then_some(inv)
}

/// Solves `a x = b` for a small general square `a` by Gaussian elimination
/// with partial pivoting, or `None` if `a` is singular (a zero or non-finite
/// pivot). It works on row-major arrays, whose rows the elimination swaps
/// and combines whole, with no index checks left in its loops; inlined, it
/// runs in the step's AVX2 copy (the fault update's `P x P` inverse).
#[inline(always)]
pub fn solve_general<const P: usize, const C: usize>(
    a: &SMatrix<f64, P, P>,
    b: &SMatrix<f64, P, C>,
) -> Option<SMatrix<f64, P, C>> {
    let mut a: [[f64; P]; P] = std::array::from_fn(|i| std::array::from_fn(|k| a[(i, k)]));
    let mut x: [[f64; C]; P] = std::array::from_fn(|i| std::array::from_fn(|c| b[(i, c)]));
    for j in 0..P {
        let mut pivot = j;
        for i in j + 1..P {
            if a[i][j].abs() > a[pivot][j].abs() {
                pivot = i;
            }
        }
        if !(a[pivot][j] != 0.0 && a[pivot][j].is_finite()) {
            return None;
        }
        if pivot != j {
            a.swap(pivot, j);
            x.swap(pivot, j);
        }
        let inv = 1.0 / a[j][j];
        let (a_done, a_below) = a.split_at_mut(j + 1);
        let (x_done, x_below) = x.split_at_mut(j + 1);
        let (a_j, x_j) = (&a_done[j], &x_done[j]);
        for (a_i, x_i) in a_below.iter_mut().zip(x_below.iter_mut()) {
            let f = a_i[j] * inv;
            for (v, pivot_v) in a_i[j..].iter_mut().zip(&a_j[j..]) {
                *v -= f * pivot_v;
            }
            for (v, pivot_v) in x_i.iter_mut().zip(x_j) {
                *v -= f * pivot_v;
            }
        }
    }
    for j in (0..P).rev() {
        let inv = 1.0 / a[j][j];
        let (x_upto, x_after) = x.split_at_mut(j + 1);
        for c in 0..C {
            let mut s = x_upto[j][c];
            for (a_jk, x_k) in a[j][j + 1..].iter().zip(x_after.iter()) {
                s -= a_jk * x_k[c];
            }
            x_upto[j][c] = s * inv;
        }
    }
    Some(SMatrix::from_fn(|i, c| x[i][c]))
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
        let mut acc = [0.0; R];
        for k in 0..K {
            let bkc = b[(k, c)];
            for r in 0..R {
                acc[r] += a[(r, k)] * bkc;
            }
        }
        out.column_mut(c).copy_from_slice(&acc);
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
        let mut acc = [0.0; R];
        for k in 0..K {
            let bck = b[(c, k)];
            for r in 0..R {
                acc[r] += a[(r, k)] * bck;
            }
        }
        out.column_mut(c).copy_from_slice(&acc);
    }
    out
}

/// `a^T b` without forming the transpose.
#[inline(always)]
pub fn mul_tn<const K: usize, const R: usize, const C: usize>(
    a: &SMatrix<f64, K, R>,
    b: &SMatrix<f64, K, C>,
) -> SMatrix<f64, R, C> {
    let mut out = SMatrix::<f64, R, C>::zeros();
    for c in 0..C {
        for r in 0..R {
            let mut s = 0.0;
            for k in 0..K {
                s += a[(k, r)] * b[(k, c)];
            }
            out[(r, c)] = s;
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
        let mut acc = [0.0; R];
        for k in 0..K {
            let bkc = b[(k, c)];
            for r in 0..R {
                if pa[r][k] {
                    acc[r] += a[(r, k)] * bkc;
                }
            }
        }
        out.column_mut(c).copy_from_slice(&acc);
    }
    out
}

/// `a b^T` for a product known to be symmetric (such as `A P A^T` given
/// `a = A P`), where `b` has the pattern `pb`: the lower triangle mirrored,
/// so the result is exactly symmetric. Whole columns are computed (and the
/// upper half then overwritten): more arithmetic than the triangle alone,
/// but in vector instructions, which is faster at these sizes. (The loop is
/// [`mul_t_sparse`]'s; calling it instead measured 1-2 % slower in the
/// extended filter step, by the code LLVM made of it.)
#[inline(always)]
pub fn sym_mul_t_sparse<const N: usize, const K: usize>(
    a: &SMatrix<f64, N, K>,
    b: &SMatrix<f64, N, K>,
    pb: &Pattern<N, K>,
) -> SMatrix<f64, N, N> {
    let mut out = SMatrix::<f64, N, N>::zeros();
    for c in 0..N {
        let mut acc = [0.0; N];
        for k in 0..K {
            if !pb[c][k] {
                continue;
            }
            let bck = b[(c, k)];
            for r in 0..N {
                acc[r] += a[(r, k)] * bck;
            }
        }
        out.column_mut(c).copy_from_slice(&acc);
    }
    mirror_lower(&mut out);
    out
}

/// `a b^T` where `b` has the structural zero pattern `pb`.
#[inline(always)]
pub fn mul_t_sparse<const R: usize, const K: usize, const C: usize>(
    a: &SMatrix<f64, R, K>,
    b: &SMatrix<f64, C, K>,
    pb: &Pattern<C, K>,
) -> SMatrix<f64, R, C> {
    let mut out = SMatrix::<f64, R, C>::zeros();
    for c in 0..C {
        let mut acc = [0.0; R];
        for k in 0..K {
            if !pb[c][k] {
                continue;
            }
            let bck = b[(c, k)];
            for r in 0..R {
                acc[r] += a[(r, k)] * bck;
            }
        }
        out.column_mut(c).copy_from_slice(&acc);
    }
    out
}

/// Copies the lower triangle of `m` over its upper triangle.
#[inline(always)]
pub fn mirror_lower<const N: usize>(m: &mut SMatrix<f64, N, N>) {
    for c in 0..N {
        for r in c + 1..N {
            m[(c, r)] = m[(r, c)];
        }
    }
}

/// Whether `m` is zero wherever `pattern` says an entry is: what the
/// sparse products trust of a model's Jacobians (checked in debug builds).
pub fn within_pattern<const R: usize, const C: usize>(
    m: &SMatrix<f64, R, C>,
    pattern: &Pattern<R, C>,
) -> bool {
    (0..R).all(|r| (0..C).all(|c| pattern[r][c] || m[(r, c)] == 0.0))
}

/// Solves `L y = b` for lower-triangular `L`, column by column.
/// (The tests' reference solve.)
#[cfg(test)]
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
/// (The tests' reference solve.)
#[cfg(test)]
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
/// (The tests' reference solve.)
#[cfg(test)]
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
        let d = nalgebra::SMatrix::<f64, 3, 2>::from_fn(|i, j| (i * 2 + j) as f64 - 1.5);
        assert!((mul_tn(&a, &d) - a.transpose() * d).amax() < 1e-12);
        let mut pa = dense::<3, 4>();
        let mut a0 = a;
        pa[1][2] = false;
        a0[(1, 2)] = 0.0;
        assert!((mul_sparse_left(&a0, &pa, &b) - a0 * b).amax() < 1e-12);
        let mut pc = dense::<2, 4>();
        let mut c0 = c;
        pc[1][3] = false;
        c0[(1, 3)] = 0.0;
        assert!((mul_t_sparse(&a, &c0, &pc) - a * c0.transpose()).amax() < 1e-12);
        let g = nalgebra::SMatrix::<f64, 3, 3>::from_fn(|i, j| (i * 3 + j) as f64 * 0.7 - 2.0);
        let pm = nalgebra::SMatrix::<f64, 3, 3>::from_fn(|i, j| if i == j { 2.0 } else { 0.5 });
        let sym = sym_mul_t_sparse(&(g * pm), &g, &dense());
        assert!((sym - g * pm * g.transpose()).amax() < 1e-12);
        assert_eq!(sym, sym.transpose());
        assert!(diagonal::<3>()[1][1] && !diagonal::<3>()[0][1]);
        // A Jacobian is checked against its declared pattern.
        assert!(within_pattern(&c0, &pc));
        assert!(!within_pattern(&c, &pc));
        assert!(within_pattern(&c, &dense()));
    }

    proptest! {
        /// `L D L^T` solves as the Cholesky factor does, its quadratic form
        /// is `b^T a^-1 b`, and it refuses exactly what Cholesky refuses.
        #[test]
        fn ldl_matches_cholesky(entries in proptest::collection::vec(-3.0f64..3.0, 16), rhs in proptest::collection::vec(-5.0f64..5.0, 4), shift in -2.0f64..0.5) {
            let g = Matrix4::from_iterator(entries);
            let a = g * g.transpose() + Matrix4::identity() * 0.1;
            let f = ldl(&a).unwrap();
            let b = Vector4::from_iterator(rhs);
            let x = f.solve(&b);
            prop_assert!((a * x - b).amax() < 1e-7 * (1.0 + b.amax()));
            prop_assert!((x - cholesky_solve(&cholesky(&a).unwrap(), &b)).amax() < 1e-8 * (1.0 + x.amax()));
            let q = b.dot(&x);
            prop_assert!((f.quadratic_form(&b) - q).abs() < 1e-8 * (1.0 + q.abs()));
            for i in 0..4 {
                prop_assert!((f.d[i] * f.inv_d[i] - 1.0).abs() < 1e-12);
            }
            // Definite or not (away from the boundary, where rounding
            // decides): both agree.
            let c = a - Matrix4::identity() * (a.trace() * shift.max(0.0));
            let lowest = c.symmetric_eigenvalues().min();
            if lowest.abs() > 1e-6 * c.amax() {
                prop_assert_eq!(ldl(&c).is_some(), lowest > 0.0);
                prop_assert_eq!(cholesky(&c).is_some(), lowest > 0.0);
            }
        }

        /// Small inverses and the general solve against nalgebra's.
        #[test]
        fn small_inverses_match_nalgebra(entries in proptest::collection::vec(-3.0f64..3.0, 9)) {
            let a3 = nalgebra::Matrix3::from_iterator(entries.iter().copied()) + nalgebra::Matrix3::identity() * 4.0;
            let inv3 = inverse_small(&a3).unwrap();
            prop_assert!((inv3 * a3 - nalgebra::Matrix3::identity()).amax() < 1e-9);
            let a2 = nalgebra::Matrix2::new(entries[0] + 4.0, entries[1], entries[2], entries[3] - 4.0);
            let inv2 = inverse_small(&a2).unwrap();
            prop_assert!((inv2 - a2.try_inverse().unwrap()).amax() < 1e-12);
            let a1 = nalgebra::Matrix1::new(entries[4] + 4.0);
            prop_assert!((inverse_small(&a1).unwrap()[0] * a1[0] - 1.0).abs() < 1e-15);
        }
    }

    #[test]
    fn singular_and_non_finite_matrices_have_no_inverse() {
        assert!(inverse_small(&nalgebra::Matrix2::new(1.0, 2.0, 2.0, 4.0)).is_none());
        assert!(inverse_small(&nalgebra::Matrix2::new(f64::NAN, 0.0, 0.0, 1.0)).is_none());
        assert!(inverse_small(&nalgebra::Matrix1::new(0.0)).is_none());
        let singular3 = nalgebra::Matrix3::new(1.0, 2.0, 3.0, 2.0, 4.0, 6.0, 0.0, 1.0, 1.0);
        assert!(inverse_small(&singular3).is_none());
        assert!(solve_general(&singular3, &nalgebra::Vector3::new(1.0, 2.0, 3.0)).is_none());
        // A zero first pivot is fine with pivoting.
        let swap = nalgebra::Matrix2::new(0.0, 1.0, 1.0, 0.0);
        assert_eq!(inverse_small(&swap).unwrap(), swap);
        let x = solve_general(&swap, &nalgebra::Vector2::new(3.0, 5.0)).unwrap();
        assert_eq!(x, nalgebra::Vector2::new(5.0, 3.0));
    }

    #[test]
    fn refuses_what_is_not_positive_definite() {
        let mut a = Matrix4::<f64>::identity();
        for bad in [-1.0, 0.0, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            a[(2, 2)] = bad;
            assert!(cholesky(&a).is_none(), "cholesky took a pivot {bad}");
            assert!(ldl(&a).is_none(), "ldl took a pivot {bad}");
        }
        assert!(cholesky(&Matrix4::<f64>::zeros()).is_none());
        assert!(ldl(&Matrix4::<f64>::zeros()).is_none());
        // The smallest positive pivot is still a pivot.
        a[(2, 2)] = f64::MIN_POSITIVE;
        assert!(ldl(&a).is_some());
    }
}
