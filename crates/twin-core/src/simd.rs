//! Which vector width the filter's step and the forecast run at on this
//! processor.
//!
//! The workspace is built for the x86-64 baseline (SSE2, two doubles per
//! vector), so its binaries run on any x86-64 machine. The filter's step and
//! the forecast are small dense linear algebra on 4x4 to 8x8 matrices, where
//! AVX2's 256-bit vectors (four doubles) cut the instruction count by about a
//! fifth; [`crate::aekf::Aekf::step`] and [`crate::predict::predict`]
//! therefore carry a second copy of their code compiled with AVX2 and FMA
//! enabled and pick one per call with [`avx2_available`] (a cached CPUID
//! test: one load and one bit test).
//!
//! The two copies give bit-identical numbers. Rust's floating-point
//! semantics forbid the compiler to reassociate or to contract `a * b + c`
//! into a fused multiply-add, so a wider vector only does the same
//! operations, in the same order, more at a time. The tests
//! `both_copies_of_the_step_give_the_same_bits` (in `aekf.rs`) and
//! `both_copies_of_the_forecast_give_the_same_bits` (in `predict.rs`) hold
//! them to that.
//!
//! These two calls are the workspace's only uses of `unsafe` (calling a
//! function compiled for features the baseline lacks, after checking that
//! the processor has them); the lint is `deny`, so any other use fails the
//! build.

/// True if this processor can run code compiled for AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[inline]
pub fn avx2_available() -> bool {
    std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
}

/// Never on processors other than x86-64 (their baseline build is used).
#[cfg(not(target_arch = "x86_64"))]
#[inline]
pub fn avx2_available() -> bool {
    false
}
