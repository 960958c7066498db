//! Short-latency exponentials for the Stribeck curve `E = exp(-p)`, `p >= 0`.
//!
//! `exp_neg_table`: the single-run path. 64-entry table of `2^(j/64)` and a degree-5 tail
//! polynomial on `|r| <= ln2/128` (the scheme of ARM's optimized-routines exp, inlined, no special
//! cases: the caller guarantees `0 <= p <= 700`). Latency about 8 dependent FP operations.
//!
//! `exp_neg_poly`: the lanes path. No table (a table needs gathers across lanes): reduction by
//! `ln2` and a degree-13 polynomial, all lane-wise operations the compiler vectorises.
//!
//! Both are generic over `F` = "use fused multiply-add" so the same source compiles for the
//! baseline x86-64 target (`F = false`, two roundings) and inside `#[target_feature(enable =
//! "fma")]` functions (`F = true`, `vfmadd`).

#[inline(always)]
pub fn fma<const F: bool>(a: f64, b: f64, c: f64) -> f64 {
    if F {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

const N_BITS: u32 = 6;
const N: usize = 1 << N_BITS;
/// 1.5 * 2^52: adding it rounds to an integer held in the low mantissa bits.
const SHIFT: f64 = 6755399441055744.0;
const INV_LN2_N: f64 = N as f64 / std::f64::consts::LN_2;
// With FMA: ln 2 to double precision and its tiny remainder (fma rounds kd * hi - x once).
// Without: fdlibm's split (hi has trailing zero bits, so kd * hi is exact). Both divided by N (exact).
const LN2_N: f64 = std::f64::consts::LN_2 / N as f64;
const LN2_REM_N: f64 = 2.319046813846299558e-17 / N as f64;
const LN2_HI_N: f64 = 6.93147180369123816490e-01 / N as f64;
const LN2_LO_N: f64 = 1.90821492927058770002e-10 / N as f64;

/// Table entries `bits(2^(j/N)) - (j << (52 - N_BITS))`, so that adding `ki << (52 - N_BITS)`
/// (wrapping) yields the bits of `2^(n/N)` for the integer `n` in `ki`.
#[derive(Debug, Clone)]
pub struct ExpTable {
    bits: [u64; N],
}

impl Default for ExpTable {
    fn default() -> Self {
        Self::new()
    }
}

impl ExpTable {
    pub fn new() -> Self {
        let mut bits = [0u64; N];
        for (j, b) in bits.iter_mut().enumerate() {
            // libm's exp2 (within 1 ulp): the whole exp_neg stays within 2 ulp of libm's exp
            // (measured by the benchmark binary over [0, 700]).
            let v = (j as f64 / N as f64).exp2();
            *b = v.to_bits().wrapping_sub((j as u64) << (52 - N_BITS));
        }
        Self { bits }
    }

    /// `exp(-p)` for `0 <= p <= 700`.
    #[inline(always)]
    pub fn exp_neg<const F: bool>(&self, p: f64) -> f64 {
        self.exp_neg_kd::<F>(fma::<F>(-p, INV_LN2_N, SHIFT), -p)
    }

    /// The rounding constant `kd` for `exp(-p)` with `p = a * q`: lets a caller fold the factor
    /// `q` into the first multiply-add of the exponential (one operation less on its chain).
    #[inline(always)]
    pub fn kd_for<const F: bool>(a: f64, q: f64) -> f64 {
        fma::<F>(a, -q * INV_LN2_N, SHIFT)
    }

    /// `exp(x)` for `-700 <= x <= 0` from `kd = x N/ln2 + SHIFT` (rounded).
    #[inline(always)]
    pub fn exp_neg_kd<const F: bool>(&self, kd: f64, x: f64) -> f64 {
        let ki = kd.to_bits();
        let kd = kd - SHIFT;
        // r = x - kd ln2/N. With FMA the remainder term is below 1e-14 |r| and joins the
        // polynomial's linear term: no extra step on the chain.
        let (r, lo) = if F {
            (fma::<F>(kd, -LN2_N, x), kd * -LN2_REM_N)
        } else {
            ((x - kd * LN2_HI_N) - kd * LN2_LO_N, 0.0)
        };
        let idx = (ki as usize) & (N - 1);
        let top = ki << (52 - N_BITS);
        let scale = f64::from_bits(self.bits[idx].wrapping_add(top));
        let r2 = r * r;
        // exp(r) - 1 = r + r^2/2 + r^3/6 + r^4/24 + r^5/120 (truncation < 4e-17 for |r| <= ln2/128)
        let a = fma::<F>(r, 1.0 / 6.0, 0.5);
        let b = fma::<F>(r, 1.0 / 120.0, 1.0 / 24.0);
        let tail = fma::<F>(r2, fma::<F>(r2, b, a), r + lo);
        fma::<F>(scale, tail, scale)
    }
}

/// `exp(-p)` for `0 <= p <= 700` without a table (vectorises across lanes).
#[inline(always)]
pub fn exp_neg_poly<const F: bool>(p: f64) -> f64 {
    let x = -p;
    let kd = fma::<F>(x, std::f64::consts::LOG2_E, SHIFT);
    let ki = kd.to_bits();
    let kd = kd - SHIFT;
    let r = fma::<F>(kd, -6.93147180369123816490e-01, x);
    let r = fma::<F>(kd, -1.90821492927058770002e-10, r);
    // |r| <= ln2/2: Taylor to degree 13 (truncation 2e-17 relative)
    let r2 = r * r;
    let r4 = r2 * r2;
    let r8 = r4 * r4;
    const C: [f64; 14] = [
        1.0,
        1.0,
        0.5,
        1.0 / 6.0,
        1.0 / 24.0,
        1.0 / 120.0,
        1.0 / 720.0,
        1.0 / 5040.0,
        1.0 / 40320.0,
        1.0 / 362880.0,
        1.0 / 3628800.0,
        1.0 / 39916800.0,
        1.0 / 479001600.0,
        1.0 / 6227020800.0,
    ];
    let p01 = fma::<F>(C[1], r, C[0]);
    let p23 = fma::<F>(C[3], r, C[2]);
    let p45 = fma::<F>(C[5], r, C[4]);
    let p67 = fma::<F>(C[7], r, C[6]);
    let p89 = fma::<F>(C[9], r, C[8]);
    let p1011 = fma::<F>(C[11], r, C[10]);
    let p1213 = fma::<F>(C[13], r, C[12]);
    let q0 = fma::<F>(p23, r2, p01);
    let q1 = fma::<F>(p67, r2, p45);
    let q2 = fma::<F>(p1011, r2, p89);
    let q3 = p1213;
    let s0 = fma::<F>(q1, r4, q0);
    let s1 = fma::<F>(q3, r4, q2);
    let poly = fma::<F>(s1, r8, s0);
    // 2^n by building the exponent bits (n >= -1022 since p <= 700)
    let n = (ki as i64).wrapping_sub(SHIFT.to_bits() as i64);
    let scale = f64::from_bits(((n + 1023) as u64) << 52);
    poly * scale
}
