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
//! The car's FPU (a Cortex-M4F's) has single precision only, and compiler_builtins' `__muldf3`
//! and `__adddf3` (some 87 and 109 instructions a call, for every operand: zeros, subnormals,
//! infinities, NaNs) were about 2.2 K instructions of the worst real tick. The car takes
//! `fixed`'s path instead: the kernels' argument exactly in 64-bit fixed point, their
//! polynomials to within 2⁻⁶⁰ (ten 64×64-bit products' top halves, four `umull` each), each
//! result rounded to `f32` where it lies farther from the middle between two `f32`s than
//! `libm`'s `f64` value can be from the exact polynomial (a few `f64` roundings, within about
//! 2⁻⁵⁰): there all three round alike. About 160 instructions a heading, against some 1 500
//! with `f64` operations. On 130 of the 234 million arguments that reach the kernels it cannot
//! tell, and the car computes `libm`'s own `f64` operations with `Soft`'s: an `f64`'s
//! bits in integer arithmetic (the significands' product from four 32×32→64-bit
//! multiplications, `umull` on the car) for the operands the kernels and reductions meet,
//! normal and with nonzero normal results, rounded to nearest, ties to even: the same bits as
//! the native operations, each operation checked against the native one on every 1021st
//! argument (the kernels are generic over `Double`; the test runs them with both at once) and
//! on random operands. `sincosf_exhaustive` checks the car's path (fixed point, `Soft` where it
//! cannot tell) and the host's (the native `f64`, the same bits, faster there) against
//! `libm::sincosf` on every argument of the range. The kernels share `z = x·x` and `w = z·z`
//! (the same values as each computes them), and the sums of the kernels, each of whose second
//! term is below a quarter of its first, normalise by two bits at most (`Double::add_small`).
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
/// what this function leaves out) one reduction by 2π in `f64` and the same branches, within
/// 2·10⁻⁷ of `sin` and `cos` up to |x| ≈ 10⁶ (the reduced argument is rounded to `f32`; ulps
/// near a zero of either), and NaN for an infinity, a NaN or |x| ≥ 2⁵³ (debug builds assert
/// that the car never gets there).
///
/// [`Observation::check`]: crate::observation::Observation::check
#[inline]
pub fn sincosf(x: f32) -> (f32, f32) {
    let ix = x.to_bits() & 0x7fff_ffff;
    if ix <= NEAR_BITS {
        #[cfg(target_arch = "arm")]
        return fixed_or_soft(x, ix);
        #[cfg(not(target_arch = "arm"))]
        near::<f64>(x, ix)
    } else {
        far(x)
    }
}

/// `libm::sincosf`'s branches for |x| ~<= 5π/4, `ix` the bits of |x|: the same kernels on the
/// same `f64` argument, their results put in place as `libm` does in each branch (each kernel
/// written once, so inlined once), the `f64` operations those of `D` ([`Double`]: the native
/// ones, or [`Soft`]'s, the same bits). `libm` also makes the tiny arguments raise the inexact
/// and underflow flags, which Rust cannot read.
#[inline]
fn near<D: Double>(x: f32, ix: u32) -> (f32, f32) {
    let sign = (x.to_bits() >> 31) != 0;

    /* |x| < 2**-12 */
    if ix < 0x3980_0000 {
        return (x, 1.0);
    }
    let x64 = D::from_f32(x);
    // The kernels' argument, and which branch of `libm`'s took it. Every reduction is exact
    // (Sterbenz: |x| lies within [c/2, 2c] of the multiple c of π/2 it is taken from) and
    // nonzero (no `f32` is π/2 or π rounded to `f64`).
    let (y, branch) = if ix <= 0x3f49_0fda {
        /* |x| ~<= pi/4 */
        (x64, Branch::Quarter)
    } else if ix <= 0x4016_cbe3 {
        /* |x| ~<= 3pi/4 */
        if sign {
            (x64.add(D::of(S1PIO2)), Branch::MinusHalf)
        } else {
            (D::of(S1PIO2).sub(x64), Branch::PlusHalf)
        }
    }
    /* |x| ~<= 5*pi/4 */
    /* -sin(x+c) is not correct if x+c could be 0: -0 vs +0 */
    else if sign {
        (x64.add(D::of(S2PIO2)), Branch::Whole)
    } else {
        (x64.sub(D::of(S2PIO2)), Branch::Whole)
    };
    let (s, c) = kernels(y);
    branch.place(s, c)
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

impl Branch {
    /// `(sin x, cos x)` from the kernels' `s = k_sinf(y)` and `c = k_cosf(y)`, as `libm` puts
    /// them in place in this branch.
    #[inline(always)]
    fn place(self, s: f32, c: f32) -> (f32, f32) {
        match self {
            Branch::Quarter => (s, c),
            Branch::PlusHalf => (c, s),
            Branch::MinusHalf => (-c, s),
            Branch::Whole => (-s, -c),
        }
    }
}

/// |x| beyond 5π/4 on the host: `libm`'s own, the same bits.
#[cfg(not(target_arch = "arm"))]
#[cold]
fn far(x: f32) -> (f32, f32) {
    libm::sincosf(x)
}

/// |x| beyond 5π/4 on the car, which a validated heading never reaches: [`reduce_far`] with
/// [`Soft`]'s operations.
#[cfg(target_arch = "arm")]
#[cold]
#[inline(never)]
fn far(x: f32) -> (f32, f32) {
    debug_assert!(false, "sincosf beyond 5π/4 on the car: {x}");
    reduce_far::<Soft>(x)
}

/// |x| beyond 5π/4 on the car: `x − 2πn` for the nearest integer `n` (in `f64`, `libm`'s
/// rounding trick of `rem_pio2f`), then the branches above; NaN where that cannot bring it
/// within 5π/4, and for an infinity, a NaN or |x| ≥ 2⁵³ (where `n` would no longer be an
/// integer). Every operation's result is a nonzero normal number, as [`Soft`]'s need: |x| >
/// 3.9 makes |n| ≥ 1, |x/(2π)| < 2⁵¹ keeps `x/(2π) + 1.5·2⁵²` from 0, and `x − 2πn` is either 0
/// (returned first) or a difference of `f64`s of magnitude ≥ 3.9, at least 2⁻⁵⁰.
#[cfg_attr(not(any(target_arch = "arm", test)), allow(dead_code))]
#[inline]
fn reduce_far<D: Double>(x: f32) -> (f32, f32) {
    /// 1/(2π) and 1.5·2⁵²: adding and taking off the latter rounds to an integer.
    const INV_2PI: f64 = 0.159_154_943_091_895_35;
    const TOINT: f64 = 1.5 / f64::EPSILON;
    let ix = x.to_bits() & 0x7fff_ffff;
    debug_assert!(ix > NEAR_BITS);
    // 2⁵³ (an infinity and a NaN beyond).
    if ix >= 0x5a00_0000 {
        return (f32::NAN, f32::NAN);
    }
    let x64 = D::from_f32(x);
    let n = x64.mul(D::of(INV_2PI)).add(D::of(TOINT)).sub(D::of(TOINT));
    let n2pi = n.mul(D::of(2.0 * S2PIO2));
    if n2pi.to_bits() == x64.to_bits() {
        return (0.0, 1.0);
    }
    let y = x64.sub(n2pi).to_f32();
    let iy = y.to_bits() & 0x7fff_ffff;
    if iy <= NEAR_BITS {
        near::<D>(y, iy)
    } else {
        (f32::NAN, f32::NAN)
    }
}

/* |sin(x)/x - s(x)| < 2**-37.5 (~[-4.89e-12, 4.824e-12]). */
const S1: f64 = -0.166666666416265235595; /* -0x15555554cbac77.0p-55 */
const S2: f64 = 0.0083333293858894631756; /*  0x111110896efbb2.0p-59 */
const S3: f64 = -0.000198393348360966317347; /* -0x1a00f9e2cae774.0p-65 */
const S4: f64 = 0.0000027183114939898219064; /*  0x16cd878c3b46a7.0p-71 */

/// `libm`'s `k_sinf` and `k_cosf` of the same argument `x`, their `z = x * x` and `w = z * z`
/// computed once (the same values as each computes them).
#[inline(never)]
fn kernels<D: Double>(x: D) -> (f32, f32) {
    let z = x.mul(x);
    let w = z.mul(z);
    (k_sinf(x, z, w), k_cosf(z, w))
}

/// `libm`'s `k_sinf`: sin on [-π/4, π/4] in `f64`, rounded once to `f32`: `((x + s * (S1 + z *
/// S2)) + s * w * r) as f32` with `z = x * x`, `w = z * z`, `r = S3 + z * S4`, `s = z * x`.
/// Each sum's second term is below a quarter of its first ([`Double::add_small`]).
#[inline]
fn k_sinf<D: Double>(x: D, z: D, w: D) -> f32 {
    let r = D::of(S3).add_small(z.mul(D::of(S4)));
    let s = z.mul(x);
    (x.add_small(s.mul(D::of(S1).add_small(z.mul(D::of(S2))))))
        .add_small(s.mul(w).mul(r))
        .to_f32()
}

/* |cos(x) - c(x)| < 2**-34.1 (~[-5.37e-11, 5.295e-11]). */
const C0: f64 = -0.499999997251031003120; /* -0x1ffffffd0c5e81.0p-54 */
const C1: f64 = 0.0416666233237390631894; /*  0x155553e1053a42.0p-57 */
const C2: f64 = -0.00138867637746099294692; /* -0x16c087e80f1e27.0p-62 */
const C3: f64 = 0.0000243904487962774090654; /*  0x199342e0ee5069.0p-68 */

/// `libm`'s `k_cosf`: cos on [-π/4, π/4] in `f64`, rounded once to `f32`: `(((1.0 + z * C0) +
/// w * C1) + (w * z) * r) as f32` with `z = x * x`, `w = z * z`, `r = C2 + z * C3`. Each sum's
/// second term is below a quarter of its first ([`Double::add_small`]).
#[inline]
fn k_cosf<D: Double>(z: D, w: D) -> f32 {
    let r = D::of(C2).add_small(z.mul(D::of(C3)));
    (D::of(1.0).add_small(z.mul(D::of(C0))))
        .add_small(w.mul(D::of(C1)))
        .add_small(w.mul(z).mul(r))
        .to_f32()
}

/// The car's path for |x| ≲ 5π/4: [`fixed`], and where it cannot tell the rounding (130 of the
/// 234 million arguments that reach the kernels), [`near`] with [`Soft`]'s operations. The same bits as
/// `libm::sincosf` either way (`sincosf_exhaustive` runs this path on every argument).
#[cfg_attr(not(any(target_arch = "arm", test)), allow(dead_code))]
#[inline]
fn fixed_or_soft(x: f32, ix: u32) -> (f32, f32) {
    match fixed(x, ix) {
        Some(sc) => sc,
        None => near::<Soft>(x, ix),
    }
}

/// A value in fixed point: `c · 2^shift` rounded to the nearest integer (for the kernels'
/// coefficients, `shift` = 64: Q64; for π/2 and π, 61).
const fn fixed_point(c: f64, shift: i32) -> u64 {
    let bits = c.to_bits();
    let e = ((bits >> 52) & 0x7ff) as i32 - 1075 + shift;
    let m = (bits & FRACTION) | IMPLICIT;
    if e >= 0 {
        m << e
    } else {
        (m + (1 << (-e - 1))) >> -e
    }
}

/// π/2 and π (the `f64`s `libm` reduces by) in Q61: exact (their lowest bit is 2⁻⁵²).
const S1PIO2_Q61: u64 = fixed_point(S1PIO2, 61);
const S2PIO2_Q61: u64 = fixed_point(S2PIO2, 61);
/// The kernels' coefficients' magnitudes in Q64 (exact down to 2⁻⁶⁴; `S3`, `S4`, `C3`
/// rounded there, an error below 2⁻⁶⁴).
const S1_Q64: u64 = fixed_point(-S1, 64);
const S2_Q64: u64 = fixed_point(S2, 64);
const S3_Q64: u64 = fixed_point(-S3, 64);
const S4_Q64: u64 = fixed_point(S4, 64);
const C0_Q64: u64 = fixed_point(-C0, 64);
const C1_Q64: u64 = fixed_point(C1, 64);
const C2_Q64: u64 = fixed_point(-C2, 64);
const C3_Q64: u64 = fixed_point(C3, 64);

/// How far from the middle between two `f32`s (in units of the 64-bit significand's lowest
/// bit) [`fixed`]'s value must lie for its rounding to be `libm`'s: `libm`'s kernels are
/// within about 2⁻⁵⁰ of their polynomial's exact value (a few roundings of `f64` operations,
/// each within 2⁻⁵³ of its result, on terms below the result), [`fixed`] within 2⁻⁶⁰, so both
/// lie within 2¹⁴ units of the exact value (the significand below 2⁶⁴): a margin of eight times
/// that.
const MARGIN: u64 = 1 << 17;

/// The top 64 bits of the 128-bit product `a · b` (truncated, up to 3 below the exact top):
/// four 32×32→64-bit multiplications.
#[inline(always)]
fn mul_high(a: u64, b: u64) -> u64 {
    let (ah, al) = (a >> 32, a & 0xffff_ffff);
    let (bh, bl) = (b >> 32, b & 0xffff_ffff);
    let middle = ((al * bl) >> 32) + ((al * bh) & 0xffff_ffff) + ((ah * bl) & 0xffff_ffff);
    ah * bh + ((al * bh) >> 32) + ((ah * bl) >> 32) + (middle >> 32)
}

/// The `f32` nearest to `significand · 2^(exponent − 150)` (`significand` in [2⁶³, 2⁶⁴): 24 bits
/// kept, 40 rounded off, ties to even, a carry into the exponent included), or `None` when
/// the bits rounded off lie within [`MARGIN`] of the middle.
#[inline(always)]
fn rounded(significand: u64, exponent: u32) -> Option<u32> {
    let rest = significand & ((1 << 40) - 1);
    if rest.abs_diff(1 << 39) <= MARGIN {
        return None;
    }
    let up = u32::from(rest > 1 << 39);
    Some((exponent << 23) + (significand >> 40) as u32 + up)
}

/// `libm::sincosf`'s branches for 2⁻¹² ≤ |x| ≲ 5π/4 (`ix` the bits of |x|) in 64-bit fixed
/// point: the kernels' argument `y` exactly (as [`near`]'s, Q61, then Q64), their polynomials
/// in `y` to within 2⁻⁶⁰ (Horner's rule on the coefficients' magnitudes, their signs known:
/// `sin y = y·(1 − z·q)`, `cos y = 1 − z·c` with `z = y²`), each result rounded to `f32` where
/// it lies farther than [`MARGIN`] from the middle between two `f32`s: there the exact
/// polynomial, `libm`'s `f64` value of it and this one all round to the same `f32`. `None`
/// otherwise (130 of the 234 million arguments that reach the kernels: [`near`] then). Integer operations only.
#[cfg_attr(not(any(target_arch = "arm", test)), allow(dead_code))]
#[inline]
fn fixed(x: f32, ix: u32) -> Option<(f32, f32)> {
    let negative = (x.to_bits() >> 31) != 0;
    /* |x| < 2**-12 */
    if ix < 0x3980_0000 {
        return Some((x, 1.0));
    }
    // |x| in Q61, exactly: 24 bits at 2^(e − 23), e from −12 to 1.
    let e = (ix >> 23) as i32 - 127;
    let ax = u64::from((ix & 0x7f_ffff) | 0x80_0000) << (38 + e);
    // `y` as its magnitude and sign; `c − |x|` is `near`'s exact reduction, nonzero.
    let off = |c: u64| {
        let d = c as i64 - ax as i64;
        (d.unsigned_abs(), d < 0)
    };
    let (y, y_negative, branch) = if ix <= 0x3f49_0fda {
        (ax, negative, Branch::Quarter)
    } else if ix <= 0x4016_cbe3 {
        let (y, below) = off(S1PIO2_Q61);
        (
            y,
            below,
            if negative {
                Branch::MinusHalf
            } else {
                Branch::PlusHalf
            },
        )
    } else {
        // x + π = π − |x| for a negative x, x − π = −(π − |x|) for a positive one.
        let (y, below) = off(S2PIO2_Q61);
        (y, below == negative, Branch::Whole)
    };
    // |y| ≤ π/4 in Q64 (below 2⁶¹ in Q61), at least 2⁻²⁶; normalised for the sine.
    let y = y << 3;
    let k = y.leading_zeros();
    let ym = y << k;
    let z = mul_high(y, y);
    // sin |y| = |y|·(1 − z·q), q = |S1| − z·(S2 − z·(|S3| − z·S4)).
    let u = S3_Q64 - mul_high(z, S4_Q64);
    let v = S2_Q64 - mul_high(z, u);
    let q = S1_Q64 - mul_high(z, v);
    let sine = ym - mul_high(ym, mul_high(z, q));
    // At least 0.89·ym: its leading bit at 63 or 62.
    let l = sine.leading_zeros();
    let s = f32::from_bits(rounded(sine << l, 125 - k - l)?);
    // cos |y| = 1 − z·c, c = |C0| − z·(C1 − z·(|C2| − z·C3)); 1 − z·c in Q64 is 2⁶⁴ − z·c,
    // at least 0.69 (z·c is at least 2¹¹ there: nonzero).
    let a = C2_Q64 - mul_high(z, C3_Q64);
    let b = C1_Q64 - mul_high(z, a);
    let c = C0_Q64 - mul_high(z, b);
    let cosine = mul_high(z, c).wrapping_neg();
    let c = f32::from_bits(rounded(cosine, 125)?);
    let s = if y_negative { -s } else { s };
    Some(branch.place(s, c))
}

/// The `f64` operations of [`near`] and its kernels: IEEE 754 binary64 arithmetic, rounded to
/// nearest, ties to even, on the operands they meet (see [`Soft`]).
trait Double: Copy {
    /// An `f32`, exactly (`x as f64`).
    fn from_f32(x: f32) -> Self;
    /// A constant.
    fn of(c: f64) -> Self;
    /// `self + o`.
    fn add(self, o: Self) -> Self;
    /// `self + o` where `o`'s exponent is at least 2 below `self`'s (|o| < |self|/2, and
    /// below |self|/4 or so): [`Soft`]'s normalises the sum by 2 bits at most.
    fn add_small(self, o: Self) -> Self;
    /// `self - o`.
    fn sub(self, o: Self) -> Self;
    /// `self * o`.
    fn mul(self, o: Self) -> Self;
    /// Rounded to `f32` (`self as f32`).
    fn to_f32(self) -> f32;
    /// The bits (`f64::to_bits`).
    fn to_bits(self) -> u64;
}

impl Double for f64 {
    #[inline]
    fn from_f32(x: f32) -> Self {
        x as f64
    }
    #[inline]
    fn of(c: f64) -> Self {
        c
    }
    #[inline]
    fn add(self, o: Self) -> Self {
        self + o
    }
    #[inline]
    fn add_small(self, o: Self) -> Self {
        self + o
    }
    #[inline]
    fn sub(self, o: Self) -> Self {
        self - o
    }
    #[inline]
    fn mul(self, o: Self) -> Self {
        self * o
    }
    #[inline]
    fn to_f32(self) -> f32 {
        self as f32
    }
    #[inline]
    fn to_bits(self) -> u64 {
        f64::to_bits(self)
    }
}

/// An `f64` as its bits, with the operations [`near`] and its kernels meet, in integer
/// arithmetic: the car's FPU (a Cortex-M4F's) has single precision only, and compiler_builtins'
/// `__muldf3` and `__adddf3` (some 87 and 109 instructions a call) handle every operand, zeros,
/// subnormals, infinities and NaNs, and pack and unpack each result.
///
/// The same bits as the native operations (round to nearest, ties to even) for normal operands
/// whose exact result is a nonzero normal number (no overflow, no underflow; debug builds
/// assert it). That covers every operation of [`near`] and its kernels: their argument is a
/// normal `f32` with 2⁻¹² ≤ |x| ≤ 5π/4 (the tinier ones and zeros return first), its reduction
/// by π/2 or π is exact and nonzero (|y| ≥ 2⁻²⁶: no `f32` lies closer to them), so the kernels'
/// operands lie within 2⁻²⁶ ≤ |y| ≤ π/4 and their products and sums (of either sign, the
/// coefficients fixed) within about 2⁻²⁰⁰ and 2, and no sum cancels to zero (each sum's larger
/// term dominates it: `1 + z·C0` ≥ 0.69, the others within a factor of 2 of their first term). The tests check the car's
/// path against `libm::sincosf` on every argument (`sincosf_exhaustive`), and each operation
/// against the native one on every 1021st argument and on random operands.
#[derive(Clone, Copy)]
#[cfg_attr(not(any(target_arch = "arm", test)), allow(dead_code))]
struct Soft(u64);

/// The sign bit, the fraction's bits, the significand's implicit bit of an `f64`.
const SIGN: u64 = 1 << 63;
const FRACTION: u64 = (1 << 52) - 1;
const IMPLICIT: u64 = 1 << 52;

impl Double for Soft {
    #[inline]
    fn from_f32(x: f32) -> Self {
        let b = x.to_bits();
        debug_assert!(x.is_normal(), "{x:e}");
        // The exponent rebiased (127 to 1023), the fraction widened (23 to 52 bits).
        let magnitude = (u64::from(b & 0x7fff_ffff) + ((1023 - 127) << 23)) << 29;
        Soft(magnitude | (u64::from(b >> 31) << 63))
    }
    #[inline]
    fn of(c: f64) -> Self {
        Soft(c.to_bits())
    }
    #[inline]
    fn add(self, o: Self) -> Self {
        Soft(soft_add(self.0, o.0))
    }
    #[inline]
    fn add_small(self, o: Self) -> Self {
        Soft(soft_add_small(self.0, o.0))
    }
    #[inline]
    fn sub(self, o: Self) -> Self {
        Soft(soft_add(self.0, o.0 ^ SIGN))
    }
    #[inline]
    fn mul(self, o: Self) -> Self {
        Soft(soft_mul(self.0, o.0))
    }
    #[inline]
    fn to_f32(self) -> f32 {
        let m = self.0 & !SIGN;
        // Rounding the bits rounds the value (they order magnitudes, a carry into the exponent
        // included): 29 bits off, to nearest, ties to the even one.
        let r = (m + 0x0fff_ffff + ((m >> 29) & 1)) >> 29;
        let bits = (r as u32).wrapping_sub((1023 - 127) << 23);
        let y = f32::from_bits(bits | ((self.0 >> 32) as u32 & 0x8000_0000));
        debug_assert!(y.is_normal() && (r >> 23) > 1023 - 127, "{:#x}", self.0);
        y
    }
    #[inline]
    fn to_bits(self) -> u64 {
        self.0
    }
}

/// The biased exponent and the significand (the implicit bit set) of a normal `f64`'s bits.
#[inline]
fn unpack(a: u64) -> (i32, u64) {
    let e = ((a >> 52) & 0x7ff) as i32;
    debug_assert!(e != 0 && e != 0x7ff, "{a:#x}");
    (e, (a & FRACTION) | IMPLICIT)
}

/// The `f64` with sign bit `sign`, biased exponent `e` and the significand `x` (its leading bit
/// at bit 62, bits below the 53 kept jammed into its lowest bits: see [`shift_right_jam`]),
/// rounded to nearest, ties to even.
#[inline]
fn round_pack(sign: u64, e: i32, x: u64) -> u64 {
    debug_assert!(x >> 62 == 1);
    // Ten bits off: up if above half (0x200), or half and the kept bits odd.
    let significand = (x + 0x1ff + ((x >> 10) & 1)) >> 10;
    // The exponent less one plus the significand with its implicit bit: a carry of the rounding
    // into 2⁵³ raises the exponent by one, as it should.
    debug_assert!((1..0x7fe).contains(&e), "exponent {e}");
    sign | ((((e - 1) as u64) << 52) + significand)
}

/// `x >> n` with a 1 in the lowest bit if any bit shifted out was one ("jamming"): every bit
/// below the rounding position kept as whether it is zero, enough to round correctly (bits
/// below the guard bit only matter as nonzero or not, also after a subtraction, which moves
/// the result up by at most two bits where it shifted anything out).
#[inline]
fn shift_right_jam(x: u64, n: u32) -> u64 {
    if n == 0 {
        x
    } else if n < 64 {
        (x >> n) | u64::from(x << (64 - n) != 0)
    } else {
        u64::from(x != 0)
    }
}

/// `a + b` for normal `a` and `b` whose sum is a nonzero normal `f64` (see [`Soft`]).
#[cfg_attr(not(any(target_arch = "arm", test)), allow(dead_code))]
#[inline(never)]
fn soft_add(a: u64, b: u64) -> u64 {
    // `a` the larger in magnitude: its sign is the sum's.
    let (a, b) = if a & !SIGN >= b & !SIGN {
        (a, b)
    } else {
        (b, a)
    };
    let (ea, sum) = aligned_sum(a, b);
    debug_assert!(sum != 0, "{a:#x} + {b:#x}");
    // The sum's leading bit moved to bit 62: from bit 62 (a carry) the exponent is one up.
    let lz = sum.leading_zeros();
    round_pack(a & SIGN, ea + 2 - lz as i32, sum << (lz - 1))
}

/// The exponent of `a` and the sum of the significands of `a` and `b` (`a` the larger in
/// magnitude, both normal), `b`'s aligned to `a`'s with its shifted-out bits kept as a sticky
/// bit: `a`'s leading bit at bit 61, so that a carry fits, with 9 bits below the significand.
#[inline(always)]
fn aligned_sum(a: u64, b: u64) -> (i32, u64) {
    let (ea, ma) = unpack(a);
    let (eb, mb) = unpack(b);
    let ma = ma << 9;
    let mb = shift_right_jam(mb << 9, (ea - eb) as u32);
    let sum = if (a ^ b) & SIGN == 0 {
        ma + mb
    } else {
        ma - mb
    };
    (ea, sum)
}

/// `a + b` for normal `a` and `b`, `b`'s exponent at least 2 below `a`'s, whose sum is a
/// normal `f64` ([`Double::add_small`]): [`soft_add`] without its ordering and with its
/// normalisation by at most 2 bits (the sum's leading bit at bit 60, 61 or 62).
#[cfg_attr(not(any(target_arch = "arm", test)), allow(dead_code))]
#[inline(never)]
fn soft_add_small(a: u64, b: u64) -> u64 {
    debug_assert!(
        ((a >> 52) & 0x7ff) >= ((b >> 52) & 0x7ff) + 2,
        "{a:#x} + {b:#x}"
    );
    let (ea, sum) = aligned_sum(a, b);
    let (e, sum) = if sum >> 62 != 0 {
        (ea + 1, sum)
    } else if sum >> 61 != 0 {
        (ea, sum << 1)
    } else {
        (ea - 1, sum << 2)
    };
    round_pack(a & SIGN, e, sum)
}

/// `a * b` for normal `a` and `b` whose product is a normal `f64` (see [`Soft`]), the
/// significands' 106-bit product from four 32×32→64-bit multiplications (one `umull` each on
/// the car).
#[cfg_attr(not(any(target_arch = "arm", test)), allow(dead_code))]
#[inline(never)]
fn soft_mul(a: u64, b: u64) -> u64 {
    let (ea, ma) = unpack(a);
    let (eb, mb) = unpack(b);
    let (ah, al) = ((ma >> 32) as u32, ma as u32);
    let (bh, bl) = ((mb >> 32) as u32, mb as u32);
    let wide = |x: u32, y: u32| u64::from(x) * u64::from(y);
    // ah and bh below 2²¹: `middle` below 2⁵⁴, `high` below 2⁴².
    let middle = wide(ah, bl) + wide(al, bh);
    let (low, carry) = wide(al, bl).overflowing_add(middle << 32);
    let high = wide(ah, bh) + (middle >> 32) + u64::from(carry);
    // The product, in [2¹⁰⁴, 2¹⁰⁶), shifted right by 43 with its lower bits jammed: its
    // leading bit at bit 62 or 61, moved to 62.
    let p = (high << 21) | (low >> 43) | u64::from(low & ((1 << 43) - 1) != 0);
    let (e, p) = if p >> 62 != 0 {
        (ea + eb - 1022, p)
    } else {
        (ea + eb - 1023, p << 1)
    };
    round_pack((a ^ b) & SIGN, e, p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f32::consts::PI;

    /// The native `f64` operations and [`Soft`]'s side by side, each result compared bit for
    /// bit (a panic names the first that differs).
    #[derive(Clone, Copy)]
    struct Both(f64, Soft);

    impl Both {
        fn checked(self, what: &str, operands: [f64; 2]) -> Self {
            assert_eq!(
                self.0.to_bits(),
                self.1.0,
                "{what} of {:e} and {:e}: native {:e}, soft {:e}",
                operands[0],
                operands[1],
                self.0,
                f64::from_bits(self.1.0)
            );
            self
        }
    }

    impl Double for Both {
        fn from_f32(x: f32) -> Self {
            Both(f64::from_f32(x), Soft::from_f32(x)).checked("as f64", [x.into(), 0.0])
        }
        fn of(c: f64) -> Self {
            Both(c, Soft::of(c))
        }
        fn add(self, o: Self) -> Self {
            Both(self.0.add(o.0), self.1.add(o.1)).checked("+", [self.0, o.0])
        }
        fn add_small(self, o: Self) -> Self {
            let exponent = |x: f64| (x.to_bits() >> 52) & 0x7ff;
            assert!(
                exponent(o.0) + 2 <= exponent(self.0),
                "{:e} + {:e}",
                self.0,
                o.0
            );
            Both(self.0.add_small(o.0), self.1.add_small(o.1)).checked("+", [self.0, o.0])
        }
        fn sub(self, o: Self) -> Self {
            Both(self.0.sub(o.0), self.1.sub(o.1)).checked("-", [self.0, o.0])
        }
        fn mul(self, o: Self) -> Self {
            Both(self.0.mul(o.0), self.1.mul(o.1)).checked("*", [self.0, o.0])
        }
        fn to_f32(self) -> f32 {
            let (native, soft) = (self.0.to_f32(), self.1.to_f32());
            assert_eq!(native.to_bits(), soft.to_bits(), "as f32 of {:e}", self.0);
            native
        }
        fn to_bits(self) -> u64 {
            self.0.to_bits()
        }
    }

    /// `sincosf(x)` and `libm::sincosf(x)` are the same bits, and within the copied branches
    /// so is [`near`] with [`Soft`]'s operations (the car's path).
    fn same(x: f32) -> bool {
        let (ls, lc) = libm::sincosf(x);
        let is = |(s, c): (f32, f32)| s.to_bits() == ls.to_bits() && c.to_bits() == lc.to_bits();
        let ix = x.to_bits() & 0x7fff_ffff;
        is(sincosf(x)) && (ix > NEAR_BITS || is(fixed_or_soft(x, ix)))
    }

    /// [`same`], and within the copied branches each of [`Soft`]'s operations the native one's
    /// bits ([`Both`]: a panic names the first that differs).
    fn same_op_by_op(x: f32) -> bool {
        let (ls, lc) = libm::sincosf(x);
        let is = |(s, c): (f32, f32)| s.to_bits() == ls.to_bits() && c.to_bits() == lc.to_bits();
        let ix = x.to_bits() & 0x7fff_ffff;
        same(x) && (ix > NEAR_BITS || is(near::<Both>(x, ix)))
    }

    /// The copied branches' bits of |x|, every `step`th, both signs: the first mismatch, if any.
    fn first_mismatch(step: usize) -> Option<f32> {
        (0..=NEAR_BITS)
            .step_by(step)
            .chain([NEAR_BITS, PI.to_bits()])
            .flat_map(|b| [f32::from_bits(b), -f32::from_bits(b)])
            .find(|&x| !same_op_by_op(x))
    }

    /// A dense sample of the range (every 1021st `f32`, both signs) and its edges, the host's
    /// path and the car's ([`same`]).
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
            assert!(same_op_by_op(x), "{x:e}");
        }
        // The validated headings end at `f32::consts::PI` (`within(heading, PI)`): inside.
        assert!(PI.to_bits() <= NEAR_BITS);
        assert_eq!(sincosf(-0.0).0.to_bits(), (-0.0f32).to_bits());
    }

    /// The car's fixed-point path decides the rounding itself on all but a few arguments of a
    /// dense sample (every 1021st `f32` of the copied branches, both signs), and where it does,
    /// its bits are `libm`'s (every argument: `sincosf_exhaustive`).
    #[test]
    fn fixed_point_rarely_falls_back() {
        let (mut decided, mut undecided) = (0u32, 0u32);
        for b in (0x3980_0000..=NEAR_BITS).step_by(1021) {
            for x in [f32::from_bits(b), -f32::from_bits(b)] {
                match fixed(x, b) {
                    Some((s, c)) => {
                        let (ls, lc) = libm::sincosf(x);
                        assert_eq!(
                            (s.to_bits(), c.to_bits()),
                            (ls.to_bits(), lc.to_bits()),
                            "{x:e}"
                        );
                        decided += 1;
                    }
                    None => undecided += 1,
                }
            }
        }
        assert!(decided > 200_000 && undecided <= 4, "{decided} {undecided}");
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

    /// [`Soft`]'s operations against the native ones beyond the kernels' operands: random
    /// normal operands of either sign within 2^±60, their significands often short (exact
    /// results and ties to even), shifted far apart and close together.
    #[test]
    fn soft_ops_are_native_on_random_operands() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
        let mut operand = || {
            let sign = u64::from(rng.random_range(0..2u32));
            let exponent = rng.random_range(1023 - 60..=1023 + 60u64);
            let zeros = rng.random_range(0..=52u32);
            let fraction = ((rng.random_range(0..=u64::MAX) & FRACTION) >> zeros) << zeros;
            f64::from_bits((sign << 63) | (exponent << 52) | fraction)
        };
        let exponent = |x: f64| (x.to_bits() >> 52) & 0x7ff;
        for _ in 0..300_000 {
            let (a, b) = (operand(), operand());
            assert_eq!(
                soft_mul(a.to_bits(), b.to_bits()),
                (a * b).to_bits(),
                "{a:e} * {b:e}"
            );
            if a + b != 0.0 {
                assert_eq!(
                    soft_add(a.to_bits(), b.to_bits()),
                    (a + b).to_bits(),
                    "{a:e} + {b:e}"
                );
            }
            if exponent(b) + 2 <= exponent(a) {
                let sum = soft_add_small(a.to_bits(), b.to_bits());
                assert_eq!(sum, (a + b).to_bits(), "{a:e} + {b:e}");
            }
            assert_eq!(
                Soft(a.to_bits()).to_f32().to_bits(),
                (a as f32).to_bits(),
                "{a:e}"
            );
            let x = a as f32;
            assert_eq!(Soft::from_f32(x).0, f64::from(x).to_bits(), "{x:e}");
        }
    }

    /// The car's reduction beyond 5π/4 with [`Soft`]'s operations: each the native one's bits
    /// (a sample up to 2⁵³, both signs), within 2·10⁻⁷ of `libm::sincosf` up to 10⁶ (1.2·10⁻⁷
    /// on this sample: `x − 2πn` rounded to `f32`), NaN from 2⁵³ on.
    #[test]
    fn reduce_far_soft_is_native() {
        let mut worst = 0.0f32;
        for b in (NEAR_BITS + 1..0x5a00_0000)
            .step_by(4099)
            .chain([NEAR_BITS + 1, 0x59ff_ffff])
        {
            for x in [f32::from_bits(b), -f32::from_bits(b)] {
                let (s, c) = reduce_far::<Both>(x);
                if x.abs() <= 1.0e6 {
                    let (ls, lc) = libm::sincosf(x);
                    worst = worst.max((s - ls).abs()).max((c - lc).abs());
                }
            }
        }
        assert!(worst <= 2.0e-7, "{worst:e}");
        for x in [
            f32::from_bits(0x5a00_0000),
            -3.0e38,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ] {
            let (s, c) = reduce_far::<Both>(x);
            assert!(s.is_nan() && c.is_nan(), "{x:e}");
        }
    }

    /// Every `f32` of the copied branches (|x| ≲ 5π/4, both signs, some 2.16e9 of them, every
    /// heading `Observation::check` admits among them), on every core, the host's path and the
    /// car's against `libm::sincosf` ([`same`]; each of [`Soft`]'s operations against the native
    /// one on the sample above, [`same_op_by_op`]): `cargo test -p firmware-core --release --lib
    /// -- --ignored sincosf_exhaustive`.
    #[test]
    #[ignore]
    fn sincosf_exhaustive() {
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get()) as u32;
        let mismatches: Vec<f32> = std::thread::scope(|scope| {
            let workers: Vec<_> = (0..threads)
                .map(|t| {
                    scope.spawn(move || {
                        // Interleaved rather than in blocks: the arguments below 2⁻¹² (nearly
                        // half of the bits) return at once, the others run the kernels.
                        (t..=NEAR_BITS)
                            .step_by(threads as usize)
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
