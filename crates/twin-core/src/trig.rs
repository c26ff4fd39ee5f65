//! The sine and cosine of a heading, both at once, inlined into the models'
//! derivative evaluations.
//!
//! The extended twin's filter step evaluates its dynamics eight times in a
//! turn (two Runge-Kutta sub-steps of four stages), each with the sine and
//! cosine of the heading. Through the C library (`f64::sin_cos`) each pair
//! was a call of about 140 instructions, a fifth of the transition's
//! instructions and cycles. [`sin_cos`] computes the pair in a few dozen
//! instructions that the compiler inlines and interleaves with the rest of
//! the stage.
//!
//! # Method
//! - Argument reduction: `x = n pi/2 + r` with `|r| <= pi/4`, `n` the nearest
//!   integer to `x 2/pi`. `pi/2` is split into three parts
//!   (`PIO2_HI`, `PIO2_MID`, `PIO2_LO`, Cody and Waite 1980): the
//!   first two have 33 significant bits, so `n` times either is exact for
//!   `|n| < 2^20`, and the difference `x - n PIO2_HI` is exact (Sterbenz).
//!   The parts sum to `pi/2` within about `1e-37`, so `r` is good to about
//!   an ulp for `|x| <` [`REDUCED_BELOW`]. Larger and non-finite arguments go to the C
//!   library (NaN and the infinities give NaN, as there).
//! - On `[-pi/4, pi/4]`: the odd and even minimax polynomials of degrees 13
//!   and 14 of FreeBSD's `msun` (Sun's fdlibm) kernels, whose error there is
//!   below `2^-58` relative; with `z = r^2`, the cosine as
//!   `w + ((1 - w) - z/2 + z^2 p(z))` with `w = 1 - z/2`, which keeps the
//!   rounding of `1 - z/2` out of the result.
//! - The quadrant `n mod 4` swaps and negates the pair.
//!
//! The result is within 1 ulp of the C library's for headings (`|x| < 8 pi`)
//! and within 2 ulp below [`REDUCED_BELOW`] (test
//! `agrees_with_the_c_library`), not always bit-equal to it. Plain
//! multiplications and additions only (no fused multiply-add), so the
//! filter's AVX2 and baseline copies give the same bits.

/// The first 33 bits of `pi/2`.
const PIO2_HI: f64 = 1.5707963267341256;
/// The next 33 bits of `pi/2`.
const PIO2_MID: f64 = 6.077100506303966e-11;
/// `pi/2 - PIO2_HI - PIO2_MID`, rounded.
const PIO2_LO: f64 = 2.0222662487959506e-21;
/// Arguments at least this large (in magnitude), and non-finite ones, go to
/// the C library: below it, `|n| < 2^17` and the reduction is exact as
/// described in the module doc.
pub const REDUCED_BELOW: f64 = 100000.0;
/// `1.5 * 2^52`: adding and subtracting it rounds a double of magnitude
/// below `2^51` to the nearest integer (ties to even), without a call.
const ROUND_TO_INTEGER: f64 = 6_755_399_441_055_744.0;

/// Sine kernel coefficients: `sin x = x + x^3 (S1 + x^2 (S2 + ...))`.
const S1: f64 = -0.16666666666666632;
const S2: f64 = 0.00833333333332249;
const S3: f64 = -0.0001984126982985795;
const S4: f64 = 2.7557313707070068e-06;
const S5: f64 = -2.5050760253406863e-08;
const S6: f64 = 1.58969099521155e-10;
/// Cosine kernel coefficients: `cos x = 1 - x^2/2 + x^4 (C1 + x^2 (C2 + ...))`.
const C1: f64 = 0.0416666666666666;
const C2: f64 = -0.001388888888887411;
const C3: f64 = 2.480158728947673e-05;
const C4: f64 = -2.7557314351390663e-07;
const C5: f64 = 2.087572321298175e-09;
const C6: f64 = -1.1359647557788195e-11;

/// `(sin x, cos x)`, within 1 ulp of `x.sin_cos()` for `|x| < 8 pi` and 2 ulp
/// below [`REDUCED_BELOW`] (see the module doc).
#[inline(always)]
pub fn sin_cos(x: f64) -> (f64, f64) {
    // False for NaN too.
    let reducible = x.abs() < REDUCED_BELOW;
    if !reducible {
        return x.sin_cos();
    }
    let shifted = x * std::f64::consts::FRAC_2_PI + ROUND_TO_INTEGER;
    let n = shifted - ROUND_TO_INTEGER;
    // The low bits of `shifted` hold `n` (two's complement within the
    // mantissa, since 2^51 is a multiple of 4).
    let quadrant = shifted.to_bits() & 3;
    let r = ((x - n * PIO2_HI) - n * PIO2_MID) - n * PIO2_LO;

    // The polynomials by Estrin's scheme (pairs of terms in parallel, then
    // powers of z^2): a shorter chain of dependent operations than Horner's,
    // which took 3 % off the extended filter step's cycles. The leading
    // terms (`r`, `1 - z/2`) are added last, so the different rounding of
    // the small tails does not show.
    let z = r * r;
    let z2 = z * z;
    let z4 = z2 * z2;
    let sin_poly = ((S1 + z * S2) + z2 * (S3 + z * S4)) + z4 * (S5 + z * S6);
    let sin_r = r + (z * r) * sin_poly;
    let cos_poly = ((C1 + z * C2) + z2 * (C3 + z * C4)) + z4 * (C5 + z * C6);
    let half_z = 0.5 * z;
    let one_minus = 1.0 - half_z;
    let cos_r = one_minus + (((1.0 - one_minus) - half_z) + z2 * cos_poly);

    match quadrant {
        0 => (sin_r, cos_r),
        1 => (cos_r, -sin_r),
        2 => (-sin_r, -cos_r),
        _ => (-cos_r, sin_r),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};

    /// Units in the last place of `reference` between `value` and it; values
    /// within `1e-300` of each other count as equal (a zero of the function).
    fn ulps(value: f64, reference: f64) -> f64 {
        let diff = (value - reference).abs();
        if diff < 1e-300 {
            return 0.0;
        }
        let ulp = f64::from_bits(reference.abs().to_bits() + 1) - reference.abs();
        diff / ulp
    }

    fn worst_error(xs: impl Iterator<Item = f64>) -> (f64, f64) {
        let mut worst = (0.0f64, 0.0f64);
        for x in xs {
            let (s, c) = sin_cos(x);
            let (s_ref, c_ref) = x.sin_cos();
            let e = ulps(s, s_ref).max(ulps(c, c_ref));
            if e > worst.0 {
                worst = (e, x);
            }
        }
        worst
    }

    #[test]
    fn agrees_with_the_c_library() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        // Headings and the stages around them, densely.
        let (e, x) = worst_error((0..400_000).map(|_| rng.random_range(-8.0 * PI..8.0 * PI)));
        assert!(e <= 1.0, "{e} ulp at {x}");
        // Across the whole reduced range.
        let (e, x) =
            worst_error((0..200_000).map(|_| rng.random_range(-REDUCED_BELOW..REDUCED_BELOW)));
        assert!(e <= 2.0, "{e} ulp at {x}");
        // Tiny arguments, where sin x = x to the last bit.
        let (e, x) = worst_error((0..10_000).map(|_| rng.random_range(-1e-6..1e-6)));
        assert!(e <= 2.0, "{e} ulp at {x}");
        // The doubles nearest the quadrant boundaries and the zeros, where the
        // reduction cancels most and the quadrant flips.
        let special = (-64i32..=64).flat_map(|k| {
            let centre = f64::from(k) * FRAC_PI_4;
            let mut near = vec![centre];
            let mut up = centre;
            let mut down = centre;
            for _ in 0..4 {
                up = f64::from_bits(up.to_bits() + 1);
                down = if down > 0.0 {
                    f64::from_bits(down.to_bits() - 1)
                } else {
                    -f64::from_bits((-down).to_bits() + 1)
                };
                near.push(up);
                near.push(down);
            }
            near
        });
        let (e, x) = worst_error(special);
        assert!(e <= 1.0, "{e} ulp at {x}");
    }

    #[test]
    fn quadrants_have_the_right_signs() {
        for (x, s, c) in [
            (0.0, 0.0, 1.0),
            (FRAC_PI_2, 1.0, 0.0),
            (PI, 0.0, -1.0),
            (-FRAC_PI_2, -1.0, 0.0),
            (3.0 * FRAC_PI_2, -1.0, 0.0),
        ] {
            let (sx, cx) = sin_cos(x);
            assert!(
                (sx - s).abs() < 1e-15 && (cx - c).abs() < 1e-15,
                "{x}: {sx} {cx}"
            );
        }
    }

    #[test]
    fn large_and_non_finite_arguments_are_the_c_librarys() {
        for x in [REDUCED_BELOW, -REDUCED_BELOW, 1e300, -3.7e12] {
            assert_eq!(sin_cos(x), x.sin_cos(), "{x}");
        }
        for x in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let (s, c) = sin_cos(x);
            assert!(s.is_nan() && c.is_nan(), "{x}");
        }
        // Just below the bound: still reduced here, and still accurate.
        let x = f64::from_bits(REDUCED_BELOW.to_bits() - 1);
        let (s, c) = sin_cos(x);
        let (s_ref, c_ref) = x.sin_cos();
        assert!(ulps(s, s_ref) <= 2.0 && ulps(c, c_ref) <= 2.0);
    }
}
