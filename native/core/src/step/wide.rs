//! The dual -> primal average of a quad level ([`super::LevelData::gather_primal`]) in vectors:
//! a value of up to four channels in one register (`f32` in SSE, `f64` in AVX), read by masked
//! loads and written by plain stores ([`avx2::Lanes::store`]) of exactly its channels. Each
//! sum is the portable loop's, in the same order, lane by lane, so the values are bitwise the
//! same.
//!
//! Why by hand: LLVM builds a three-channel value from a two-lane load and a scalar one, so a
//! point costs two of each operation, and it keeps a bounds check per read. The portable loop
//! took 57 instructions an edge point and was 73 % of a cached averaging-3 evaluation at level 3
//! (17.1M of 23.4M instructions under callgrind, one thread), 35 % of averaging 9 (17.1M of
//! 48.9M): every odd degree ends each step with this average over every fine vertex. The reads
//! are unchecked once a chunk's table is checked against the data (a table past it panics, as
//! indexing does). Now 11.4M of 17.8M at degree 3 (about 35 instructions a fine vertex);
//! averaging 5 and 7 34.6M -> 28.9M, 9 48.9M -> 43.2M; the rest of an odd-degree evaluation is
//! the regular windows' kernel ([`super::regular`]).
//!
//! The fused points of degrees 3 and 5 ([`super::fused`]) have their sums and their nets' walk
//! here too: the same operations as the portable code, four lanes at a time.

use std::mem::MaybeUninit;

use super::fused::{self, Fused};
use super::Tables;
use crate::parallel::Disjoint;
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

/// Writes the fused points of `fused` ([`super::fused`]) from the coarse vertices' data `x`
/// into `out` when the processor has AVX2 and the values are one to four channels of `f32` or
/// `f64`; returns false, having written nothing, otherwise. `fused`, `x`, `ids` and `out`
/// are as [`Fused::apply`] checked them.
pub(super) fn fused_points<T: Scalar, const N: usize>(
    fused: &Fused,
    x: &[Value<T, N>],
    ids: fused::ClosureIds,
    out: &Disjoint<Value<T, N>>,
) -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        use std::any::TypeId;
        if !(1..=4).contains(&N) || !std::arch::is_x86_feature_detected!("avx2") {
            return false;
        }
        if TypeId::of::<T>() == TypeId::of::<f32>() {
            // SAFETY: `T` is `f32`: the same types; the rest is the caller's promise.
            unsafe { avx2::fused::<f32, N>(fused, cast(x), ids, cast_disjoint(out)) };
            return true;
        }
        if TypeId::of::<T>() == TypeId::of::<f64>() {
            // SAFETY: `T` is `f64`: the same types; the rest is the caller's promise.
            unsafe { avx2::fused::<f64, N>(fused, cast(x), ids, cast_disjoint(out)) };
            return true;
        }
    }
    let _ = (fused, x, ids, out);
    false
}

/// Writes the nets ([`fused::NET`] ids each) of the faces `start..` that `nets` holds from
/// the walk's corner tables when the processor has AVX2; returns false, having written
/// nothing, otherwise. The same ids as the loop of [`super::fused`]: four corners at once.
pub(super) fn fused_nets(
    corners: super::regular::Tables,
    start: usize,
    nets: &mut [MaybeUninit<u32>],
) -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        let (twin, verts) = corners.corner_tables();
        // The gathers index by `i32`.
        if std::arch::is_x86_feature_detected!("avx2") && twin.len() <= i32::MAX as usize {
            let faces = nets.len() / fused::NET;
            assert!(
                nets.len().is_multiple_of(fused::NET)
                    && 4 * (start + faces) + 4 <= twin.len()
                    && verts.len() == twin.len(),
                "nets of the tables' faces"
            );
            // SAFETY: AVX2 is there; the faces are the tables' (above), whose twins and
            // vertices are within them (`Tables::corner_tables`).
            unsafe { avx2::nets(twin, verts, start, nets) };
            return true;
        }
    }
    let _ = (corners, start, nets);
    false
}

/// Writes the net of the dual face of a coarse vertex with corners `cycle` (a drawing step's,
/// [`super::fused`]) from the walk's corner tables when the processor has AVX2; returns false,
/// having written nothing, otherwise. The same ids as the loop: the four corners' faces, then
/// the faces across the twins of the corners after them, two after them, and before the first
/// twins, in one gather of four each.
pub(super) fn dual_net(
    corners: super::regular::Tables,
    cycle: [u32; 4],
    net: &mut [MaybeUninit<u32>; fused::NET],
) -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        let (twin, _) = corners.corner_tables();
        // The gathers index by `i32`; the cycle's corners are the level's.
        let fits = twin.len() <= i32::MAX as usize
            && twin.len() >= 4
            && cycle.iter().all(|&c| (c as usize) < twin.len() - 4);
        if std::arch::is_x86_feature_detected!("avx2") && fits {
            // SAFETY: AVX2 is there; the corners are the tables' (above), whose twins are
            // within them (`Tables::corner_tables`).
            unsafe { avx2::dual_net(twin, cycle, net) };
            return true;
        }
    }
    let _ = (corners, cycle, net);
    false
}

/// `out` writing values of `[U; N]`.
///
/// # Safety
/// `U` must be `T`.
#[cfg(target_arch = "x86_64")]
unsafe fn cast_disjoint<'a, 'o, T, U, const N: usize>(
    out: &'a Disjoint<'o, [T; N]>,
) -> &'a Disjoint<'o, [U; N]> {
    // SAFETY: the same type (the caller's promise), so the same layout.
    unsafe { &*(out as *const Disjoint<'o, [T; N]>).cast::<Disjoint<'o, [U; N]>>() }
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
    use crate::parallel::{Disjoint, CHUNK};
    use crate::scalar::{reciprocal, Scalar};
    use crate::step::fused::{closure_points, ClosureIds, Fused, Sums, Weights, NET};
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
        /// Writes lanes `0..N` of `v` to `at`, and nothing past them, by plain stores: a masked
        /// store (`vmaskmovps` / `vmaskmovpd` to memory) writes the same bytes, but on this
        /// project's machines (AMD Zen 3) took 4.0-5.3 ns against 1.1-1.6 ns for a scattered
        /// three-channel `f32` value (a loop of 20 x 2^20 stores, 2026-12-08), and cached
        /// evaluations of degree 3 ran 1.5-1.9x faster without them.
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
            let at = at.cast::<f32>();
            // SAFETY: `N` writable values at `at` (the caller's promise), each store within
            // them; SSE4.1 is part of the AVX2 code this inlines into.
            unsafe {
                match N {
                    0 => {}
                    1 => _mm_store_ss(at, v),
                    2 => _mm_storel_epi64(at.cast(), _mm_castps_si128(v)),
                    3 => {
                        _mm_storel_epi64(at.cast(), _mm_castps_si128(v));
                        (at.add(2).cast::<i32>()).write_unaligned(_mm_extract_ps::<2>(v));
                    }
                    _ => _mm_storeu_ps(at, v),
                }
            }
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
            let at = at.cast::<f64>();
            // SAFETY: `N` writable values at `at` (the caller's promise), each store within
            // them; AVX is enabled (the caller's promise).
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

    /// A vector register holding a value, as the fused points' sums see it. Made only inside
    /// functions compiled for AVX2 ([`fused_chunk`]), where its operations are inlined.
    #[derive(Clone, Copy)]
    struct Reg<W: Lanes>(W::V);

    impl<W: Lanes> Sums for Reg<W> {
        type Weight = W;
        #[inline(always)]
        fn plus(self, other: Self) -> Self {
            // SAFETY: a `Reg` exists only in code compiled for AVX2 (above).
            Reg(unsafe { W::plus(self.0, other.0) })
        }
        #[inline(always)]
        fn times(self, w: W) -> Self {
            // SAFETY: as `plus`.
            Reg(unsafe { W::scale(self.0, w) })
        }
    }

    /// [`super::fused_points`] with vectors of `W`, in parallel chunks of faces.
    ///
    /// # Safety
    /// The processor must have AVX2, and `fused`, `x`, `ids` and `out` must be as
    /// [`Fused::apply`] checks them.
    pub(super) unsafe fn fused<W: Lanes, const N: usize>(
        fused: &Fused,
        x: &[[W; N]],
        ids: ClosureIds,
        out: &Disjoint<[W; N]>,
    ) {
        let weights = Weights::new(W::from_f64);
        let nets = fused.nets();
        let (degree, dual) = (fused.degree(), fused.dual());
        fused
            .owned()
            .par_chunks(CHUNK)
            .enumerate()
            // SAFETY: the caller's promise.
            .for_each(|(chunk, owned)| unsafe {
                let start = chunk * CHUNK;
                let (o, n, s, w) = (owned, nets, start, weights);
                match (degree, dual) {
                    (3, false) => fused_chunk::<W, N, 3, false>(o, n, s, x, ids, out, w),
                    (3, true) => fused_chunk::<W, N, 3, true>(o, n, s, x, ids, out, w),
                    (_, false) => fused_chunk::<W, N, 5, false>(o, n, s, x, ids, out, w),
                    (_, true) => fused_chunk::<W, N, 5, true>(o, n, s, x, ids, out, w),
                }
            });
    }

    /// The fused points of cells `start..start + owned.len()` (faces, or the dual grid's
    /// vertices when `DUAL`), with the masks of `DEGREE`.
    ///
    /// # Safety
    /// As [`fused`].
    #[target_feature(enable = "avx2")]
    unsafe fn fused_chunk<W: Lanes, const N: usize, const DEGREE: u32, const DUAL: bool>(
        owned: &[u16],
        nets: &[u32],
        start: usize,
        x: &[[W; N]],
        ids: ClosureIds,
        out: &Disjoint<[W; N]>,
        weights: Weights<W>,
    ) {
        let base = x.as_ptr();
        for (i, &bits) in owned.iter().enumerate() {
            if bits == 0 {
                continue;
            }
            let f = start + i;
            // SAFETY: AVX2 is enabled here; the face's net is within `nets` and its ids within
            // `x`, each written vertex below `out.len()` and written by this face alone
            // (`Fused::apply` checked the sizes; `Owners::of` gave each point one owner and
            // checked its id).
            unsafe {
                let net = nets.get_unchecked(NET * f..NET * f + NET);
                let p: [Reg<W>; NET] =
                    std::array::from_fn(|k| Reg(W::load(base.add(*net.get_unchecked(k) as usize))));
                closure_points::<_, DEGREE, DUAL>(bits, &p, weights, |bit, value: Reg<W>| {
                    W::store(out.slot(ids.fine_vertex_of::<DUAL>(bit, f)), value.0)
                });
            }
        }
    }

    /// [`super::fused_nets`]: per face, its four corners' twins `t` and the twins `d` across
    /// the corner before each `t`, in one vector of four each; the net is then four vectors,
    /// the corners' vertices and those of `t ^ 2`, of the corner before `t`, and of `d ^ 2`.
    ///
    /// # Safety
    /// The processor must have AVX2; `twin` and `verts` as [`super::fused_nets`] checks them,
    /// with `4 nf + 4` entries for the `nf` faces of the level, `start + nets.len() / NET` of
    /// them at most, every twin below `4 nf + 4` and `twin.len()` at most `i32::MAX`.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn nets(
        twin: &[u32],
        verts: &[u32],
        start: usize,
        nets: &mut [MaybeUninit<u32>],
    ) {
        let (twins, vertices) = (twin.as_ptr().cast::<i32>(), verts.as_ptr().cast::<i32>());
        let lanes = _mm_setr_epi32(0, 1, 2, 3);
        let (quad, corner, two) = (_mm_set1_epi32(!3), _mm_set1_epi32(3), _mm_set1_epi32(2));
        for (i, net) in nets.chunks_exact_mut(NET).enumerate() {
            let f = start + i;
            let c = _mm_add_epi32(_mm_set1_epi32(4 * f as i32), lanes);
            // SAFETY: every index is a corner of the level or of the dead face, below
            // `twin.len() = verts.len()` (the caller's promise): `c` of a face, `t` and `d`
            // twins, the others corners of their quads; the net has `NET` = 16 ids.
            unsafe {
                let t = _mm_i32gather_epi32::<4>(twins, c);
                // The corner before `t` in its quad (`after(t, 3)`).
                let before = _mm_or_si128(
                    _mm_and_si128(t, quad),
                    _mm_and_si128(_mm_add_epi32(t, corner), corner),
                );
                let d = _mm_i32gather_epi32::<4>(twins, before);
                let out = net.as_mut_ptr().cast::<__m128i>();
                _mm_storeu_si128(out, _mm_loadu_si128(vertices.add(4 * f).cast()));
                let across = _mm_i32gather_epi32::<4>(vertices, _mm_xor_si128(t, two));
                _mm_storeu_si128(out.add(1), across);
                _mm_storeu_si128(out.add(2), _mm_i32gather_epi32::<4>(vertices, before));
                let diagonal = _mm_i32gather_epi32::<4>(vertices, _mm_xor_si128(d, two));
                _mm_storeu_si128(out.add(3), diagonal);
            }
        }
    }

    /// [`super::dual_net`]: the corners after each of `cycle`'s and two after, their twins `a`
    /// and `b`, and the twins `d` of the corners before each `a`; the faces of the four
    /// vectors (0 for the dead face, `twin.len() - 4`).
    ///
    /// # Safety
    /// The processor must have AVX2; `cycle` corners of the level (below `twin.len() - 4`),
    /// `twin` at most `i32::MAX` entries, every twin below `twin.len()`.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn dual_net(
        twin: &[u32],
        cycle: [u32; 4],
        net: &mut [MaybeUninit<u32>; NET],
    ) {
        let twins = twin.as_ptr().cast::<i32>();
        let dead = _mm_set1_epi32((twin.len() - 4) as i32);
        let (quad, corner) = (_mm_set1_epi32(!3), _mm_set1_epi32(3));
        let after = |c: __m128i, k: i32| {
            _mm_or_si128(
                _mm_and_si128(c, quad),
                _mm_and_si128(_mm_add_epi32(c, _mm_set1_epi32(k)), corner),
            )
        };
        // The face of each corner, 0 for the dead face's.
        let face = |c: __m128i| _mm_and_si128(_mm_srli_epi32::<2>(c), _mm_cmpgt_epi32(dead, c));
        // SAFETY: every index is a corner of the level or of the dead face, below `twin.len()`
        // (the caller's promise): the cycle's, twins, and the other corners of their quads.
        unsafe {
            let c = _mm_loadu_si128(cycle.as_ptr().cast());
            let a = _mm_i32gather_epi32::<4>(twins, after(c, 1));
            let b = _mm_i32gather_epi32::<4>(twins, _mm_xor_si128(c, _mm_set1_epi32(2)));
            let d = _mm_i32gather_epi32::<4>(twins, after(a, 3));
            let out = net.as_mut_ptr().cast::<__m128i>();
            _mm_storeu_si128(out, _mm_srli_epi32::<2>(c));
            _mm_storeu_si128(out.add(1), face(a));
            _mm_storeu_si128(out.add(2), face(b));
            _mm_storeu_si128(out.add(3), face(d));
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
        // The chunk's offsets and corners checked once (not per read, as indexing would; the
        // portable loop panics there too): offsets in order within the table, corners in `f`.
        let offsets = &t.vertex_offsets[start..=start + out.len()];
        let first = offsets[0] as usize;
        let corners = &t.vertex_corners[first..offsets[out.len()] as usize];
        let len = f.len() as u64;
        let fit = (corners.iter()).fold(true, |fit, &c| fit & (u64::from(c) < len))
            & (offsets.windows(2)).fold(true, |fit, w| fit & (w[0] <= w[1]));
        assert!(fit, "a vertex corner past the level's faces");
        let (faces, corners) = (f.as_ptr(), corners.as_ptr());
        for (item, ends) in out.iter_mut().zip(offsets.windows(2)) {
            let (from, to) = (ends[0] as usize - first, ends[1] as usize - first);
            // SAFETY: AVX2 is enabled here; `from..to` is within the chunk's corners and each
            // corner within `f` (checked above); `item` is `N` values.
            unsafe {
                let mut sum = W::zero();
                for k in from..to {
                    sum = W::plus(sum, W::load(faces.add(*corners.add(k) as usize)));
                }
                W::store(item.as_mut_ptr(), W::scale(sum, reciprocal(to - from)));
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
        // The corners checked once for the chunk (not per read, as indexing would): the
        // portable loop panics there too.
        let quads_len = quads.len() as u64;
        let inside = |c: u32| u64::from(c >> 2) < quads_len;
        let fit = (corners.iter()).fold(true, |fit, &[c, d]| {
            fit & inside(c) & (d == NONE || inside(d))
        });
        assert!(fit, "an edge corner past the level's faces");
        let faces = quads.as_ptr().cast::<[W; N]>();
        let pair = |c: u32| {
            // The corner's fine face and its successor's, in the same coarse quad.
            let next = (c & !3) | (c.wrapping_add(1) & 3);
            // SAFETY: AVX2 is enabled here; both are fine faces of quad `c >> 2`, which the
            // check above found in `quads`.
            unsafe {
                let (a, b) = (faces.add(c as usize), faces.add(next as usize));
                W::plus(W::load(a), W::load(b))
            }
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

#[cfg(test)]
mod tests {
    use std::mem::MaybeUninit;

    use super::{gather_primal, PrimalSections};
    use crate::refinement::Refinement;
    use crate::scalar::{Scalar, Value};
    use crate::step::regular::tests::{cube_grid, open_grid};
    use crate::step::{quad_edge_mean, quad_mean, vertex_corner_mean, Tables};
    use crate::{Cage, Options, Rules};

    /// Fine-face data of `n` values: pseudo-random, of mixed signs and magnitudes, with a
    /// negative zero in every 17th channel (a sum must start from `+0.0` as the portable one does).
    fn data<T: Scalar, const N: usize>(n: usize, seed: u64) -> Vec<Value<T, N>> {
        let mut s = seed;
        (0..n)
            .map(|i| {
                std::array::from_fn(|c| {
                    s = s
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    let x = (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
                    if (N * i + c).is_multiple_of(17) {
                        T::from_f64(-0.0)
                    } else {
                        T::from_f64(x * 10f64.powi((i % 7) as i32 - 3))
                    }
                })
            })
            .collect()
    }

    /// Every quad level of `cage` refined: the vectors' three sections against the portable
    /// means, bit for bit.
    fn same_as_portable<T: Scalar, const N: usize>(cage: &Cage) {
        let options = Options {
            degree: 3,
            levels: 3,
            rules: Rules::Averaging,
            ..Options::default()
        };
        let refinement = Refinement::new(cage, &options).unwrap();
        let mut tested = 0;
        for (j, coarse) in refinement.levels()[..3].iter().enumerate() {
            let t = Tables::of(coarse);
            if !t.quads {
                continue;
            }
            let f = data::<T, N>(4 * coarse.num_faces(), j as u64 + 1);
            let (quads, _) = f.as_chunks::<4>();
            let (nv, ne, nf) = (
                coarse.num_vertices,
                t.edge_corners.len(),
                coarse.num_faces(),
            );
            let mut out = vec![MaybeUninit::<Value<T, N>>::uninit(); nv + ne + nf];
            let (olds, rest) = out.split_at_mut(nv);
            let (edges, faces) = rest.split_at_mut(ne);
            let done = gather_primal(&t, &f, PrimalSections { olds, edges, faces });
            #[cfg(target_arch = "x86_64")]
            assert_eq!(done, std::arch::is_x86_feature_detected!("avx2"));
            if !done {
                return;
            }
            // SAFETY: `gather_primal` returned true: it wrote every item.
            let out: Vec<Value<T, N>> = out.iter().map(|x| unsafe { x.assume_init() }).collect();
            let bits = |x: Value<T, N>| x.map(|c| c.to_f64().to_bits());
            for (w, &value) in out.iter().enumerate() {
                let portable = if w < nv {
                    vertex_corner_mean(&t, &f, w)
                } else if w < nv + ne {
                    quad_edge_mean(quads, t.edge_corners[w - nv])
                } else {
                    quad_mean(&quads[w - nv - ne], T::from_f64(0.25))
                };
                assert_eq!(
                    bits(value),
                    bits(portable),
                    "level {j}, item {w} of {}",
                    out.len()
                );
            }
            tested += 1;
        }
        assert!(tested >= 2, "{tested} quad levels");
    }

    /// A table pointing past the fine faces panics on the vectors' path, as indexing does on
    /// the portable one (their reads are unchecked once the chunk's table is checked).
    #[test]
    fn a_corner_past_the_faces_panics() {
        let (cage, _) = cube_grid(2);
        let options = Options {
            degree: 3,
            levels: 2,
            rules: Rules::Averaging,
            ..Options::default()
        };
        let refinement = Refinement::new(&cage, &options).unwrap();
        let coarse = &refinement.levels()[1];
        let t = Tables::of(coarse);
        let f = data::<f32, 3>(4 * coarse.num_faces(), 1);
        let past = 4 * coarse.num_faces() as u32;
        let (mut edge_corners, mut vertex_corners) =
            (t.edge_corners.to_vec(), t.vertex_corners.to_vec());
        edge_corners[5][1] = past;
        vertex_corners[7] = past + 3;
        let run = |t: Tables| {
            let n = coarse.num_vertices + t.edge_corners.len() + coarse.num_faces();
            let mut out = vec![MaybeUninit::<Value<f32, 3>>::uninit(); n];
            let (olds, rest) = out.split_at_mut(coarse.num_vertices);
            let (edges, faces) = rest.split_at_mut(t.edge_corners.len());
            let sections = PrimalSections { olds, edges, faces };
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                gather_primal(&t, &f, sections)
            }))
        };
        assert!(matches!(run(t), Ok(true) | Ok(false)));
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            assert!(run(Tables {
                edge_corners: &edge_corners,
                ..t
            })
            .is_err());
            assert!(run(Tables {
                vertex_corners: &vertex_corners,
                ..t
            })
            .is_err());
        }
    }

    /// Lanes `0..N` of `1, 2, 3, 4` stored between guards by [`super::avx2::Lanes::store`]: exactly
    /// those, nothing else.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn stored<W: super::avx2::Lanes, const N: usize>() -> [f64; 6] {
        let mut out = [W::from_f64(-1.0); 6];
        let four = [1.0, 2.0, 3.0, 4.0].map(W::from_f64);
        // SAFETY: AVX2 is enabled; four values to read, items 1..5 writable, `N` at most 4.
        unsafe { W::store::<N>(out[1..].as_mut_ptr().cast(), W::load::<4>(&four)) };
        out.map(W::to_f64)
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn stores_write_exactly_their_channels() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            eprintln!("no AVX2 here: the stores are not run");
            return;
        }
        let expected = |n: usize| -> [f64; 6] {
            std::array::from_fn(|i| match (1..=n).contains(&i) {
                true => i as f64,
                false => -1.0,
            })
        };
        // SAFETY: the processor has AVX2 (checked above).
        let (single, double) = unsafe {
            (
                [
                    stored::<f32, 0>(),
                    stored::<f32, 1>(),
                    stored::<f32, 2>(),
                    stored::<f32, 3>(),
                    stored::<f32, 4>(),
                ],
                [
                    stored::<f64, 0>(),
                    stored::<f64, 1>(),
                    stored::<f64, 2>(),
                    stored::<f64, 3>(),
                    stored::<f64, 4>(),
                ],
            )
        };
        for n in 0..=4 {
            assert_eq!(single[n], expected(n), "f32, {n} channels");
            assert_eq!(double[n], expected(n), "f64, {n} channels");
        }
    }

    #[test]
    fn vectors_give_the_portable_means() {
        // Boundaries (edges of one face), valences 2 to 5, triangles at level 0; valence 3.
        for (cage, _) in [open_grid(7, 6, 1.5), cube_grid(2)] {
            same_as_portable::<f32, 1>(&cage);
            same_as_portable::<f32, 2>(&cage);
            same_as_portable::<f32, 3>(&cage);
            same_as_portable::<f32, 4>(&cage);
            same_as_portable::<f64, 1>(&cage);
            same_as_portable::<f64, 2>(&cage);
            same_as_portable::<f64, 3>(&cage);
            same_as_portable::<f64, 4>(&cage);
        }
    }
}
