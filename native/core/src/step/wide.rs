//! The dual -> primal average of a quad level ([`super::LevelData::gather_primal`]) in vectors:
//! a value of up to four channels in one register (`f32` in SSE, `f64` in AVX), read and
//! written by masked loads and stores of exactly its channels. Each sum is the portable loop's,
//! in the same order, lane by lane, so the values are bitwise the same.
//!
//! Why by hand: LLVM builds a three-channel value from a two-lane load and a scalar one, so a
//! point costs two of each operation, and it keeps a bounds check per read. The portable loop
//! took 57 instructions an edge point and was 73 % of a cached averaging-3 evaluation at level 3
//! (17.1M of 23.4M instructions under callgrind, one thread), 35 % of averaging 9 (17.1M of
//! 48.9M): every odd degree ends each step with this average over every fine vertex.

use std::mem::MaybeUninit;

use super::Tables;
use crate::scalar::{Scalar, Value};

/// The three sections of a quad level's fine vertices: old vertices, edge points, face points.
pub(super) struct PrimalSections<'o, T, const N: usize> {
    /// One per coarse vertex: the mean of its fine faces.
    pub(super) olds: &'o mut [MaybeUninit<Value<T, N>>],
    /// One per coarse edge: the mean of the four (two on a boundary) fine faces at its midpoint.
    pub(super) edges: &'o mut [MaybeUninit<Value<T, N>>],
    /// One per coarse face: the mean of its four fine faces.
    pub(super) faces: &'o mut [MaybeUninit<Value<T, N>>],
}

/// Fills every item of `out` from the fine faces' data `f` of the quad level `t` (face `c` of
/// the fine level is corner `c` of the coarse one) when the processor has AVX2 and the values
/// are one to four channels of `f32` or `f64`; returns false, having written nothing, otherwise.
pub(super) fn gather_primal<T: Scalar, const N: usize>(
    t: &Tables,
    f: &[Value<T, N>],
    out: PrimalSections<T, N>,
) -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        use std::any::TypeId;
        if !(1..=4).contains(&N) || !std::arch::is_x86_feature_detected!("avx2") {
            return false;
        }
        if TypeId::of::<T>() == TypeId::of::<f32>() {
            // SAFETY: `T` is `f32`: the same types.
            unsafe { avx2::gather::<f32, N>(t, cast(f), cast_out(out)) };
            return true;
        }
        if TypeId::of::<T>() == TypeId::of::<f64>() {
            // SAFETY: `T` is `f64`: the same types.
            unsafe { avx2::gather::<f64, N>(t, cast(f), cast_out(out)) };
            return true;
        }
    }
    let _ = (t, f, out);
    false
}

/// `x` as a slice of `[U; N]`.
///
/// # Safety
/// `U` must be `T`.
#[cfg(target_arch = "x86_64")]
unsafe fn cast<T, U, const N: usize>(x: &[[T; N]]) -> &[[U; N]] {
    // SAFETY: the same type (the caller's promise).
    unsafe { std::slice::from_raw_parts(x.as_ptr().cast(), x.len()) }
}

/// `out` with its values of `U`.
///
/// # Safety
/// `U` must be `T`.
#[cfg(target_arch = "x86_64")]
unsafe fn cast_out<'o, T, U, const N: usize>(
    out: PrimalSections<'o, T, N>,
) -> PrimalSections<'o, U, N> {
    // SAFETY: the same type (the caller's promise).
    let cast = |x: &'o mut [MaybeUninit<[T; N]>]| unsafe {
        std::slice::from_raw_parts_mut(x.as_mut_ptr().cast(), x.len())
    };
    PrimalSections {
        olds: cast(out.olds),
        edges: cast(out.edges),
        faces: cast(out.faces),
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;
    use std::mem::MaybeUninit;

    use rayon::prelude::*;

    use super::PrimalSections;
    use crate::parallel::CHUNK;
    use crate::scalar::{reciprocal, Scalar};
    use crate::step::Tables;
    use crate::topology::NONE;

    /// A scalar type whose values of up to four channels fit one vector register.
    pub(super) trait Lanes: Scalar {
        /// The register.
        type V: Copy;
        /// Channels `0..N` of the value at `at`, zero in the other lanes.
        ///
        /// # Safety
        /// AVX must be enabled, and `at` must point to `N` readable values.
        unsafe fn load<const N: usize>(at: *const [Self; N]) -> Self::V;
        /// Writes lanes `0..N` of `v` to `at`, and nothing past them.
        ///
        /// # Safety
        /// AVX must be enabled, and `at` must point to `N` writable values.
        unsafe fn store<const N: usize>(at: *mut [Self; N], v: Self::V);
        /// `a + b`, lane by lane.
        ///
        /// # Safety
        /// AVX must be enabled.
        unsafe fn plus(a: Self::V, b: Self::V) -> Self::V;
        /// `a * s`, lane by lane.
        ///
        /// # Safety
        /// AVX must be enabled.
        unsafe fn scale(a: Self::V, s: Self) -> Self::V;
        /// Zero in every lane.
        ///
        /// # Safety
        /// AVX must be enabled.
        unsafe fn zero() -> Self::V;
    }

    /// The mask of lanes `0..N` of four 32-bit lanes.
    #[inline(always)]
    fn mask32<const N: usize>() -> __m128i {
        let on = |l: usize| if l < N { -1 } else { 0 };
        // SAFETY: SSE2 is part of x86_64.
        unsafe { _mm_setr_epi32(on(0), on(1), on(2), on(3)) }
    }

    /// The mask of lanes `0..N` of four 64-bit lanes.
    #[inline(always)]
    fn mask64<const N: usize>() -> __m256i {
        let on = |l: usize| if l < N { -1 } else { 0 };
        // SAFETY: `_mm256_setr_epi64x` only builds a value (inlined into AVX2 code).
        unsafe { _mm256_setr_epi64x(on(0), on(1), on(2), on(3)) }
    }

    impl Lanes for f32 {
        type V = __m128;
        #[inline(always)]
        unsafe fn load<const N: usize>(at: *const [f32; N]) -> __m128 {
            // SAFETY: the caller's promise; the mask reads lanes `0..N` alone.
            unsafe { _mm_maskload_ps(at.cast(), mask32::<N>()) }
        }
        #[inline(always)]
        unsafe fn store<const N: usize>(at: *mut [f32; N], v: __m128) {
            // SAFETY: the caller's promise; the mask writes lanes `0..N` alone.
            unsafe { _mm_maskstore_ps(at.cast(), mask32::<N>(), v) }
        }
        #[inline(always)]
        unsafe fn plus(a: __m128, b: __m128) -> __m128 {
            _mm_add_ps(a, b)
        }
        #[inline(always)]
        unsafe fn scale(a: __m128, s: f32) -> __m128 {
            _mm_mul_ps(a, _mm_set1_ps(s))
        }
        #[inline(always)]
        unsafe fn zero() -> __m128 {
            _mm_setzero_ps()
        }
    }

    impl Lanes for f64 {
        type V = __m256d;
        #[inline(always)]
        unsafe fn load<const N: usize>(at: *const [f64; N]) -> __m256d {
            // SAFETY: the caller's promise; the mask reads lanes `0..N` alone.
            unsafe { _mm256_maskload_pd(at.cast(), mask64::<N>()) }
        }
        #[inline(always)]
        unsafe fn store<const N: usize>(at: *mut [f64; N], v: __m256d) {
            // SAFETY: the caller's promise; the mask writes lanes `0..N` alone.
            unsafe { _mm256_maskstore_pd(at.cast(), mask64::<N>(), v) }
        }
        #[inline(always)]
        unsafe fn plus(a: __m256d, b: __m256d) -> __m256d {
            // SAFETY: AVX is enabled (the caller's promise).
            unsafe { _mm256_add_pd(a, b) }
        }
        #[inline(always)]
        unsafe fn scale(a: __m256d, s: f64) -> __m256d {
            // SAFETY: as `plus`.
            unsafe { _mm256_mul_pd(a, _mm256_set1_pd(s)) }
        }
        #[inline(always)]
        unsafe fn zero() -> __m256d {
            // SAFETY: as `plus`.
            unsafe { _mm256_setzero_pd() }
        }
    }

    /// [`super::gather_primal`] with vectors of `W`, each section in parallel chunks.
    ///
    /// # Safety
    /// The processor must have AVX2.
    pub(super) unsafe fn gather<W: Lanes, const N: usize>(
        t: &Tables,
        f: &[[W; N]],
        out: PrimalSections<W, N>,
    ) {
        let (quads, _) = f.as_chunks::<4>();
        // Every item of each section is written (a shorter table would leave some unwritten).
        assert_eq!(
            out.edges.len(),
            t.edge_corners.len(),
            "one edge point per edge"
        );
        let quads_of_faces = &quads[..out.faces.len()];
        out.olds
            .par_chunks_mut(CHUNK)
            .enumerate()
            // SAFETY: the processor has AVX2 (the caller's promise).
            .for_each(|(chunk, olds)| unsafe { old_points(t, f, chunk * CHUNK, olds) });
        out.edges
            .par_chunks_mut(CHUNK)
            .zip(t.edge_corners.par_chunks(CHUNK))
            // SAFETY: as above.
            .for_each(|(edges, corners)| unsafe { edge_points(quads, corners, edges) });
        out.faces
            .par_chunks_mut(CHUNK)
            .zip(quads_of_faces.par_chunks(CHUNK))
            // SAFETY: as above.
            .for_each(|(faces, quads)| unsafe { face_points(quads, faces) });
    }

    /// Old vertices `start..`: the mean of the fine faces at each one's corners.
    #[target_feature(enable = "avx2")]
    unsafe fn old_points<W: Lanes, const N: usize>(
        t: &Tables,
        f: &[[W; N]],
        start: usize,
        out: &mut [MaybeUninit<[W; N]>],
    ) {
        for (i, item) in out.iter_mut().enumerate() {
            let corners = t.corners_of_vertex(start + i);
            // SAFETY: AVX2 is enabled here; `&f[c]` (bounds checked) and `item` are `N` values.
            unsafe {
                let mut sum = W::zero();
                for &c in corners {
                    sum = W::plus(sum, W::load(&f[c as usize]));
                }
                W::store(item.as_mut_ptr(), W::scale(sum, reciprocal(corners.len())));
            }
        }
    }

    /// Edge points: the fine faces of each edge's corners and their successors (two faces of
    /// one coarse quad each).
    #[target_feature(enable = "avx2")]
    unsafe fn edge_points<W: Lanes, const N: usize>(
        quads: &[[[W; N]; 4]],
        corners: &[[u32; 2]],
        out: &mut [MaybeUninit<[W; N]>],
    ) {
        let pair = |c: u32| {
            let (q, k) = (&quads[(c >> 2) as usize], (c & 3) as usize);
            // SAFETY: AVX2 is enabled here; each is `N` values of the quad.
            unsafe { W::plus(W::load(&q[k]), W::load(&q[(k + 1) & 3])) }
        };
        let (half, quarter) = (W::from_f64(0.5), W::from_f64(0.25));
        for (item, &corners) in out.iter_mut().zip(corners) {
            // SAFETY: AVX2 is enabled here; `item` is `N` values.
            unsafe {
                let mean = match corners {
                    [c, NONE] => W::scale(pair(c), half),
                    [c, d] => W::scale(W::plus(pair(c), pair(d)), quarter),
                };
                W::store(item.as_mut_ptr(), mean);
            }
        }
    }

    /// Face points: the mean of each coarse quad's four fine faces.
    #[target_feature(enable = "avx2")]
    unsafe fn face_points<W: Lanes, const N: usize>(
        quads: &[[[W; N]; 4]],
        out: &mut [MaybeUninit<[W; N]>],
    ) {
        let quarter = W::from_f64(0.25);
        for (item, q) in out.iter_mut().zip(quads) {
            // SAFETY: AVX2 is enabled here; each of `q` and `item` is `N` values.
            unsafe {
                let sum = q.iter().fold(W::zero(), |s, x| W::plus(s, W::load(x)));
                W::store(item.as_mut_ptr(), W::scale(sum, quarter));
            }
        }
    }
}
