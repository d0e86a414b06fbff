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
