//! The sine and cosine of the path reference's heading: [`sincosf`], `libm`'s own operations for
//! the headings [`Observation::check`](crate::observation::Observation::check) admits, without
//! its large-argument reduction.
//!
//! `libm::sincosf` reduces an argument beyond 9π/4 with `rem_pio2f` and `rem_pio2_large` (Payne
//! and Hanek's, with 2/π to hundreds of bits): about 3 K of code and tables on the car and a
//! 768-byte stack frame, which a heading within ±π never reaches, but which the linker keeps
//! since nothing tells it so. [`sincosf`] copies the branches of `libm::sincosf` that cover
//! |x| ≤ 5π/4 (a validated heading lies within |x| ≤ `f32::consts::PI`, 0x40490fdb, the
//! `f32` just above π) and its two kernels with their `f64` coefficients: the same operations in
//! the same order, so the same bits (every `f32` of that range compared with `libm::sincosf`:
//! `cargo test -p firmware-core --release --lib -- --ignored sincosf_exhaustive`). Beyond
//! 5π/4, where no validated heading goes, the host takes `libm::sincosf` itself (so the same bits
//! everywhere) and the car reduces by 2π once (see [`sincosf`]).
//!
//! The code below is adapted from the `libm` crate 0.2.16 (`src/math/sincosf.rs`, `k_sinf.rs`,
//! `k_cosf.rs`; <https://github.com/rust-lang/compiler-builtins>), which carries this notice:
//!
//! > rust-lang/libm as a whole is available for use under the MIT license:
//! >
//! > Permission is hereby granted, free of charge, to any person obtaining a copy of this
//! > software and associated documentation files (the "Software"), to deal in the Software
//! > without restriction, including without limitation the rights to use, copy, modify, merge,
//! > publish, distribute, sublicense, and/or sell copies of the Software, and to permit persons
//! > to whom the Software is furnished to do so, subject to the following conditions:
//! >
//! > The above copyright notice and this permission notice shall be included in all copies or
//! > substantial portions of the Software.
//! >
//! > THE SOFTWARE IS PROVIDED "AS IS", WITHOUT WARRANTY OF ANY KIND, EXPRESS OR IMPLIED,
//! > INCLUDING BUT NOT LIMITED TO THE WARRANTIES OF MERCHANTABILITY, FITNESS FOR A PARTICULAR
//! > PURPOSE AND NONINFRINGEMENT. IN NO EVENT SHALL THE AUTHORS OR COPYRIGHT HOLDERS BE LIABLE
//! > FOR ANY CLAIM, DAMAGES OR OTHER LIABILITY, WHETHER IN AN ACTION OF CONTRACT, TORT OR
//! > OTHERWISE, ARISING FROM, OUT OF OR IN CONNECTION WITH THE SOFTWARE OR THE USE OR OTHER
//! > DEALINGS IN THE SOFTWARE.
//!
//! and which took them from FreeBSD (`/usr/src/lib/msun/src/s_sinf.c`, `k_sinf.c`, `k_cosf.c`;
//! conversion to float by Ian Lance Taylor, Cygnus Support, ian@cygnus.com; optimized and
//! debugged by Bruce D. Evans), under this notice:
//!
//! > Copyright (C) 1993 by Sun Microsystems, Inc. All rights reserved.
//! >
//! > Developed at SunPro, a Sun Microsystems, Inc. business.
//! > Permission to use, copy, modify, and distribute this
//! > software is freely granted, provided that this notice
//! > is preserved.

// `libm`'s literals verbatim, digits beyond an `f64`'s and its π/2 as it writes it.
#![allow(clippy::excessive_precision, clippy::approx_constant)]

/// π/2 rounded to double precision, and its multiples (`libm`'s `S1PIO2`, `S2PIO2`, `S4PIO2`).
const PI_2: f64 = 0.5 * 3.1415926535897931160E+00;
const S1PIO2: f64 = PI_2; /* 0x3FF921FB, 0x54442D18 */
const S2PIO2: f64 = 2.0 * PI_2; /* 0x400921FB, 0x54442D18 */

/// |x| ~<= 5π/4: the largest `|x|.to_bits()` the copied branches of `libm::sincosf` cover.
const NEAR_BITS: u32 = 0x407b_53d1;

/// `sin(x)` and `cos(x)`, as `libm::sincosf(x)`, the same bits for every `x` with
/// |x| ≲ 5π/4, which includes every heading [`Observation::check`] admits (|x| ≤
/// `f32::consts::PI`).
///
/// Beyond 5π/4 (never a validated heading): on the host `libm::sincosf` itself, so the same bits
/// for every `x`; on the car (`target_arch = "arm"`, where `libm`'s large-argument reduction is
/// what this function leaves out) one reduction by 2π in `f64` and the same branches, within a
/// few `f32` ulps of `sin` and `cos` up to |x| ≈ 10⁶, and NaN for an infinity, a NaN or an `x`
/// beyond 2⁵¹·2π (debug builds assert that the car never gets there).
///
/// [`Observation::check`]: crate::observation::Observation::check
#[inline]
pub fn sincosf(x: f32) -> (f32, f32) {
    let ix = x.to_bits() & 0x7fff_ffff;
    if ix <= NEAR_BITS { near(x, ix) } else { far(x) }
}

/// `libm::sincosf`'s branches for |x| ~<= 5π/4, `ix` the bits of |x|: the same kernels on the
/// same `f64` argument, their results put in place as `libm` does in each branch (each kernel
/// written once, so inlined once). `libm` also makes the tiny arguments raise the inexact and
/// underflow flags, which Rust cannot read.
#[inline]
fn near(x: f32, ix: u32) -> (f32, f32) {
    let sign = (x.to_bits() >> 31) != 0;

    /* |x| < 2**-12 */
    if ix < 0x3980_0000 {
        return (x, 1.0);
    }
    let x64 = x as f64;
    // The kernels' argument, and which branch of `libm`'s took it.
    let (y, branch) = if ix <= 0x3f49_0fda {
        /* |x| ~<= pi/4 */
        (x64, Branch::Quarter)
    } else if ix <= 0x4016_cbe3 {
        /* |x| ~<= 3pi/4 */
        if sign {
            (x64 + S1PIO2, Branch::MinusHalf)
        } else {
            (S1PIO2 - x64, Branch::PlusHalf)
        }
    }
    /* |x| ~<= 5*pi/4 */
    /* -sin(x+c) is not correct if x+c could be 0: -0 vs +0 */
    else if sign {
        (x64 + S2PIO2, Branch::Whole)
    } else {
        (x64 - S2PIO2, Branch::Whole)
    };
    let s = k_sinf(y);
    let c = k_cosf(y);
    match branch {
        Branch::Quarter => (s, c),
        Branch::PlusHalf => (c, s),
        Branch::MinusHalf => (-c, s),
        Branch::Whole => (-s, -c),
    }
}

/// The branches of `libm::sincosf` that [`near`] takes, by the multiple of π/2 their kernels'
/// argument is taken from `x`.
#[derive(Clone, Copy)]
enum Branch {
    /// |x| ~<= π/4: `(k_sinf(x), k_cosf(x))`.
    Quarter,
    /// π/4 < x ~<= 3π/4: `(k_cosf(π/2 − x), k_sinf(π/2 − x))`.
    PlusHalf,
    /// −3π/4 ~<= x < −π/4: `(−k_cosf(x + π/2), k_sinf(x + π/2))`.
    MinusHalf,
    /// 3π/4 < |x| ~<= 5π/4: `(−k_sinf(x ∓ π), −k_cosf(x ∓ π))`.
    Whole,
}

/// |x| beyond 5π/4 on the host: `libm`'s own, the same bits.
#[cfg(not(target_arch = "arm"))]
#[cold]
fn far(x: f32) -> (f32, f32) {
    libm::sincosf(x)
}

/// |x| beyond 5π/4 on the car, which a validated heading never reaches: `x − 2πn` for the
/// nearest integer `n` (in `f64`, `libm`'s rounding trick of `rem_pio2f`), then the branches
/// above; NaN where that cannot bring it within 5π/4 (an infinity, a NaN, |x| ≳ 2⁵¹·2π).
#[cfg(target_arch = "arm")]
#[cold]
#[inline(never)]
fn far(x: f32) -> (f32, f32) {
    /// 1/(2π) and 1.5·2⁵²: adding and taking off the latter rounds to an integer.
    const INV_2PI: f64 = 0.159_154_943_091_895_35;
    const TOINT: f64 = 1.5 / f64::EPSILON;
    debug_assert!(false, "sincosf beyond 5π/4 on the car: {x}");
    let x64 = x as f64;
    let n = (x64 * INV_2PI + TOINT) - TOINT;
    let y = (x64 - n * (2.0 * S2PIO2)) as f32;
    let iy = y.to_bits() & 0x7fff_ffff;
    if iy <= NEAR_BITS {
        near(y, iy)
    } else {
        (f32::NAN, f32::NAN)
    }
}

/* |sin(x)/x - s(x)| < 2**-37.5 (~[-4.89e-12, 4.824e-12]). */
const S1: f64 = -0.166666666416265235595; /* -0x15555554cbac77.0p-55 */
const S2: f64 = 0.0083333293858894631756; /*  0x111110896efbb2.0p-59 */
const S3: f64 = -0.000198393348360966317347; /* -0x1a00f9e2cae774.0p-65 */
const S4: f64 = 0.0000027183114939898219064; /*  0x16cd878c3b46a7.0p-71 */

/// `libm`'s `k_sinf`: sin on [-π/4, π/4] in `f64`, rounded once to `f32`.
#[inline(never)]
fn k_sinf(x: f64) -> f32 {
    let z = x * x;
    let w = z * z;
    let r = S3 + z * S4;
    let s = z * x;
    ((x + s * (S1 + z * S2)) + s * w * r) as f32
}

/* |cos(x) - c(x)| < 2**-34.1 (~[-5.37e-11, 5.295e-11]). */
const C0: f64 = -0.499999997251031003120; /* -0x1ffffffd0c5e81.0p-54 */
const C1: f64 = 0.0416666233237390631894; /*  0x155553e1053a42.0p-57 */
const C2: f64 = -0.00138867637746099294692; /* -0x16c087e80f1e27.0p-62 */
const C3: f64 = 0.0000243904487962774090654; /*  0x199342e0ee5069.0p-68 */

/// `libm`'s `k_cosf`: cos on [-π/4, π/4] in `f64`, rounded once to `f32`.
#[inline(never)]
fn k_cosf(x: f64) -> f32 {
    let z = x * x;
    let w = z * z;
    let r = C2 + z * C3;
    (((1.0 + z * C0) + w * C1) + (w * z) * r) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f32::consts::PI;

    /// `sincosf(x)` and `libm::sincosf(x)` are the same bits.
    fn same(x: f32) -> bool {
        let (s, c) = sincosf(x);
        let (ls, lc) = libm::sincosf(x);
        s.to_bits() == ls.to_bits() && c.to_bits() == lc.to_bits()
    }

    /// The copied branches' bits of |x|, every `step`th, both signs: the first mismatch, if any.
    fn first_mismatch(step: usize) -> Option<f32> {
        (0..=NEAR_BITS)
            .step_by(step)
            .chain([NEAR_BITS, PI.to_bits()])
            .flat_map(|b| [f32::from_bits(b), -f32::from_bits(b)])
            .find(|&x| !same(x))
    }

    /// A dense sample of the range (every 1021st `f32`, both signs) and its edges.
    #[test]
    fn sincosf_is_libms_on_a_sample() {
        assert_eq!(first_mismatch(1021), None);
        for x in [
            0.0,
            -0.0,
            f32::from_bits(1),
            -f32::from_bits(1),
            f32::MIN_POSITIVE,
            f32::from_bits(0x397f_ffff),
            f32::from_bits(0x3980_0000),
            f32::from_bits(0x3f49_0fda),
            f32::from_bits(0x3f49_0fdb),
            f32::from_bits(0x4016_cbe3),
            f32::from_bits(0x4016_cbe4),
            PI,
            -PI,
            f32::from_bits(NEAR_BITS),
            -f32::from_bits(NEAR_BITS),
        ] {
            assert!(same(x), "{x:e}");
        }
        // The validated headings end at `f32::consts::PI` (`within(heading, PI)`): inside.
        assert!(PI.to_bits() <= NEAR_BITS);
        assert_eq!(sincosf(-0.0).0.to_bits(), (-0.0f32).to_bits());
    }

    /// Beyond the copied branches the host takes `libm`'s own.
    #[test]
    fn sincosf_beyond_is_libms_on_the_host() {
        for x in [
            f32::from_bits(NEAR_BITS + 1),
            5.0,
            -7.0,
            1.0e6,
            -3.0e38,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ] {
            assert!(same(x), "{x:e}");
        }
        assert!(sincosf(f32::NAN).0.is_nan() && sincosf(f32::NAN).1.is_nan());
    }

    /// Every `f32` of the copied branches (|x| ≲ 5π/4, both signs, some 2.16e9 of them, every
    /// heading `Observation::check` admits among them), on every core: `cargo test -p
    /// firmware-core --release --lib -- --ignored sincosf_exhaustive`.
    #[test]
    #[ignore]
    fn sincosf_exhaustive() {
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get()) as u32;
        let chunk = NEAR_BITS / threads + 1;
        let mismatches: Vec<f32> = std::thread::scope(|scope| {
            let workers: Vec<_> = (0..threads)
                .map(|t| {
                    scope.spawn(move || {
                        let end = NEAR_BITS.min((t + 1) * chunk - 1);
                        (t * chunk..=end)
                            .flat_map(|b| [f32::from_bits(b), -f32::from_bits(b)])
                            .filter(|&x| !same(x))
                            .collect::<Vec<_>>()
                    })
                })
                .collect();
            workers
                .into_iter()
                .flat_map(|w| w.join().unwrap())
                .collect()
        });
        assert!(mismatches.is_empty(), "{mismatches:?}");
    }
}
