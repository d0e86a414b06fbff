//! Limit tiles: limit positions and normals over the regular regions of a quad level by
//! separable tensor-product B-spline masks, a block of vertices at a time.
//!
//! Where a vertex's `N`-ring neighbourhood is a grid of regular vertices, its limit masks are
//! the tensor products of the 1-D B-spline masks at a knot: the value mask for the position,
//! value x slope and slope x value for the two tangents (DESIGN.md §1; the eigenvectors of the
//! parent module give the same masks at valence 4, tested). Walked per vertex, as the stencils
//! are, each vertex reads its `K^2` items (`K = 2N + 1` vertices for odd degrees, `2N` faces
//! for even ones) and makes three sums over all of them. Over a block of vertices the rows of
//! the block's window are filtered once for all of its columns, and each vertex then makes three
//! column sums of `K` products: per vertex and channel about `5K` products instead of `3K^2`
//! (fewer with the symmetric folding), and each datum is read once per block instead of `K^2`
//! times.
//!
//! A tile is the block of level-`L` vertices over a face of level `L - t`, `t` at most
//! [`MAX_DEPTH`]: its descendants are the level's faces `g 4^t .. (g + 1) 4^t` (a face's
//! children are numbered by its corners), and the first of them has its corner 0 at the face's
//! corner 0, along the face's first edge, so the tile's frame is the face's. Its window, `N`
//! rings more on every side, is found once per plan: where the faces of the level above around
//! the tile's face are a grid of regular vertices (most of a mesh), its cells follow from them by
//! the children's numbering ([`Above`]); elsewhere the window is walked over the level's twin
//! corners (the same cells where both apply: test `fast_walks_are_the_walks`). A vertex is
//! taken by a tile whose walk holds its whole neighbourhood as a grid of regular vertices
//! (valence 4, interior, on no curve; all different): exactly the vertices whose stencils would
//! be the valence-4 masks, less those that no tile holds so (near an irregular vertex, the walk
//! from the tile's corner goes around it), which keep their stencils. The tile is the first (in
//! face order) that holds the vertex off its far column and far row, else the first that holds
//! it at all: the far column is shared with the next tile, and a tile that owns none of it
//! filters fewer columns (one four-lane vector less at sides 5 and 9).

use std::mem::MaybeUninit;
use std::sync::Mutex;

use rayon::prelude::*;

use super::{knot_mask, Pooled, Stamps};
use crate::analysis::neighbourhood_size;
use crate::error::{Error, Result};
use crate::memory;
use crate::parallel::Disjoint;
use crate::scalar::{add, mad, sub, Scalar};
use crate::scheme::{cardinal_bspline, cardinal_bspline_derivative};
use crate::topology::{quad_next, quad_prev, Level, NONE};

/// The largest tile depth `t`: a tile holds `2^t x 2^t` faces of its level.
pub(super) const MAX_DEPTH: u32 = 3;

/// Output vertices per side of the largest tile.
const MAX_SIDE: usize = (1 << MAX_DEPTH) + 1;
// A row of a tile's vertices is walked as the bits of a `u32`.
const _: () = assert!(MAX_SIDE <= 32);

/// Data items per side of the largest window (`N <= 4`, degree 9).
const MAX_DATA: usize = MAX_SIDE + 2 * 4;

/// Four-lane vectors per filtered row: the output columns of the largest tile, rounded up.
const MAX_VECTORS: usize = MAX_SIDE.div_ceil(4);

/// Items per row of a task's window: the items the vectors of the largest tile read (output
/// column `4 MAX_VECTORS - 1` reads `K - 1 <= 8` more). Past a window's data they are leftovers
/// that no output's sum reads.
const WINDOW_ROW: usize = 4 * MAX_VECTORS + 8;

/// Walked cells per side of the largest window (one ring more than the data, so that every
/// vertex of the window has its four cells).
const MAX_CELLS: usize = MAX_DATA + 1;

/// Tiles walked between two claims (bounds the memory of the walks in flight).
const BLOCK: usize = 1 << 12;

/// The tiles of one quad level: their windows, the vertices each computes, and the 1-D masks.
#[derive(Debug)]
pub(super) struct Tiles {
    /// Output vertices per side of a tile (`2^t + 1`; the far row and column are shared with
    /// the next tiles, whichever claims them first).
    side: usize,
    /// Items per side of a window: vertices for odd degrees, faces for even ones.
    data_side: usize,
    /// The masks' width `K`.
    width: usize,
    /// The 1-D value and slope masks at a knot over the `K` items, lowest coordinate first.
    value: Vec<f64>,
    slope: Vec<f64>,
    /// Per tile, its window's data ids row after row (`data_side^2`; 0 where no output of the
    /// tile reads one).
    ids: Vec<u32>,
    /// One more than the largest of `ids`.
    ids_end: usize,
    /// Per tile, its output vertices (bit `side * j + i` for the vertex at column `i`, row `j`).
    owned: Vec<u128>,
    /// Per tile, its first slot (the slots of its vertices follow in bit order); one more.
    offsets: Vec<u32>,
    /// Per slot, its level vertex (each vertex in one slot at most).
    vertices: Vec<u32>,
    /// One more than the largest of `vertices`.
    vertices_end: usize,
}

impl Tiles {
    /// The tiles of `level` (a quad level whose faces `g 4^depth ..` descend from one face of
    /// the level `depth` above it) for the limit of `degree`: `twins` are the level's
    /// [`Level::twin_corners`], `marks` per vertex 0 when regular (valence 4, interior, on no
    /// curve). `None` when no vertex is computed by a tile. The walks take their [`Stamps`]
    /// over `marks` from `pool` (the stencils' build then finds them there). `above` is the
    /// level `depth` levels above (the tiles' faces descend from its faces): most tiles' cells
    /// follow from its faces ([`Above`]).
    pub(super) fn build(
        level: &Level,
        above: &Level,
        twins: &[u32],
        marks: &[u32],
        degree: u32,
        depth: u32,
        pool: &Mutex<Vec<Stamps>>,
    ) -> Result<Option<Tiles>> {
        if depth > MAX_DEPTH || !level.is_quads() || !(2..=9).contains(&degree) {
            return Ok(None);
        }
        // The slope's sign is the same for both tangents, so the normal does not see it.
        let value = knot_mask(degree, cardinal_bspline);
        let slope = knot_mask(degree, cardinal_bspline_derivative);
        let width = value.len();
        let faces = level.num_faces();
        let count = faces >> (2 * depth);
        if count << (2 * depth) != faces || above.num_faces() != count || !above.all_quads() {
            return Err(Error::Internal(
                "limit tiles: the level's faces are not blocks of one face's descendants".into(),
            ));
        }
        let geometry = Geometry::new(level, above, twins, marks, degree, depth)?;
        let (side, data_side) = (geometry.t + 1, geometry.data_side);
        // Claims in two passes, each in tile order (the result does not depend on the thread
        // count): first the outputs off a tile's far column and row, then the far ones that no
        // tile took. A far output of one tile is most often a near one of the next, so most
        // tiles own no far column and filter fewer columns ([`Tiles::write`]).
        let far = far_outputs(side);
        let (window, outputs_per_tile) = (data_side * data_side, side * side);
        let mut claimed = memory::filled(level.num_vertices, false)?;
        // Per tile that may own an output: its window's ids, its outputs' level vertices, what
        // it owns, and its valid far outputs. Each block of tiles is walked into the tail of
        // the first two, then the tiles that own nothing and hold no far output are dropped.
        let mut ids: Vec<u32> = Vec::new();
        let mut outputs: Vec<u32> = Vec::new();
        let mut owned: Vec<u128> = Vec::new();
        let mut far_valid: Vec<u128> = Vec::new();
        // A block's valid outputs in a buffer allocated fallibly once (collected into a new
        // vector, a block's walks were the allocation that aborted a deep limit under a tight
        // address space).
        let mut valid: Vec<Result<u128>> = memory::with_capacity(count.min(BLOCK))?;
        for start in (0..count).step_by(BLOCK) {
            let end = (start + BLOCK).min(count);
            let (walked, kept) = (end - start, owned.len());
            // Room for every tile of the block at once (per tile, the checks of `grow` were 2 %
            // of a first limit call at degree 3, level 2).
            memory::grow(&mut ids, walked * window)?;
            memory::grow(&mut outputs, walked * outputs_per_tile)?;
            memory::grow(&mut owned, walked)?;
            memory::grow(&mut far_valid, walked)?;
            ids.resize(ids.len() + walked * window, 0);
            outputs.resize(outputs.len() + walked * outputs_per_tile, NONE);
            let tails = (ids[kept * window..].par_chunks_mut(window))
                .zip(outputs[kept * outputs_per_tile..].par_chunks_mut(outputs_per_tile));
            (start..end)
                .into_par_iter()
                .zip(tails)
                .with_min_len(16)
                .map_init(
                    || Pooled::take(pool, marks),
                    |stamps, (g, (ids, outputs))| {
                        let stamps = stamps.stamps.as_mut().map_err(|e| e.clone())?;
                        Ok(geometry.walk(g << (2 * depth), stamps, ids, outputs))
                    },
                )
                .collect_into_vec(&mut valid);
            let mut to = kept;
            for (k, bits) in valid.iter().enumerate() {
                let bits = *bits.as_ref().map_err(|e| e.clone())?;
                let from = kept + k;
                let tile_outputs = &outputs[from * outputs_per_tile..][..outputs_per_tile];
                let mine = claim(bits & !far, tile_outputs, &mut claimed)?;
                if mine == 0 && bits & far == 0 {
                    continue;
                }
                if to != from {
                    ids.copy_within(from * window..(from + 1) * window, to * window);
                    outputs.copy_within(
                        from * outputs_per_tile..(from + 1) * outputs_per_tile,
                        to * outputs_per_tile,
                    );
                }
                owned.push(mine);
                far_valid.push(bits & far);
                to += 1;
            }
            ids.truncate(to * window);
            outputs.truncate(to * outputs_per_tile);
        }
        for ((mine, &bits), outputs) in owned
            .iter_mut()
            .zip(&far_valid)
            .zip(outputs.chunks_exact(outputs_per_tile))
        {
            *mine |= claim(bits, outputs, &mut claimed)?;
        }
        // The tiles that own an output, each with its vertices' slots in bit order.
        let mut kept = 0;
        let mut offsets: Vec<u32> = memory::with_capacity(owned.len() + 1)?;
        offsets.push(0);
        let owned_outputs = owned.iter().map(|m| m.count_ones() as usize).sum();
        let mut vertices: Vec<u32> = memory::with_capacity(owned_outputs)?;
        for tile in 0..owned.len() {
            let mine = owned[tile];
            if mine == 0 {
                continue;
            }
            let mut bits = mine;
            while bits != 0 {
                let b = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                vertices.push(outputs[tile * outputs_per_tile + b]);
            }
            offsets.push(vertices.len() as u32);
            ids.copy_within(tile * window..(tile + 1) * window, kept * window);
            owned[kept] = mine;
            kept += 1;
        }
        ids.truncate(kept * window);
        owned.truncate(kept);
        if owned.is_empty() {
            return Ok(None);
        }
        let ids_end = ids.iter().max().map_or(0, |&id| id as usize + 1);
        let vertices_end = vertices.iter().max().map_or(0, |&v| v as usize + 1);
        Ok(Some(Tiles {
            side,
            data_side,
            width,
            value,
            slope,
            ids_end,
            ids,
            owned,
            offsets,
            vertices,
            vertices_end,
        }))
    }

    /// The tiles that own an output of their far column (filtered with more columns), and
    /// all tiles.
    #[cfg(test)]
    pub(super) fn far_column_tiles(&self) -> (usize, usize) {
        let far = far_column(self.side);
        let wide = self.owned.iter().filter(|&&o| o & far != 0).count();
        (wide, self.owned.len())
    }

    /// Per vertex of the level (`num_vertices` of them), whether a tile computes it: what the
    /// stencils are built with, once (the tiles keep only their vertices' list).
    pub(super) fn computed(&self, num_vertices: usize) -> Result<Vec<bool>> {
        let mut computed = memory::filled(num_vertices, false)?;
        for &v in &self.vertices {
            *computed
                .get_mut(v as usize)
                .ok_or_else(|| Error::Internal("limit tiles: a vertex past the level".into()))? =
                true;
        }
        Ok(computed)
    }

    /// Writes at each vertex a tile computes its limit position from `data` (the level's
    /// data: per vertex for odd degrees, per face for even ones) into `positions` and, when
    /// given, its unit normal into `normals` (both per level vertex): the tangents are rounded
    /// to `T` before their cross product, as the stencils' are. No other item is written.
    pub(super) fn write<T: Scalar, const N: usize>(
        &self,
        data: &[[T; N]],
        positions: &mut [MaybeUninit<[T; N]>],
        normals: Option<&mut [MaybeUninit<[T; 3]>]>,
    ) -> Result<()> {
        self.write_on(data, positions, normals, wide_vectors())
    }

    /// [`Tiles::write`], in four-lane vectors when `wide` (the processor must have AVX2).
    pub(super) fn write_on<T: Scalar, const N: usize>(
        &self,
        data: &[[T; N]],
        positions: &mut [MaybeUninit<[T; N]>],
        normals: Option<&mut [MaybeUninit<[T; 3]>]>,
        wide: bool,
    ) -> Result<()> {
        let out = Out {
            positions: Disjoint::new(positions),
            normals: normals.map(Disjoint::new),
        };
        // Output columns are filtered four at a time, in as many vectors as the columns a tile
        // owns need, so that the tiles of levels 1 and 2 (side 3 and 5) do not filter the nine
        // columns of the largest tile, and a tile that owns no output of its far column (most
        // of them: see the claims of [`Tiles::build`]) filters one column less: two vectors, not
        // three, at side 9; one, not two, at side 5.
        match self.side {
            0..=4 => self.write_lanes::<T, N, 1, 1>(data, &out, wide),
            5 => self.write_lanes::<T, N, 1, 2>(data, &out, wide),
            6..=8 => self.write_lanes::<T, N, 2, 2>(data, &out, wide),
            _ => self.write_lanes::<T, N, 2, MAX_VECTORS>(data, &out, wide),
        }
    }

    /// [`Tiles::write_on`] with `NEAR` four-lane vectors of output columns for a tile that owns
    /// no output of its far column (at least the side less one), `FAR` for the others (at least
    /// the side).
    fn write_lanes<T: Scalar, const N: usize, const NEAR: usize, const FAR: usize>(
        &self,
        data: &[[T; N]],
        out: &Out<T, N>,
        wide: bool,
    ) -> Result<()> {
        match self.width {
            2 => self.write_with::<T, N, 2, NEAR, FAR>(data, out, wide),
            3 => self.write_with::<T, N, 3, NEAR, FAR>(data, out, wide),
            4 => self.write_with::<T, N, 4, NEAR, FAR>(data, out, wide),
            5 => self.write_with::<T, N, 5, NEAR, FAR>(data, out, wide),
            6 => self.write_with::<T, N, 6, NEAR, FAR>(data, out, wide),
            7 => self.write_with::<T, N, 7, NEAR, FAR>(data, out, wide),
            8 => self.write_with::<T, N, 8, NEAR, FAR>(data, out, wide),
            _ => self.write_with::<T, N, 9, NEAR, FAR>(data, out, wide),
        }
    }

    /// [`Tiles::write_lanes`] with the masks' width `K` a constant.
    fn write_with<
        T: Scalar,
        const N: usize,
        const K: usize,
        const NEAR: usize,
        const FAR: usize,
    >(
        &self,
        data: &[[T; N]],
        out: &Out<T, N>,
        wide: bool,
    ) -> Result<()> {
        // The rows read items up to `4 FAR + K - 2` of a window row (past the data: finite
        // leftovers, in sums no vertex reads).
        const { assert!(NEAR <= FAR && FAR <= MAX_VECTORS && 4 * FAR + K - 1 <= WINDOW_ROW) };
        if self.width != K
            || self.data_side > MAX_DATA
            || self.side > 4 * FAR
            || self.side > 4 * NEAR + 1
        {
            return Err(Error::Internal(
                "limit tiles: a window past its bounds".into(),
            ));
        }
        // What lets [`Kernel::tile`] write its vertices unchecked (a check per write was 2 %
        // of a cached limit).
        if self.vertices_end > out.positions.len()
            || out
                .normals
                .as_ref()
                .is_some_and(|n| self.vertices_end > n.len())
        {
            return Err(Error::Internal(
                "limit tiles: a vertex past the output".into(),
            ));
        }
        let tiles = self.owned.len();
        let value: [f64; K] = std::array::from_fn(|k| self.value[k]);
        let slope: [f64; K] = std::array::from_fn(|k| self.slope[k]);
        let kernel = Kernel {
            tiles: self,
            value: &value,
            slope: &slope,
            far_column: far_column(self.side),
            ids_in_data: self.ids_end <= data.len(),
        };
        let wide = wide && wide_vectors();
        // A tile is a few thousand instructions: small tasks still amortise.
        const TASK: usize = 32;
        (0..tiles.div_ceil(TASK))
            .into_par_iter()
            // One set of rows per split, not per task: zeroed per task, they were about 5 % of
            // a cached limit's instructions at level 2. Every tile overwrites what it reads of
            // them (the columns past a small tile's side hold finite leftovers of earlier tiles,
            // filtered into sums no vertex reads).
            .try_for_each_init(
                || {
                    Box::new(Rows::<N> {
                        window: [[[0.0; WINDOW_ROW]; MAX_DATA]; N],
                        by_value: [[[[0.0; 4]; MAX_VECTORS]; MAX_DATA]; N],
                        by_slope: [[[[0.0; 4]; MAX_VECTORS]; MAX_DATA]; N],
                    })
                },
                |rows, task| {
                    let tiles = task * TASK..((task + 1) * TASK).min(tiles);
                    #[cfg(target_arch = "x86_64")]
                    if wide {
                        // SAFETY: `wide_vectors` found AVX2 on this processor.
                        return unsafe {
                            kernel.tiles_avx2::<T, N, NEAR, FAR>(tiles, data, rows, out)
                        };
                    }
                    let _ = wide;
                    kernel.tiles::<T, N, NEAR, FAR, false>(tiles, data, rows, out)
                },
            )
    }
}

/// The bits of a tile's far column and far row (see [`Tiles::owned`]): the outputs it shares
/// with the next tiles.
fn far_outputs(side: usize) -> u128 {
    (0..side).fold(far_column(side), |far, i| {
        far | 1 << (side * (side - 1) + i)
    })
}

/// The bits of a tile's far column.
fn far_column(side: usize) -> u128 {
    (0..side).fold(0, |far, j| far | 1 << (side * j + side - 1))
}

/// Claims the outputs of `bits` (at the level vertices `outputs`) that no tile has yet: the
/// bits claimed.
fn claim(bits: u128, outputs: &[u32], claimed: &mut [bool]) -> Result<u128> {
    let mut mine = 0u128;
    let mut rest = bits;
    while rest != 0 {
        let b = rest.trailing_zeros() as usize;
        rest &= rest - 1;
        let Some(taken) = claimed.get_mut(outputs[b] as usize) else {
            return Err(Error::Internal(
                "limit tiles: an output past the level".into(),
            ));
        };
        if !*taken {
            *taken = true;
            mine |= 1 << b;
        }
    }
    Ok(mine)
}

/// Where the tiles write, per level vertex: the limit position and, when asked for, the unit
/// normal. Each vertex is in one tile's slots at most, so no two tiles write one item.
pub(super) struct Out<'a, T, const N: usize> {
    positions: Disjoint<'a, [T; N]>,
    normals: Option<Disjoint<'a, [T; 3]>>,
}

/// Whether the processor has AVX2 (four-lane `f64` vectors) for the kernel: the same products
/// and sums lane by lane (no fused multiply-add), so the values are bitwise those of two lanes.
pub(super) fn wide_vectors() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// A task's working rows for [`Kernel::tile`], channel by channel: a tile's window of data and
/// its rows filtered for the output columns (by the value mask and by the slope mask), output
/// column `i` in lane `i % 4` of vector `i / 4`.
struct Rows<const N: usize> {
    window: [[[f64; WINDOW_ROW]; MAX_DATA]; N],
    by_value: [[[Lanes; MAX_VECTORS]; MAX_DATA]; N],
    by_slope: [[[Lanes; MAX_VECTORS]; MAX_DATA]; N],
}

/// Four output columns: what one AVX2 register holds.
type Lanes = [f64; 4];

/// Items `at..at + 4` of a window row.
#[inline(always)]
fn four(row: &[f64; WINDOW_ROW], at: usize) -> Lanes {
    std::array::from_fn(|l| row[at + l])
}

/// The separable masks of width `K` over the tiles.
struct Kernel<'a, const K: usize> {
    tiles: &'a Tiles,
    value: &'a [f64; K],
    slope: &'a [f64; K],
    /// The bits of the tiles' far column ([`far_column`]).
    far_column: u128,
    /// Whether every id of every window is an item of the data (checked once per call: the
    /// gather then reads them unchecked).
    ids_in_data: bool,
}

impl<const K: usize> Kernel<'_, K> {
    /// Writes the values of the vertices of the tiles `tiles` into `out`: every vertex of
    /// their slots, or an error.
    #[inline(always)]
    fn tiles<T: Scalar, const N: usize, const NEAR: usize, const FAR: usize, const WIDE: bool>(
        &self,
        tiles: std::ops::Range<usize>,
        data: &[[T; N]],
        rows: &mut Rows<N>,
        out: &Out<T, N>,
    ) -> Result<()> {
        // A loop, not a closure: a closure would not take `tiles_avx2`'s target features.
        for tile in tiles {
            match self.tiles.owned[tile] & self.far_column {
                0 => self.tile::<T, N, NEAR, WIDE>(tile, data, rows, out)?,
                _ => self.tile::<T, N, FAR, WIDE>(tile, data, rows, out)?,
            }
        }
        Ok(())
    }

    /// [`Kernel::tiles`] compiled for AVX2.
    ///
    /// # Safety
    /// The processor must have AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn tiles_avx2<T: Scalar, const N: usize, const NEAR: usize, const FAR: usize>(
        &self,
        tiles: std::ops::Range<usize>,
        data: &[[T; N]],
        rows: &mut Rows<N>,
        out: &Out<T, N>,
    ) -> Result<()> {
        self.tiles::<T, N, NEAR, FAR, true>(tiles, data, rows, out)
    }

    /// The window of a tile (`ids`, `d` rows of `d` items) read from `data` into `rows`, in
    /// [`gather_avx2`] when `WIDE` and it applies, else item by item.
    #[inline(always)]
    fn gather<T: Scalar, const N: usize, const WIDE: bool>(
        &self,
        ids: &[u32],
        d: usize,
        data: &[[T; N]],
        rows: &mut Rows<N>,
    ) -> Result<()> {
        // SAFETY: `WIDE` is set by `tiles_avx2` alone, on a processor with AVX2, and
        // `self.ids_in_data` checked that every id of every window is an item of `data`.
        #[cfg(target_arch = "x86_64")]
        if WIDE && self.ids_in_data && unsafe { gather_avx2(ids, d, data, &mut rows.window) } {
            return Ok(());
        }
        for (y, ids) in ids.chunks_exact(d).enumerate() {
            for (x, &id) in ids.iter().enumerate() {
                let item = data.get(id as usize).ok_or_else(|| {
                    Error::Internal("limit tiles: a window item past the data".into())
                })?;
                for (window, &value) in rows.window.iter_mut().zip(item) {
                    window[y][x] = value.to_f64();
                }
            }
        }
        Ok(())
    }

    /// The `d` window rows in `rows` filtered for the output columns by the value mask and,
    /// when `both`, the slope mask: in [`Kernel::rows_avx2`] when `WIDE`, else in `[f64; 4]`
    /// arrays. The value mask is symmetric and the slope mask antisymmetric (zero at an odd
    /// mask's centre): items `k` and `K - 1 - k` are summed and subtracted once for both. The
    /// sums run per vector of four output columns, over the taps in registers (arrays of all
    /// the columns, each sum went through memory: LLVM built the vectors lane by lane).
    #[inline(always)]
    fn filter_rows<const N: usize, const V: usize, const WIDE: bool>(
        &self,
        d: usize,
        rows: &mut Rows<N>,
        both: bool,
    ) {
        #[cfg(target_arch = "x86_64")]
        if WIDE {
            // SAFETY: `WIDE` is set by `tiles_avx2` alone, on a processor with AVX2.
            unsafe {
                match both {
                    true => self.rows_avx2::<N, V, true>(d, rows),
                    false => self.rows_avx2::<N, V, false>(d, rows),
                }
            }
            return;
        }
        let (half, odd) = (K / 2, K % 2 == 1);
        for c in 0..N {
            for y in 0..d {
                let x = &rows.window[c][y];
                for u in 0..V {
                    let at = 4 * u;
                    let (mut v, mut s) = ([0.0f64; 4], [0.0f64; 4]);
                    for k in 0..half {
                        let (p, q) = (four(x, at + k), four(x, at + K - 1 - k));
                        v = mad(v, self.value[k], add(p, q));
                        // Both masks when both are wanted: each item is read once.
                        if both {
                            s = mad(s, self.slope[k], sub(p, q));
                        }
                    }
                    if odd {
                        v = mad(v, self.value[half], four(x, at + half));
                    }
                    rows.by_value[c][y][u] = v;
                    rows.by_slope[c][y][u] = s;
                }
            }
        }
    }

    /// The rows of [`Kernel::tile`]'s window filtered for its output columns, as the portable
    /// loop of [`Kernel::filter_rows`] does (the same products and sums in the same order), in
    /// explicit AVX2 vectors: the portable loop's reversed four-item reads were built by LLVM
    /// with blends, inserts and permutes (a cached limit at degree 9, level 3: the kernel less its gather 60.3M
    /// instructions, 44.9M with these rows).
    ///
    /// # Safety
    /// The processor must have AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn rows_avx2<const N: usize, const V: usize, const BOTH: bool>(
        &self,
        d: usize,
        rows: &mut Rows<N>,
    ) {
        use std::arch::x86_64::*;
        const { assert!(4 * V + K - 1 <= WINDOW_ROW) };
        let (half, odd) = (K / 2, K % 2 == 1);
        let value: [__m256d; K] = std::array::from_fn(|k| _mm256_set1_pd(self.value[k]));
        let slope: [__m256d; K] = std::array::from_fn(|k| _mm256_set1_pd(self.slope[k]));
        let load = |row: &[f64; WINDOW_ROW], at: usize| {
            let four: &[f64; 4] = row[at..at + 4].try_into().unwrap();
            // SAFETY: four `f64`s, read unaligned.
            unsafe { _mm256_loadu_pd(four.as_ptr()) }
        };
        let store = |to: &mut Lanes, v: __m256d| {
            // SAFETY: four `f64`s, written unaligned.
            unsafe { _mm256_storeu_pd(to.as_mut_ptr(), v) }
        };
        for c in 0..N {
            let (window, by_value, by_slope) = (
                &rows.window[c],
                &mut rows.by_value[c],
                &mut rows.by_slope[c],
            );
            for y in 0..d.min(MAX_DATA) {
                let x = &window[y];
                for u in 0..V {
                    let at = 4 * u;
                    let (mut v, mut s) = (_mm256_setzero_pd(), _mm256_setzero_pd());
                    for k in 0..half {
                        let (p, q) = (load(x, at + k), load(x, at + K - 1 - k));
                        v = _mm256_add_pd(v, _mm256_mul_pd(value[k], _mm256_add_pd(p, q)));
                        if BOTH {
                            s = _mm256_add_pd(s, _mm256_mul_pd(slope[k], _mm256_sub_pd(p, q)));
                        }
                    }
                    if odd {
                        v = _mm256_add_pd(v, _mm256_mul_pd(value[half], load(x, at + half)));
                    }
                    store(&mut by_value[y][u], v);
                    store(&mut by_slope[y][u], s);
                }
            }
        }
    }

    /// Writes the values of `tile`'s vertices into `out`: every vertex of its slots, or an
    /// error. Rows first, for all output columns at once (each a sum over `K` window columns), then
    /// per output row the three column sums; the vertices the tile owns are picked from them.
    #[inline(always)]
    fn tile<T: Scalar, const N: usize, const V: usize, const WIDE: bool>(
        &self,
        tile: usize,
        data: &[[T; N]],
        rows: &mut Rows<N>,
        out: &Out<T, N>,
    ) -> Result<()> {
        let (d, side) = (self.tiles.data_side, self.tiles.side);
        let normals = out.normals.as_ref();
        let offsets = &self.tiles.offsets;
        let vertices = (offsets.get(tile..tile + 2))
            .and_then(|o| self.tiles.vertices.get(o[0] as usize..o[1] as usize))
            .ok_or_else(|| Error::Internal("limit tiles: a tile past its slots".into()))?;
        let ids = &self.tiles.ids[tile * d * d..(tile + 1) * d * d];
        let (half, odd) = (K / 2, K % 2 == 1);
        let both = normals.is_some();
        self.gather::<T, N, WIDE>(ids, d, data, rows)?;
        self.filter_rows::<N, V, WIDE>(d, rows, both);
        let owned = self.tiles.owned[tile];
        let row_bits = (1u128 << side) - 1;
        let mut n = 0;
        for j in 0..side {
            // A row's bits fit a `u32` (`side <= MAX_SIDE`): the walk below on `u128` cost
            // a few instructions more a vertex.
            let mine = ((owned >> (j * side)) & row_bits) as u32;
            if mine == 0 {
                continue;
            }
            // The three column sums of output row j, all columns at once.
            let mut position = [[[0.0f64; 4]; V]; N];
            let mut along_i = [[[0.0f64; 4]; V]; N];
            let mut along_j = [[[0.0f64; 4]; V]; N];
            for c in 0..N {
                let (bv, bs) = (&rows.by_value[c], &rows.by_slope[c]);
                for u in 0..V {
                    let (mut p_sum, mut i_sum, mut j_sum) = ([0.0f64; 4], [0.0f64; 4], [0.0f64; 4]);
                    for r in 0..half {
                        let (a, b) = (j + r, j + K - 1 - r);
                        let (p, q) = (bv[a][u], bv[b][u]);
                        p_sum = mad(p_sum, self.value[r], add(p, q));
                        if both {
                            i_sum = mad(i_sum, self.value[r], add(bs[a][u], bs[b][u]));
                            j_sum = mad(j_sum, self.slope[r], sub(p, q));
                        }
                    }
                    if odd {
                        let m = j + half;
                        p_sum = mad(p_sum, self.value[half], bv[m][u]);
                        // Unread without normals; a test of `both` here cost more than the sum.
                        i_sum = mad(i_sum, self.value[half], bs[m][u]);
                    }
                    position[c][u] = p_sum;
                    along_i[c][u] = i_sum;
                    along_j[c][u] = j_sum;
                }
            }
            // Not in a closure: one that LLVM did not inline ran outside `tiles_avx2`'s target
            // features, in two-lane vectors.
            let normal = if normals.is_some() {
                Some(unit_normals::<T, N, V>(&along_i, &along_j))
            } else {
                None
            };
            let mut bits = mine;
            while bits != 0 {
                let i = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let v = *vertices.get(n).ok_or_else(|| {
                    Error::Internal("limit tiles: more vertices than slots".into())
                })? as usize;
                // SAFETY: `v` is below `vertices_end`, which `write_with` checked against both
                // outputs; a vertex is in one slot of one tile at most (`Tiles::build`), and
                // each tile is walked by one task.
                unsafe {
                    out.positions.write(
                        v,
                        std::array::from_fn(|c| T::from_f64(position[c].as_flattened()[i])),
                    );
                    if let (Some(to), Some(normal)) = (normals, &normal) {
                        to.write(
                            v,
                            std::array::from_fn(|c| T::from_f64(normal[c].as_flattened()[i])),
                        );
                    }
                }
                n += 1;
            }
        }
        match n == vertices.len() {
            true => Ok(()),
            false => Err(Error::Internal(
                "limit tiles: fewer vertices than slots".into(),
            )),
        }
    }
}

/// The window of a tile (`ids`, `d` rows of `d` items) read from `data` into `window` as the
/// portable loop of [`Kernel::gather`] does, four items at a time: each item's three channels
/// loaded and widened in one vector, four of them turned into three rows of four (one per
/// channel). The portable loop took 19 instructions an item (a fifth of a cached limit's
/// tiles at degree 9, level 3: 289 items a tile for 64 outputs). False, with nothing read,
/// unless `data` holds three channels of `f32` or `f64`; then the portable loop reads the
/// window.
///
/// # Safety
/// The processor must have AVX2, and every id must be an item of `data`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn gather_avx2<T: Scalar, const N: usize>(
    ids: &[u32],
    d: usize,
    data: &[[T; N]],
    window: &mut [[[f64; WINDOW_ROW]; MAX_DATA]; N],
) -> bool {
    use std::any::TypeId;
    use std::arch::x86_64::*;
    let single = TypeId::of::<T>() == TypeId::of::<f32>();
    let double = TypeId::of::<T>() == TypeId::of::<f64>();
    let [xs, ys, zs] = &mut window[..] else {
        return false;
    };
    if !(single || double) || d == 0 || d > MAX_DATA || ids.len() != d * d {
        return false;
    }
    // The items of a row four at a time: `d` rounded up stays within a window row.
    const { assert!(MAX_DATA.next_multiple_of(4) <= WINDOW_ROW) };
    let base = data.as_ptr();
    // SAFETY: every id is an item of `data` (the caller's promise), so its three channels are
    // there; the masked loads read no fourth.
    let item = |id: u32| unsafe {
        let at = base.add(id as usize) as *const T;
        match single {
            true => _mm256_cvtps_pd(_mm_maskload_ps(
                at as *const f32,
                _mm_setr_epi32(-1, -1, -1, 0),
            )),
            false => _mm256_maskload_pd(at as *const f64, _mm256_setr_epi64x(-1, -1, -1, 0)),
        }
    };
    for (y, row) in ids.chunks_exact(d).enumerate() {
        let (xs, ys, zs) = (&mut xs[y], &mut ys[y], &mut zs[y]);
        for x in (0..d).step_by(4) {
            // Past the row: its first item again (leftovers that no output's sum reads).
            let four: [u32; 4] = match row.get(x..x + 4) {
                Some(&[a, b, c, e]) => [a, b, c, e],
                _ => std::array::from_fn(|l| row.get(x + l).copied().unwrap_or(row[0])),
            };
            let [a, b, c, e] = four.map(item);
            let (ab_even, ab_odd) = (_mm256_unpacklo_pd(a, b), _mm256_unpackhi_pd(a, b));
            let (ce_even, ce_odd) = (_mm256_unpacklo_pd(c, e), _mm256_unpackhi_pd(c, e));
            let to = |row: &mut [f64; WINDOW_ROW], v: __m256d| {
                let four: &mut [f64; 4] = (&mut row[x..x + 4]).try_into().unwrap();
                // SAFETY: four `f64`s, written unaligned.
                unsafe { _mm256_storeu_pd(four.as_mut_ptr(), v) }
            };
            to(xs, _mm256_permute2f128_pd(ab_even, ce_even, 0x20));
            to(ys, _mm256_permute2f128_pd(ab_odd, ce_odd, 0x20));
            to(zs, _mm256_permute2f128_pd(ab_even, ce_even, 0x31));
        }
    }
    true
}

/// The unit normals of a row of output columns from its two tangents' sums (channels 0..3,
/// zero past `N`), each tangent rounded to `T` first (as [`super::rounded`] does for the stencils):
/// glam's `cross(..).normalize_or_zero()` written over the whole row, the same operations in
/// the same order, so that they run lane by lane in vectors with bitwise the same values (a
/// vertex at a time, the cross product and normalisation were a tenth of a cached limit's
/// instructions at degree 3).
#[inline(always)]
fn unit_normals<T: Scalar, const N: usize, const V: usize>(
    along_i: &[[Lanes; V]; N],
    along_j: &[[Lanes; V]; N],
) -> [[Lanes; V]; 3] {
    let channel = |t: &[[Lanes; V]; N], c: usize| match t.get(c) {
        Some(t) => t.map(|lanes| lanes.map(|x| T::from_f64(x).to_f64())),
        None => [[0.0; 4]; V],
    };
    let (ax, ay, az) = (
        channel(along_i, 0),
        channel(along_i, 1),
        channel(along_i, 2),
    );
    let (bx, by, bz) = (
        channel(along_j, 0),
        channel(along_j, 1),
        channel(along_j, 2),
    );
    let mut out = [[[0.0; 4]; V]; 3];
    for u in 0..V {
        let (ax, ay, az, bx, by, bz) = (ax[u], ay[u], az[u], bx[u], by[u], bz[u]);
        let x: Lanes = std::array::from_fn(|l| ay[l] * bz[l] - by[l] * az[l]);
        let y: Lanes = std::array::from_fn(|l| az[l] * bx[l] - bz[l] * ax[l]);
        let z: Lanes = std::array::from_fn(|l| ax[l] * by[l] - bx[l] * ay[l]);
        let rcp: Lanes =
            std::array::from_fn(|l| 1.0 / (x[l] * x[l] + y[l] * y[l] + z[l] * z[l]).sqrt());
        // `rcp.is_finite() && rcp > 0.0` on the bits (positive finite `f64`s are the bits
        // `1..=f64::MAX.to_bits()`), as a mask of the product's bits (zero bits are `0.0`): as
        // float comparisons, LLVM made them a class test of each lane, one by one.
        let keep: [u64; 4] = std::array::from_fn(|l| {
            let above_zero = rcp[l].to_bits().wrapping_sub(1);
            (above_zero < f64::MAX.to_bits()) as u64 * u64::MAX
        });
        for (out, v) in out.iter_mut().zip([x, y, z]) {
            out[u] = std::array::from_fn(|l| f64::from_bits((v[l] * rcp[l]).to_bits() & keep[l]));
        }
    }
    out
}

/// What the walk of a tile reads (see [`Tiles::build`]).
struct Geometry<'a> {
    level: &'a Level,
    twins: &'a [u32],
    marks: &'a [u32],
    t: usize,
    rings: usize,
    primal: bool,
    data_side: usize,
    /// The level the tiles' faces descend from, for the walks through it ([`Above`]).
    above: Option<Above<'a>>,
}

/// The quad level `depth` levels above the tiles' level (the faces the tiles descend from):
/// where the block of its faces around a tile's face is a grid of regular vertices, the tile's
/// cells follow from that block by the children's numbering, without a step of the walk on the
/// tiles' level (the same cells: test `fast_walks_are_the_walks`).
struct Above<'a> {
    /// Its [`Level::twin_corners`].
    twins: Vec<u32>,
    /// Its corners' vertices (ids the tiles' level keeps: `marks` applies to them).
    verts: &'a [u32],
    /// Its faces around the tile's face on each side: enough to hold the tile's cells.
    rings: usize,
    /// The window's cells along a side in runs, one per face of the block they are in: the
    /// face's place in the block, the run's first cell in the window, its first cell in the
    /// face, and its length (the same runs for rows and columns).
    runs: Vec<(usize, usize, usize, usize)>,
    /// Per corner `j` of a face at the lower left of its cell, then per cell `(x, y)` of the
    /// face's `2^depth x 2^depth` descendants (row after row), the cell's descendant index
    /// (`0 .. 4^depth`) times 4 plus its corner at the cell's lower left.
    descent: Vec<u32>,
}

/// For the tests: per tile of `level` (as [`Tiles::build`]'s), asserts that the walk whose
/// cells come from `above` finds what the walk on `level` finds, and, where its cells came from
/// `above`, the same cells. The tiles whose cells came from `above`, and all tiles.
#[cfg(test)]
pub(super) fn walks_agree(
    level: &Level,
    above: &Level,
    twins: &[u32],
    marks: &[u32],
    degree: u32,
    depth: u32,
) -> (usize, usize) {
    let fast = Geometry::new(level, above, twins, marks, degree, depth).unwrap();
    let slow = Geometry {
        above: None,
        ..fast
    };
    let (t, rings) = (fast.t, fast.rings);
    let mut stamps = Stamps::new(marks).unwrap();
    let (tiles, side) = (level.num_faces() >> (2 * depth), t + 2 * rings + 2);
    let mut from_above = 0;
    for g in 0..tiles {
        let anchor = g << (2 * depth);
        let mut cells = [NONE; MAX_CELLS * MAX_CELLS];
        if fast.cells_from_above(anchor, &mut cells) {
            from_above += 1;
            let mut walked = [NONE; MAX_CELLS * MAX_CELLS];
            walk_cells(twins, 4 * anchor as u32, side, rings + 1, &mut walked);
            assert_eq!(cells, walked, "tile {g}: cells");
        }
        let walk = |geometry: &Geometry, stamps: &mut Stamps| {
            let (d, out_side) = (geometry.data_side, t + 1);
            let (mut ids, mut outputs) = (vec![0; d * d], vec![NONE; out_side * out_side]);
            let valid = geometry.walk(anchor, stamps, &mut ids, &mut outputs);
            (ids, valid, outputs)
        };
        let (a, b) = (walk(&fast, &mut stamps), walk(&slow, &mut stamps));
        assert_eq!(a, b, "tile {g}");
    }
    (from_above, tiles)
}

/// The largest side of the block of faces above a tile (`2 Above::rings + 1`: at depth 1 and
/// degree 9, 3 faces on each side).
const MAX_BLOCK: usize = 7;

impl<'a> Above<'a> {
    /// The walks through `level` (all quads, `depth` levels above the tiles' level, at least
    /// one) for masks of `rings` rings.
    fn new(level: &'a Level, depth: u32, rings: usize) -> Result<Above<'a>> {
        let s = 1usize << depth;
        let mut descent = Vec::with_capacity(4 * s * s);
        for j in 0..4u32 {
            for y in 0..s {
                for x in 0..s {
                    // A face whose corner `i` is at position `i + r` of its cell (positions
                    // counterclockwise from the lower left); its child `k` is at its corner
                    // `k`, and the child's corner `i` at the position `k + r + i` of its own
                    // quarter: a child's rotation is its quarter's position.
                    let (mut r, mut index) = ((4 - j) & 3, 0u32);
                    for bit in (0..depth).rev() {
                        let position = match ((x >> bit) & 1, (y >> bit) & 1) {
                            (0, 0) => 0,
                            (1, 0) => 1,
                            (1, 1) => 2,
                            _ => 3,
                        };
                        index = 4 * index + ((position + 4 - r) & 3);
                        r = position;
                    }
                    descent.push(4 * index + ((4 - r) & 3));
                }
            }
        }
        // The window's cell `a` is at `a - n - 1` on the tiles' level (`n` rings), in the
        // block's face `(a - n - 1).div_euclid(s) + r`: within the block when `r s >= n + 1`.
        let n = rings;
        let r = (n + 1).div_ceil(s);
        if 2 * r + 1 > MAX_BLOCK {
            return Err(Error::Internal(
                "limit tiles: a block past its bounds".into(),
            ));
        }
        let mut runs: Vec<(usize, usize, usize, usize)> = Vec::new();
        for a in 0..s + 2 * n + 2 {
            let x = a as isize - n as isize - 1;
            let (face, at) = (
                x.div_euclid(s as isize) + r as isize,
                x.rem_euclid(s as isize),
            );
            match runs.last_mut() {
                Some(run) if run.0 == face as usize => run.3 += 1,
                _ => runs.push((face as usize, a, at as usize, 1)),
            }
        }
        Ok(Above {
            twins: level.twin_corners()?,
            verts: &level.corner_verts,
            rings: r,
            runs,
            descent,
        })
    }
}

/// From a cell's corner at its lower left, that of the cell on its right across the twin
/// corners `twins`.
#[inline(always)]
fn right(twins: &[u32], c: u32) -> Option<u32> {
    Some(quad_next(twin(twins, quad_next(c as usize) as u32)? as usize) as u32)
}

/// The twin corner of `c`, if it has one.
#[inline(always)]
fn twin(twins: &[u32], c: u32) -> Option<u32> {
    let o = *twins.get(c as usize)?;
    (o != NONE).then_some(o)
}

/// The cells of a `side x side` square of quads (`cells[b * side + a]`, each its corner at the
/// lower left, `NONE` where the walk did not reach) walked from `first` at `(origin, origin)`:
/// along its row both ways, then up and down each column.
fn walk_cells(twins: &[u32], first: u32, side: usize, origin: usize, cells: &mut [u32]) {
    let left = |c: u32| Some(quad_prev(twin(twins, quad_prev(c as usize) as u32)? as usize) as u32);
    let up = |c: u32| twin(twins, c ^ 2);
    let down = |c: u32| Some(twin(twins, c)? ^ 2);
    // From `from`, `step` as far as it goes, each cell reached written at the next place
    // (generic, not `dyn`: the steps inline into the walk).
    fn follow(
        cells: &mut [u32],
        from: u32,
        step: impl Fn(u32) -> Option<u32>,
        places: impl Iterator<Item = usize>,
    ) {
        let mut c = from;
        for at in places {
            let Some(next) = step(c) else { break };
            c = next;
            cells[at] = c;
        }
    }
    let cell = |a: usize, b: usize| b * side + a;
    cells[cell(origin, origin)] = first;
    let row = (origin + 1..side).map(|a| cell(a, origin));
    follow(cells, first, |c| right(twins, c), row);
    follow(
        cells,
        first,
        left,
        (0..origin).rev().map(|a| cell(a, origin)),
    );
    for a in 0..side {
        let base = cells[cell(a, origin)];
        if base != NONE {
            follow(cells, base, up, (origin + 1..side).map(|b| cell(a, b)));
            follow(cells, base, down, (0..origin).rev().map(|b| cell(a, b)));
        }
    }
}

impl<'a> Geometry<'a> {
    /// What the walks of [`Tiles::build`]'s tiles read (its arguments).
    fn new(
        level: &'a Level,
        above: &'a Level,
        twins: &'a [u32],
        marks: &'a [u32],
        degree: u32,
        depth: u32,
    ) -> Result<Geometry<'a>> {
        let rings = neighbourhood_size(degree);
        let t = 1usize << depth;
        // An output column's items start at its own column: the window reaches `width - 1`
        // more than the `t + 1` outputs.
        let width = knot_mask(degree, cardinal_bspline).len();
        Ok(Geometry {
            level,
            twins,
            marks,
            t,
            rings,
            primal: degree % 2 == 1,
            data_side: t + width,
            above: match depth {
                0 => None,
                _ => Some(Above::new(above, depth, rings)?),
            },
        })
    }

    /// The cells of the window of the tile whose first face is `anchor` (see
    /// [`Geometry::walk`]) from the block of faces around the face above it, if that block is
    /// a grid of regular vertices (each vertex inside it regular, its four cells meeting as a
    /// grid's): then the walk on the tiles' level finds the same cells, and every vertex
    /// inside the block meets its cells as a grid's.
    fn cells_from_above(&self, anchor: usize, cells: &mut [u32]) -> bool {
        let Some(above) = &self.above else {
            return false;
        };
        let (s, n) = (self.t, self.rings);
        let depth = s.trailing_zeros();
        let (r, twins) = (above.rings, &above.twins[..]);
        let bs = 2 * r + 1;
        let mut block = [NONE; MAX_BLOCK * MAX_BLOCK];
        let block = &mut block[..bs * bs];
        walk_cells(twins, 4 * (anchor >> (2 * depth)) as u32, bs, r, block);
        if block.contains(&NONE) {
            return false;
        }
        for q in 1..bs {
            for p in 1..bs {
                let [below_left, below, left_of, own] = [
                    block[(q - 1) * bs + p - 1],
                    block[(q - 1) * bs + p],
                    block[q * bs + p - 1],
                    block[q * bs + p],
                ];
                let v = above.verts.get(own as usize).copied().unwrap_or(NONE);
                let regular = self.marks.get(v as usize) == Some(&0)
                    && right(twins, below_left) == Some(below)
                    && right(twins, left_of) == Some(own);
                if !regular {
                    return false;
                }
            }
        }
        // The window's cells, a rectangle per face of the block: the face's first descendant
        // plus the descent of each cell (rows of consecutive items).
        let (side, shift) = (s + 2 * n + 2, 2 * depth as usize + 2);
        for &(q, b0, y0, rows) in &above.runs {
            for &(p, a0, x0, columns) in &above.runs {
                let c = block[q * bs + p] as usize;
                let first = ((c >> 2) << shift) as u32;
                let descent = &above.descent[(c & 3) * s * s..][..s * s];
                for y in 0..rows {
                    let to = &mut cells[(b0 + y) * side + a0..][..columns];
                    let from = &descent[(y0 + y) * s + x0..][..columns];
                    for (cell, &own) in to.iter_mut().zip(from) {
                        *cell = first + own;
                    }
                }
            }
        }
        true
    }

    /// The walk of the tile whose first face is `anchor`: the cells of its window from the
    /// anchor's corner 0 (cell `(0, 0)`), along row 0 both ways, then up and down each column.
    /// A vertex is good when it is regular and its four cells meet around it as a grid's do;
    /// an output vertex is valid when every vertex within `N` rings of it is good and the good
    /// vertices of the window are all different. Writes the window's data ids (`ids`, its
    /// `data_side^2` items row after row, 0 where no output reads one) and each output's level
    /// vertex (`outputs`, `(t + 1)^2`); returns the valid outputs (bit `(t + 1) j + i` for the
    /// output at column `i`, row `j`).
    fn walk(
        &self,
        anchor: usize,
        stamps: &mut Stamps,
        ids: &mut [u32],
        outputs: &mut [u32],
    ) -> u128 {
        let (t, n, d) = (self.t, self.rings, self.data_side);
        // Cells (a, b) for a, b in -n-1 ..= t+n, stored at (b + n + 1) side + a + n + 1.
        let side = t + 2 * n + 2;
        let mut cells = [NONE; MAX_CELLS * MAX_CELLS];
        // From the faces above when they are a grid: then every vertex inside meets its cells
        // as a grid's, and no step is checked.
        let grid = self.cells_from_above(anchor, &mut cells);
        if !grid {
            walk_cells(self.twins, 4 * anchor as u32, side, n + 1, &mut cells);
        }
        // Vertices (i, j) for i, j in -n ..= t+n, at (i + n, j + n): the corner 0 of cell
        // (i, j), good when the cells to its left, below and diagonally meet it as a grid's.
        // Walked a row of cells and the row above at a time (no index checked per vertex).
        let (verts, marks, twins) = (&self.level.corner_verts, self.marks, self.twins);
        let vside = t + 2 * n + 1;
        let mut good = [false; MAX_DATA * MAX_DATA];
        let mut vertex = [NONE; MAX_DATA * MAX_DATA];
        let rows = cells[..side * side].chunks_exact(side);
        let pairs = rows.clone().zip(rows.skip(1));
        let vertex_rows = vertex
            .chunks_exact_mut(vside)
            .zip(good.chunks_exact_mut(vside));
        let mut all_good = true;
        for ((vertex, good), (lower, upper)) in vertex_rows.zip(pairs) {
            let corners = lower.windows(2).zip(upper.windows(2));
            for ((v, g), (lower, upper)) in vertex.iter_mut().zip(good.iter_mut()).zip(corners) {
                let [below_left, below, left_of, own] = [lower[0], lower[1], upper[0], upper[1]];
                // From above, every cell is there and meets its neighbours as a grid's.
                if !grid && [below_left, below, left_of, own].contains(&NONE) {
                    all_good = false;
                    continue;
                }
                *v = verts[own as usize];
                *g = marks[*v as usize] == 0
                    && (grid
                        || right(twins, below_left) == Some(below)
                            && right(twins, left_of) == Some(own));
                all_good &= *g;
            }
        }
        // All good vertices different (the window is a disc), else no output: good vertices
        // are regular, so a stamp refused is one met before (a sort of the window's vertices
        // cost 5 % of a first limit call at degree 3).
        stamps.start();
        let window = vertex[..vside * vside].iter().zip(&good[..vside * vside]);
        let distinct = window.filter(|(_, &g)| g).all(|(&v, _)| stamps.insert(v));
        let out_side = t + 1;
        for (j, row) in outputs
            .chunks_exact_mut(out_side)
            .take(out_side)
            .enumerate()
        {
            row.copy_from_slice(&vertex[(j + n) * vside + n..][..out_side]);
        }
        // Bad vertices counted over each box of N rings by prefix sums (most windows have none:
        // then every output is valid).
        let valid = match (distinct, all_good) {
            (false, _) => 0,
            (true, true) => (1u128 << (out_side * out_side)) - 1,
            (true, false) => {
                let ps = vside + 1;
                let mut bad = [0u16; (MAX_DATA + 1) * (MAX_DATA + 1)];
                for j in 0..vside {
                    for i in 0..vside {
                        bad[(j + 1) * ps + i + 1] = bad[j * ps + i + 1] + bad[(j + 1) * ps + i]
                            - bad[j * ps + i]
                            + u16::from(!good[j * vside + i]);
                    }
                }
                let mut valid = 0u128;
                for j in 0..out_side {
                    for i in 0..out_side {
                        // The box of output (i, j) is vertices i ..= i + 2n (shifted by n).
                        let (x0, y0, x1, y1) = (i, j, i + 2 * n + 1, j + 2 * n + 1);
                        if bad[y1 * ps + x1] + bad[y0 * ps + x0]
                            == bad[y0 * ps + x1] + bad[y1 * ps + x0]
                        {
                            valid |= 1 << (j * out_side + i);
                        }
                    }
                }
                valid
            }
        };
        // The data the outputs read: vertices -n ..= t+n (odd degrees) or the faces of cells
        // -n ..= t+n-1 (even); 0 where there is none.
        for (y, row) in ids.chunks_exact_mut(d).take(d).enumerate() {
            let from = match self.primal {
                true => &vertex[y * vside..][..d],
                false => &cells[(y + 1) * side + 1..][..d],
            };
            let shift = if self.primal { 0 } else { 2 };
            for (id, &x) in row.iter_mut().zip(from) {
                *id = if x == NONE { 0 } else { x >> shift };
            }
        }
        valid
    }
}
