//! The scalar types that points and attributes come in (`f32`, `f64`) and the arithmetic on
//! values of `N` channels that every pass uses. Ground floor: imports nothing of the crate.

use std::fmt::Debug;
use std::ops::{Add, Mul, Sub};

/// Floating-point types that points and attributes can be given in: `f32` and `f64`.
pub trait Scalar:
    Copy
    + Send
    + Sync
    + Default
    + PartialOrd
    + Debug
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + 'static
{
    /// Unit roundoff: half the machine epsilon, the largest relative error of one rounding to
    /// nearest (bounds of rounding errors are stated in it).
    const UNIT_ROUNDOFF: f64;
    /// Converts from f64 (weights are computed in f64).
    fn from_f64(x: f64) -> Self;
    /// Converts to f64.
    fn to_f64(self) -> f64;
    /// True unless NaN or infinite.
    fn is_finite(self) -> bool;
}

impl Scalar for f32 {
    const UNIT_ROUNDOFF: f64 = f32::EPSILON as f64 / 2.0;
    #[inline]
    fn from_f64(x: f64) -> Self {
        x as f32
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self as f64
    }
    #[inline]
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }
}

impl Scalar for f64 {
    const UNIT_ROUNDOFF: f64 = f64::EPSILON / 2.0;
    #[inline]
    fn from_f64(x: f64) -> Self {
        x
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self
    }
    #[inline]
    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }
}

/// A value carried by the scheme: `N` channels of one scalar type.
pub(crate) type Value<T, const N: usize> = [T; N];

/// The zero value.
#[inline(always)]
pub(crate) fn zero<T: Scalar, const N: usize>() -> Value<T, N> {
    [T::default(); N]
}

/// `a + b`, channel by channel.
#[inline(always)]
pub(crate) fn add<T: Scalar, const N: usize>(a: [T; N], b: [T; N]) -> [T; N] {
    std::array::from_fn(|k| a[k] + b[k])
}

/// `a - b`, channel by channel.
#[inline(always)]
pub(crate) fn sub<T: Scalar, const N: usize>(a: [T; N], b: [T; N]) -> [T; N] {
    std::array::from_fn(|k| a[k] - b[k])
}

/// `s * a`, channel by channel.
#[inline(always)]
pub(crate) fn scale<T: Scalar, const N: usize>(a: [T; N], s: T) -> [T; N] {
    std::array::from_fn(|k| a[k] * s)
}

/// `acc + w * x`, channel by channel.
#[inline(always)]
pub(crate) fn mad<T: Scalar, const N: usize>(acc: [T; N], w: T, x: [T; N]) -> [T; N] {
    std::array::from_fn(|k| acc[k] + w * x[k])
}

/// `p * a + (1 - p) * b`.
#[inline(always)]
pub(crate) fn lerp<T: Scalar, const N: usize>(a: [T; N], b: [T; N], p: f64) -> [T; N] {
    add(scale(a, T::from_f64(p)), scale(b, T::from_f64(1.0 - p)))
}

/// `1/k` as every centroid of `k` values computes it (a sum and one multiply); the adaptive
/// evaluation relies on the same bits.
#[inline(always)]
pub(crate) fn reciprocal<T: Scalar>(k: usize) -> T {
    match k {
        2 => T::from_f64(0.5),
        4 => T::from_f64(0.25),
        _ => T::from_f64(1.0 / k as f64),
    }
}

/// A value's channels written from a four-lane register (x86_64): exactly the value's `N`
/// channels, by plain stores. A masked store (`vmaskmovps` / `vmaskmovpd` to memory) writes
/// the same bytes, but on this project's machines (AMD Zen 3) it took about four times as
/// long: 4.0-5.3 ns against 1.1-1.6 ns per scattered three-channel `f32` store, in a loop of
/// 20 x 2^20 stores (a tile's corners' spread), measured 2026-12-08.
#[cfg(target_arch = "x86_64")]
pub(crate) mod lanes {
    use std::arch::x86_64::*;

    /// Writes lanes `0..N` of `v` (`N` at most 4) at `at`.
    ///
    /// # Safety
    /// `at` must point to `N` writable `f32`s; SSE4.1 must be enabled (the callers run in
    /// AVX2 code).
    #[inline(always)]
    pub(crate) unsafe fn store_f32<const N: usize>(at: *mut f32, v: __m128) {
        // SAFETY: `N` writable values at `at` (the caller's promise), each store within them.
        unsafe {
            match N {
                0 => {}
                1 => _mm_store_ss(at, v),
                2 => _mm_storel_epi64(at.cast(), _mm_castps_si128(v)),
                3 => {
                    _mm_storel_epi64(at.cast(), _mm_castps_si128(v));
                    at.add(2)
                        .cast::<i32>()
                        .write_unaligned(_mm_extract_ps::<2>(v));
                }
                _ => _mm_storeu_ps(at, v),
            }
        }
    }

    /// Writes lanes `0..N` of `v` (`N` at most 4) at `at`.
    ///
    /// # Safety
    /// `at` must point to `N` writable `f64`s; AVX must be enabled.
    #[inline(always)]
    pub(crate) unsafe fn store_f64<const N: usize>(at: *mut f64, v: __m256d) {
        // SAFETY: `N` writable values at `at` (the caller's promise), each store within them.
        unsafe {
            let low = _mm256_castpd256_pd128(v);
            match N {
                0 => {}
                1 => _mm_store_sd(at, low),
                2 => _mm_storeu_pd(at, low),
                3 => {
                    _mm_storeu_pd(at, low);
                    _mm_store_sd(at.add(2), _mm256_extractf128_pd::<1>(v));
                }
                _ => _mm256_storeu_pd(at, v),
            }
        }
    }

    #[cfg(test)]
    mod tests {
        use super::*;

        /// Lanes `0..N` of `1, 2, 3, 4` stored between guards: exactly those, nothing else.
        #[target_feature(enable = "avx2")]
        fn stored<const N: usize>() -> ([f32; 6], [f64; 6]) {
            let (mut single, mut double) = ([-1.0f32; 6], [-1.0f64; 6]);
            // SAFETY: AVX2 is enabled; items 1..5 are writable, `N` at most 4.
            unsafe {
                store_f32::<N>(single[1..].as_mut_ptr(), _mm_setr_ps(1.0, 2.0, 3.0, 4.0));
                store_f64::<N>(double[1..].as_mut_ptr(), _mm256_setr_pd(1.0, 2.0, 3.0, 4.0));
            }
            (single, double)
        }

        fn expected<const N: usize>() -> [f64; 6] {
            std::array::from_fn(|i| match i {
                1..=4 if i <= N => i as f64,
                _ => -1.0,
            })
        }

        #[test]
        fn stores_write_exactly_their_channels() {
            if !std::arch::is_x86_feature_detected!("avx2") {
                eprintln!("no AVX2 here: the stores are not run");
                return;
            }
            // SAFETY: the processor has AVX2 (checked above).
            let all = unsafe {
                [
                    (stored::<0>(), expected::<0>()),
                    (stored::<1>(), expected::<1>()),
                    (stored::<2>(), expected::<2>()),
                    (stored::<3>(), expected::<3>()),
                    (stored::<4>(), expected::<4>()),
                ]
            };
            for (n, ((single, double), expected)) in all.into_iter().enumerate() {
                assert_eq!(single.map(f64::from), expected, "f32, {n} channels");
                assert_eq!(double, expected, "f64, {n} channels");
            }
        }
    }
}
