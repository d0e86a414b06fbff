//! The whole step of degree 3 or 5 where the mesh is a grid, primal in and primal out: the fine
//! vertices straight from the coarse ones, with no children in between; the same sums for the
//! drawing points of a step of degree 2 or 4 (dual in, primal out); and degree 3's for the
//! smooth points of a classic Catmull-Clark step on a quad level ([`Fused::classic`]).
//!
//! A step of odd degree n is replication and n averages; on primal input the regular windows
//! ([`super::regular`]) make the children (n - 1 averages: at degree 3 `(9, 3, 3, 1) / 16` of
//! their parent's corners) and the last average (dual -> primal) takes each fine vertex as the
//! mean of the children around it. Where a fine vertex has four children around it and the
//! kernel makes all four, that mean is a fixed sum of the coarse vertices (the B-spline's
//! masks). At degree 3: an old vertex `(36 v + 6 E + D) / 64` (`E` its four edge neighbours, `D`
//! its four diagonal ones), an edge point `(6 A + S) / 16` (`A` its edge's ends, `S` the four
//! other corners of its two faces), a face point the mean of its four corners. At degree 5 the
//! tensor products of `(3, 10, 3) / 16` (at a vertex) and `(1, 15, 15, 1) / 32` (at a midpoint):
//! an old vertex `(100 v + 30 E + 9 D) / 256`, an edge point reaching one vertex further along
//! its line on either side, a face point the sixteen vertices of its 4 x 4 net. Each coarse face
//! writes the points of its closure that it owns (its face point; the edge point of an edge
//! whose smaller corner is its; the old vertex of a grid vertex whose first corner in the
//! level's vertex table is its) from a 4 x 4 net of coarse vertices around it (walked once per
//! plan over the regular windows' corner tables, four corners at once in vectors), and the last
//! average makes only the other fine vertices, from the children the kernel and the passes still
//! make for them.
//!
//! The sums pair each point with its mirror image (`E` as (left + right) + (below + above), `D`
//! as the two diagonals' pairs, `S` as the two sides' pairs; degree 5's rings of eight as pairs
//! through the point, grouped by the orbits of its quarter turns) and add pairs in the same way
//! whichever face's frame they are read in, so a point's bits do not depend on which face owns
//! it: a partial level (limits, adaptive) that makes a point from another face, or in a face of
//! another rotation, gets the same bits as the full level, and the decision (four kernel children
//! around the point) is the same on both wherever the point is exact.
//!
//! Drawing points. An even degree's step leaves dual data (per fine face), and its drawing mesh
//! is one more dual -> primal average. On a grid, one more average of dual input gives the 1-D
//! masks of the next odd degree with vertex and midpoint swapped (degree 4: `(1, 15, 15, 1) /
//! 32` at a coarse vertex, `(3, 10, 3) / 16` at a face centre), so the drawing points are that
//! degree's sums over the dual grid: its vertices the coarse faces, its faces the coarse
//! vertices, each with a net of the sixteen coarse faces around it (walked from the vertex's
//! four corners, in vectors where the processor has AVX2). A coarse vertex owns its own point,
//! the edge points of the edges whose first corner is its, the face points of the faces whose
//! corner 0 is its ([`Fused::drawing`], in [`dual`]). A plan's last step takes these windows
//! when the output is the drawing mesh ([`super::regular::Windows::drawn`]: the kernel and the
//! zone then make only the children the other points read), and the adaptive levels make the
//! same points with the same sums from their coarse data ([`super::LevelData::drawing_points`]),
//! so that their bits are the uniform ones.
//!
//! Measured (2026-12-06, callgrind driver, 3,840-quad sphere, level 3, one thread): a cached
//! evaluation of averaging 3 17.08M -> 9.77M instructions, a new plan and its evaluation 55.87M
//! -> 81.82M (the nets and owners, made once per plan), then 71.84M with the owners decided point
//! by point and the nets walked in vectors ([`Owners::of`], [`nets`]). Degree 5 (2026-12-07,
//! same driver): a cached evaluation of averaging 5 24.44M -> 14.29M, a new plan 83.63M ->
//! 92.02M; degree 9 the same way did not pay (its masks' 25 to 36 taps a point cost what the
//! kernel saves); `docs/research/fused-primal-kernel.md`. Drawing points (2026-12-07, same
//! driver): a cached evaluation of averaging 4 21.41M -> 14.66M, of averaging 2 19.57M ->
//! 11.90M; a new plan of averaging 4 and its evaluation 77.62M -> 103.17M (the dual grid: its
//! walk in parallel, about 220 instructions a coarse vertex, and the edges' and faces' owners in
//! serial passes, 27.0M in all at level 3).
use std::mem::MaybeUninit;

use rayon::prelude::*;

use super::regular::{after, Bits, Tables as CornerTables};
use crate::error::{Error, Result};
use crate::memory;
use crate::parallel::{Disjoint, CHUNK};
use crate::scalar::{add, scale, Scalar, Value};
use crate::topology::{Level, NONE};

mod dual;

use dual::walked_dual;

/// Ids of a face's net: the sixteen grid vertices `(x, y)` of its frame, `x` and `y` in
/// `-1..=2` (its corner 0 at `(0, 0)`, corner `k` at [`CORNERS`]`[k]`), stored in the order its
/// walk names them: `4 j + k` is the `j`-th of corner `k`'s four ([`walked`]), so that a walk
/// in vectors of four corners stores each of its four vectors whole.
pub(super) const NET: usize = 16;

/// Where a face's corners are in its frame.
const CORNERS: [(i32, i32); 4] = [(0, 0), (1, 0), (1, 1), (0, 1)];

/// The frame point of the `j`-th grid vertex the walk names from corner `k`: the corner's own
/// (`j` = 0), the two across edge `k` (from corner `k` to corner `k + 1`; at corner `k`, then
/// at corner `k + 1`) and the far corner of the diagonal cell at corner `k + 1` (across edge
/// `k`, then across the next edge of that face). Over the four corners, the sixteen of the net.
const fn walked(k: usize, j: usize) -> (i32, i32) {
    let (ax, ay) = CORNERS[k];
    let (bx, by) = CORNERS[(k + 1) % 4];
    let (cx, cy) = CORNERS[(k + 2) % 4];
    // The unit steps across edge k and across edge k + 1.
    let (ox, oy) = (by - ay, ax - bx);
    let (px, py) = (cy - by, bx - cx);
    match j {
        0 => (ax, ay),
        1 => (ax + ox, ay + oy),
        2 => (bx + ox, by + oy),
        _ => (bx + ox + px, by + oy + py),
    }
}

/// The net index of frame point `(x, y)` (`x` and `y` in `-1..=2`) in the order of the
/// primal walk ([`walked`]) or of the dual one ([`dual::walked_dual`]).
const fn at_in(x: i32, y: i32, dual: bool) -> u8 {
    let mut i = 0;
    while i < NET {
        let (u, v) = match dual {
            true => walked_dual(i % 4, i / 4),
            false => walked(i % 4, i / 4),
        };
        if u == x && v == y {
            return i as u8;
        }
        i += 1;
    }
    panic!("a point outside the net")
}

/// The net index of frame point `(x, y)` in the order of the primal walk.
#[cfg(test)]
const fn at(x: i32, y: i32) -> u8 {
    at_in(x, y, false)
}

/// The net indices the sums read, in one order of a net's ids (the primal or the dual walk's).
struct Layout {
    /// Per corner `k`: the net indices of its vertex, its edge neighbours as two mirrored pairs
    /// (left, right, below, above) and its diagonal neighbours as two mirrored pairs.
    old: [[u8; 9]; 4],
    /// Per edge `k` (from corner `k`, at `a`, to corner `k + 1`, at `b`; `o` the step across
    /// it, away from the face): the net indices of its two ends, then of the two points beside
    /// them across it (`a + o`, `b + o`), then on the face's side (the face's corners `k + 3`
    /// and `k + 2`).
    edge: [[u8; 6]; 4],
    /// Degree 5, per edge `k` (`u = b - a`): the net indices of the points on its line beyond
    /// its ends (`a - u`, `b + u`), then those beside them across it (`a - u + o`, `b + u +
    /// o`) and on the face's side (`a - u - o`, `b + u - o`): mirrored pairs, as `edge`'s.
    edge_outer: [[u8; 6]; 4],
    /// Degree 5: the net indices of the eight points beside the face's edges (the ring outside
    /// its corners, `(-1, 0)` and so on), as pairs mirrored through the face's centre, the
    /// first two pairs one orbit of its quarter turns and the last two the other, so that the
    /// sum is the same in every frame of the face.
    ring: [u8; 8],
    /// Degree 5: the net indices of the four far corners, as `old`'s face corners: pairs
    /// through the face's centre.
    far: [u8; 4],
}

/// The [`Layout`] of the primal walk's order (`dual` false) or the dual one's.
const fn layout(dual: bool) -> Layout {
    let mut old = [[0; 9]; 4];
    let mut edge = [[0; 6]; 4];
    let mut edge_outer = [[0; 6]; 4];
    let mut k = 0;
    while k < 4 {
        let (x, y) = CORNERS[k];
        old[k] = [
            at_in(x, y, dual),
            at_in(x - 1, y, dual),
            at_in(x + 1, y, dual),
            at_in(x, y - 1, dual),
            at_in(x, y + 1, dual),
            at_in(x - 1, y - 1, dual),
            at_in(x + 1, y + 1, dual),
            at_in(x + 1, y - 1, dual),
            at_in(x - 1, y + 1, dual),
        ];
        let (ax, ay) = CORNERS[k];
        let (bx, by) = CORNERS[(k + 1) % 4];
        let (ux, uy) = (bx - ax, by - ay);
        let (ox, oy) = (by - ay, ax - bx);
        edge[k] = [
            at_in(ax, ay, dual),
            at_in(bx, by, dual),
            at_in(ax + ox, ay + oy, dual),
            at_in(bx + ox, by + oy, dual),
            at_in(ax - ox, ay - oy, dual),
            at_in(bx - ox, by - oy, dual),
        ];
        edge_outer[k] = [
            at_in(ax - ux, ay - uy, dual),
            at_in(bx + ux, by + uy, dual),
            at_in(ax - ux + ox, ay - uy + oy, dual),
            at_in(bx + ux + ox, by + uy + oy, dual),
            at_in(ax - ux - ox, ay - uy - oy, dual),
            at_in(bx + ux - ox, by + uy - oy, dual),
        ];
        k += 1;
    }
    Layout {
        old,
        edge,
        edge_outer,
        ring: [
            at_in(-1, 0, dual),
            at_in(2, 1, dual),
            at_in(1, -1, dual),
            at_in(0, 2, dual),
            at_in(-1, 1, dual),
            at_in(2, 0, dual),
            at_in(0, -1, dual),
            at_in(1, 2, dual),
        ],
        far: [
            at_in(-1, -1, dual),
            at_in(2, 2, dual),
            at_in(2, -1, dual),
            at_in(-1, 2, dual),
        ],
    }
}

/// The layouts of the primal walk's nets and of the dual one's, by `dual as usize`.
const LAYOUTS: [Layout; 2] = [layout(false), layout(true)];

/// Bit of [`Fused::owned`] for the old vertex at corner `k`; `EDGE_BIT << k` for the edge
/// point of edge `k`, [`FACE_BIT`] for the face point.
const EDGE_BIT: u16 = 1 << 4;
const FACE_BIT: u16 = 1 << 8;

/// The fused last average of a step of degree 3 or 5 on primal input, or the fused drawing
/// step of a step of degree 2 or 4 on dual input (module documentation).
#[derive(Debug)]
pub(super) struct Fused {
    /// The degree of the sums: 3 or 5 (the step's degree, or one more for a drawing step).
    degree: u32,
    /// Per cell (coarse face, or coarse vertex when `dual`), the fine vertices of its closure
    /// that it writes: bit `k` the old vertex at its corner `k`, bit `4 + k` the edge point of
    /// its edge `k`, bit 8 its face point (in the dual grid: the face point of the coarse face
    /// at its corner `k`, the edge point of the coarse edge between its corners `k` and `k +
    /// 1`, the coarse vertex's own point).
    owned: Vec<u16>,
    /// Per cell, [`NET`] coarse vertices (or faces when `dual`; read only for cells that own a
    /// point).
    nets: Vec<u32>,
    /// When `dual`, per coarse vertex, its four corners in the order of its dual face's corners
    /// (each in the face across the previous one's outgoing edge), or four zeros for a vertex
    /// that cannot be inside a grid; empty otherwise.
    cycles: Vec<u32>,
    /// The fine vertices the fused sums do not make, increasing: the last average makes them
    /// from the children.
    rest: Vec<u32>,
    /// The level's vertices, edges and faces when the points were made (the nets' ids are
    /// below the first; [`Owners::of`] checked the id of every owned point).
    ids: [usize; 3],
    /// Whether the fused points and `rest` are every fine vertex, each once: `rest` is what
    /// the owners leave (not so for points made for some items).
    whole: bool,
}

/// The sums of the fused points on a value of `N` channels or a vector register holding one:
/// the same operations lane by lane, so every path gives the same bits.
pub(super) trait Sums: Copy {
    /// A weight.
    type Weight: Copy;
    /// `self + other`.
    fn plus(self, other: Self) -> Self;
    /// `self * w`.
    fn times(self, w: Self::Weight) -> Self;
}

impl<T: Scalar, const N: usize> Sums for Value<T, N> {
    type Weight = T;
    #[inline(always)]
    fn plus(self, other: Self) -> Self {
        add(self, other)
    }
    #[inline(always)]
    fn times(self, w: T) -> Self {
        scale(self, w)
    }
}

/// The weights of the sums, exact in either scalar type: degree 3's `(1, 6, 1) / 8` and `(1, 1) /
/// 2` in each direction, degree 5's `(3, 10, 3) / 16` and `(1, 15, 15, 1) / 32`, as products.
#[derive(Clone, Copy)]
pub(super) struct Weights<W> {
    w36: W,
    w6: W,
    w64: W,
    w16: W,
    w4: W,
    /// Degree 5: an old vertex's 100, 30, 9 and 1/256.
    w100: W,
    w30: W,
    w9: W,
    w256: W,
    /// Degree 5: an edge point's 150, 45, 10, 3 and 1/512.
    w150: W,
    w45: W,
    w10: W,
    w3: W,
    w512: W,
    /// Degree 5: a face point's 225, 15 and 1/1024.
    w225: W,
    w15: W,
    w1024: W,
}

impl<W: Copy> Weights<W> {
    /// The weights from a conversion of f64.
    pub(super) fn new(of: impl Fn(f64) -> W) -> Self {
        Weights {
            w36: of(36.0),
            w6: of(6.0),
            w64: of(1.0 / 64.0),
            w16: of(1.0 / 16.0),
            w4: of(0.25),
            w100: of(100.0),
            w30: of(30.0),
            w9: of(9.0),
            w256: of(1.0 / 256.0),
            w150: of(150.0),
            w45: of(45.0),
            w10: of(10.0),
            w3: of(3.0),
            w512: of(1.0 / 512.0),
            w225: of(225.0),
            w15: of(15.0),
            w1024: of(1.0 / 1024.0),
        }
    }
}

/// Calls `write(bit, value)` for each point of `owned` (bits of [`Fused::owned`]) from the net
/// `p` of its cell, in the order of the dual walk (`DUAL`) or the primal one, with the masks
/// of `DEGREE` (3 or 5).
#[inline(always)]
pub(super) fn closure_points<S: Sums, const DEGREE: u32, const DUAL: bool>(
    owned: u16,
    p: &[S; NET],
    w: Weights<S::Weight>,
    mut write: impl FnMut(u16, S),
) {
    let at = |i: u8| p[i as usize];
    let pair = |a: u8, b: u8| at(a).plus(at(b));
    let layout = &LAYOUTS[DUAL as usize];
    for (k, t) in layout.old.iter().enumerate() {
        if owned & (1 << k) != 0 {
            let value = match DEGREE {
                3 => cubic_vertex(at, t, w),
                _ => {
                    let edges = pair(t[1], t[2]).plus(pair(t[3], t[4]));
                    let diagonals = pair(t[5], t[6]).plus(pair(t[7], t[8]));
                    (at(t[0]).times(w.w100))
                        .plus(edges.times(w.w30))
                        .plus(diagonals.times(w.w9))
                        .times(w.w256)
                }
            };
            write(1 << k, value);
        }
    }
    for (k, t) in layout.edge.iter().enumerate() {
        if owned & (EDGE_BIT << k) != 0 {
            let value = match DEGREE {
                3 => cubic_edge(at, t, w),
                _ => {
                    let sides = pair(t[2], t[3]).plus(pair(t[4], t[5]));
                    let o = &layout.edge_outer[k];
                    let outer_sides = pair(o[2], o[3]).plus(pair(o[4], o[5]));
                    let ends = (pair(t[0], t[1]).times(w.w150)).plus(sides.times(w.w45));
                    let outer = (pair(o[0], o[1]).times(w.w10)).plus(outer_sides.times(w.w3));
                    ends.plus(outer).times(w.w512)
                }
            };
            write(EDGE_BIT << k, value);
        }
    }
    if owned & FACE_BIT != 0 {
        let corners = layout.old.map(|t| t[0]);
        let value = match DEGREE {
            3 => cubic_face(at, &corners, w),
            _ => {
                let [c0, c1, c2, c3] = corners;
                let corners = pair(c0, c2).plus(pair(c1, c3));
                let [a, b, c, d, e, f, g, h] = layout.ring;
                let ring = (pair(a, b).plus(pair(c, d))).plus(pair(e, f).plus(pair(g, h)));
                let [i, j, k, l] = layout.far;
                let far = pair(i, j).plus(pair(k, l));
                (corners.times(w.w225))
                    .plus(ring.times(w.w15))
                    .plus(far)
                    .times(w.w1024)
            }
        };
        write(FACE_BIT, value);
    }
}

/// Degree 3's old vertex `(36 v + 6 E + D) / 64` from the points `p(t[i])`: `t[0]` the vertex,
/// `t[1..5]` its four edge neighbours as the two pairs opposite through it, `t[5..9]` its
/// diagonal ones likewise. The cubic B-spline's mask, which is also classic Catmull-Clark's
/// smooth vertex point at valence 4 among quads ([`super::catmark`] makes it with this
/// function where no face owns it): one order of additions for every path and frame (each
/// pair, and the two pairs, commute), so the point's bits are the same on all.
#[inline(always)]
pub(super) fn cubic_vertex<S: Sums>(p: impl Fn(u8) -> S, t: &[u8; 9], w: Weights<S::Weight>) -> S {
    let pair = |a: u8, b: u8| p(a).plus(p(b));
    let edges = pair(t[1], t[2]).plus(pair(t[3], t[4]));
    let diagonals = pair(t[5], t[6]).plus(pair(t[7], t[8]));
    (p(t[0]).times(w.w36))
        .plus(edges.times(w.w6))
        .plus(diagonals)
        .times(w.w64)
}

/// Degree 3's edge point `(6 A + S) / 16` from the points `p(t[i])`: `t[0..2]` the edge's
/// ends, `t[2..4]` and `t[4..6]` the other two corners of each of its quads. The B-spline's
/// mask and classic Catmull-Clark's smooth edge point between two quads, as [`cubic_vertex`].
#[inline(always)]
pub(super) fn cubic_edge<S: Sums>(p: impl Fn(u8) -> S, t: &[u8; 6], w: Weights<S::Weight>) -> S {
    let pair = |a: u8, b: u8| p(a).plus(p(b));
    let sides = pair(t[2], t[3]).plus(pair(t[4], t[5]));
    (pair(t[0], t[1]).times(w.w6)).plus(sides).times(w.w16)
}

/// Degree 3's face point of a quad, the mean of its corners `p(t[k])` in order around it: every
/// scheme's face point of a quad at degree 3, as [`cubic_vertex`].
#[inline(always)]
pub(super) fn cubic_face<S: Sums>(p: impl Fn(u8) -> S, t: &[u8; 4], w: Weights<S::Weight>) -> S {
    let pair = |a: u8, b: u8| p(a).plus(p(b));
    pair(t[0], t[2]).plus(pair(t[1], t[3])).times(w.w4)
}

impl Fused {
    /// The fused points of the step of `degree` (3 or 5) from `coarse` whose kernel writes the
    /// children of `masks` (for two averages on primal input, degree 3's, all four of a clean
    /// face and none of another), with the level's corner tables as the regular windows' walk
    /// reads them (`corners`: each corner's twin, across its outgoing edge and at its end, and
    /// vertex, with a dead face after the level's faces for a missing twin; whether each vertex
    /// can be inside a grid); `None` when no point is fused.
    pub(super) fn new(
        coarse: &Level,
        degree: u32,
        masks: &[u8],
        corners: CornerTables,
    ) -> Result<Option<Fused>> {
        let ids = ClosureIds::of(coarse)?;
        let [_, _, nf] = ids.sizes();
        if masks.len() != nf || !matches!(degree, 3 | 5) {
            return Err(Error::Internal(
                "fused points: masks not the level's, or no sums for the degree".into(),
            ));
        }
        // Two averages of primal input read a face's own corners alone: the kernel makes all
        // four children of a clean face (no curve vertex born from it) and none of another.
        debug_assert!(
            degree != 3
                || (0..nf).all(|f| masks[f] == if corners.clean(4 * f as u32) { 0xf } else { 0 })
        );
        // Whether the kernel makes the child at corner `c` (below `4 nf`).
        let child = |c: u32| masks[(c >> 2) as usize] & (1 << (c & 3)) != 0;
        let faces = memory::collect(masks.iter().map(|&m| match m {
            0xf => FACE_BIT,
            _ => 0,
        }))?;
        let owners = Owners::of(coarse, ids, corners, faces, child, |_| true, |_| true)?;
        Fused::of_owners(ids, owners, corners, degree)
    }

    /// The fused points of a classic Catmull-Clark step from the quad level `coarse`, with its
    /// corner tables as for [`Fused::new`]: every face point, the edge point of every edge
    /// between two quads for which `smooth_edge` holds and the vertex point of every vertex
    /// inside a grid for which `smooth_vertex` holds, by degree 3's sums, which are the classic
    /// masks of these points ([`super::catmark`]); `None` when no point is fused (a level
    /// without faces: every face point is).
    pub(super) fn classic(
        coarse: &Level,
        corners: CornerTables,
        smooth_vertex: impl Fn(usize) -> bool,
        smooth_edge: impl Fn(usize) -> bool,
    ) -> Result<Option<Fused>> {
        let ids = ClosureIds::of(coarse)?;
        // No children: every face's point is its corners' mean, so each face owns its own.
        let faces = memory::filled(ids.sizes()[2], FACE_BIT)?;
        let owners = Owners::of(
            coarse,
            ids,
            corners,
            faces,
            |_| true,
            smooth_vertex,
            smooth_edge,
        )?;
        Fused::of_owners(ids, owners, corners, 3)
    }

    /// The points of `owners` with the nets of the level's faces; `None` when no point is
    /// fused.
    fn of_owners(
        ids: ClosureIds,
        owners: Owners,
        corners: CornerTables,
        degree: u32,
    ) -> Result<Option<Fused>> {
        let [nv, ne, nf] = ids.sizes();
        if owners.rest.len() == nv + ne + nf {
            return Ok(None);
        }
        let nets = nets(corners, nf, true)?;
        Ok(Some(Fused {
            degree,
            owned: owners.owned,
            nets,
            cycles: Vec::new(),
            rest: owners.rest,
            ids: [nv, ne, nf],
            whole: true,
        }))
    }

    /// The same points restricted to the fine vertices `needed` (increasing) of a partial
    /// level: a face writes only the needed points it owns, and the last average makes the
    /// needed others.
    pub(super) fn for_items(self, coarse: &Level, needed: &[u32]) -> Result<Fused> {
        let ids = ClosureIds::of(coarse)?.with_cycles_of_fused(&self.cycles)?;
        if self.owned.len() != self.cells(coarse) {
            return Err(Error::Internal(
                "fused points: made for another level".into(),
            ));
        }
        let n = ids.nv + ids.ne + coarse.num_faces();
        let mut wanted = Bits::new(n)?;
        for &w in needed {
            wanted.set(w as usize);
        }
        let owned = memory::collect(self.owned.iter().enumerate().map(|(f, &bits)| {
            let mut kept = 0;
            let mut left = bits;
            while left != 0 {
                let bit = left & left.wrapping_neg();
                if wanted.contains(ids.fine_vertex(bit, f)) {
                    kept |= bit;
                }
                left &= !bit;
            }
            kept
        }))?;
        let rest = memory::collect(
            self.rest
                .iter()
                .copied()
                .filter(|&w| wanted.contains(w as usize)),
        )?;
        Ok(Fused {
            degree: self.degree,
            owned,
            nets: self.nets,
            cycles: self.cycles,
            rest,
            ids: self.ids,
            whole: false,
        })
    }

    /// The cells of `coarse` the points are owned by: its faces, or its vertices when `dual`.
    fn cells(&self, coarse: &Level) -> usize {
        match self.dual() {
            true => coarse.num_vertices,
            false => coarse.num_faces(),
        }
    }

    /// Whether the fused points and [`Fused::rest`] are every fine vertex, each once.
    pub(super) fn whole(&self) -> bool {
        self.whole
    }

    /// The fine vertices the last average still makes (increasing).
    pub(super) fn rest(&self) -> &[u32] {
        &self.rest
    }

    /// Writes the fused points into `out` (per fine vertex) from the coarse data `x` (per vertex,
    /// or per face for a drawing step) of `coarse`, the level the points were made for; the
    /// other fine vertices are left as they are. An [`Error::Internal`] when `x` or `out` is
    /// too short or the level's tables are not the points' (the buffers and levels come from
    /// the crate).
    pub(super) fn apply<T: Scalar, const N: usize>(
        &self,
        x: &[Value<T, N>],
        coarse: &Level,
        out: &mut [MaybeUninit<Value<T, N>>],
    ) -> Result<()> {
        let ids = ClosureIds::again(coarse, self.ids)?.with_cycles_of_fused(&self.cycles)?;
        let [nv, ne, nf] = self.ids;
        // What lets the sums read and write unchecked: the nets' ids are vertices of the level
        // (the walk writes no other: [`super::regular`]) or, for a drawing step, its faces
        // (`dual::DualGrid::of`), and each written id is below `nv + ne + nf` ([`Owners::of`] and
        // `dual::DualGrid::of` checked it of every owned point).
        let (cells, reach) = match self.dual() {
            true => (nv, nf),
            false => (nf, nv),
        };
        let fits = self.owned.len() == cells
            && self.nets.len() == NET * cells
            && x.len() >= reach
            && out.len() >= nv + ne + nf;
        if !fits {
            return Err(Error::Internal(
                "fused points: the data or the output is not the points'".into(),
            ));
        }
        let out = Disjoint::new(out);
        if super::wide::fused_points(self, x, ids, &out) {
            return Ok(());
        }
        match (self.degree, self.dual()) {
            (3, false) => self.apply_loop::<T, N, 3, false>(x, ids, &out),
            (3, true) => self.apply_loop::<T, N, 3, true>(x, ids, &out),
            (_, false) => self.apply_loop::<T, N, 5, false>(x, ids, &out),
            (_, true) => self.apply_loop::<T, N, 5, true>(x, ids, &out),
        }
        Ok(())
    }

    /// [`Fused::apply`] without vectors, with the masks of `DEGREE`, on the cells of the dual
    /// grid (`DUAL`) or on faces.
    fn apply_loop<T: Scalar, const N: usize, const DEGREE: u32, const DUAL: bool>(
        &self,
        x: &[Value<T, N>],
        ids: ClosureIds,
        out: &Disjoint<Value<T, N>>,
    ) {
        let w = Weights::new(T::from_f64);
        self.owned
            .par_chunks(CHUNK)
            .enumerate()
            .for_each(|(chunk, owned)| {
                for (i, &bits) in owned.iter().enumerate() {
                    let f = chunk * CHUNK + i;
                    if bits == 0 {
                        continue;
                    }
                    let net = &self.nets[NET * f..NET * f + NET];
                    let p: [Value<T, N>; NET] = std::array::from_fn(|i| x[net[i] as usize]);
                    closure_points::<_, DEGREE, DUAL>(bits, &p, w, |bit, value| {
                        let v = ids.fine_vertex_of::<DUAL>(bit, f);
                        // SAFETY: below `nv + ne + nf` (checked by `apply`), and written by
                        // this face alone: each fine vertex has one owner (`Owners::of`).
                        unsafe { out.write(v, value) };
                    });
                }
            });
    }

    /// The degree of the sums (3 or 5).
    pub(super) fn degree(&self) -> u32 {
        self.degree
    }

    /// Whether the points are a drawing step's: the cells are then the coarse vertices (the
    /// faces of the dual grid, with their cycles of corners), their nets coarse faces.
    pub(super) fn dual(&self) -> bool {
        !self.cycles.is_empty()
    }

    /// Per cell, the points it writes.
    pub(super) fn owned(&self) -> &[u16] {
        &self.owned
    }

    /// Per cell, its net.
    pub(super) fn nets(&self) -> &[u32] {
        &self.nets
    }
}

/// The nets of a quad level's `nf` faces from its corner tables (in vectors where the
/// processor has AVX2 and `wide` allows it: the same ids).
///
/// Measured (2026-12-06, callgrind driver, 3,840-quad sphere, a new plan and its evaluation of
/// averaging 3 at level 3, one thread): the scalar walk is about 190 instructions a face
/// (15.8M of 77.1M), the vectors' about 33 (2.7M: gathers of four corners at once).
fn nets(corners: CornerTables, nf: usize, wide: bool) -> Result<Vec<u32>> {
    let mut nets: Vec<u32> = memory::with_capacity(NET * nf)?;
    nets.spare_capacity_mut()[..NET * nf]
        .par_chunks_mut(NET * CHUNK)
        .enumerate()
        .for_each(|(chunk, nets)| {
            if wide && super::wide::fused_nets(corners, chunk * CHUNK, nets) {
                return;
            }
            for (i, net) in nets.chunks_exact_mut(NET).enumerate() {
                let net: &mut [MaybeUninit<u32>; NET] = net.try_into().expect("a net");
                let c: [u32; 4] = std::array::from_fn(|k| (4 * (chunk * CHUNK + i) + k) as u32);
                // Across edge k (from corner k to k + 1): `t[k]`, at corner k + 1; across the
                // next edge of that face from corner k + 1: `d[k]`, the diagonal cell.
                let t = c.map(|c| corners.twin(c));
                let d = t.map(|t| corners.twin(after(t, 3)));
                for k in 0..4 {
                    net[k].write(corners.vertex(c[k]));
                    net[4 + k].write(corners.vertex(after(t[k], 2)));
                    net[8 + k].write(corners.vertex(after(t[k], 3)));
                    net[12 + k].write(corners.vertex(after(d[k], 2)));
                }
            }
        });
    // SAFETY: every face's net (its sixteen grid vertices: [`walked`]) was written above, by
    // the vectors or the loop (a panic would have unwound past here).
    unsafe { nets.set_len(NET * nf) };
    Ok(nets)
}

/// Which face writes each fused point, and the fine vertices left to the last average.
struct Owners {
    /// Per coarse face, its bits of [`Fused::owned`].
    owned: Vec<u16>,
    /// The fine vertices not fused, increasing (all of them when none is).
    rest: Vec<u32>,
}

impl Owners {
    /// The owners on `coarse` (its closure ids `ids`, its corner tables as the walk reads
    /// them, `child(c)` whether the kernel makes the child at corner `c`): a fine vertex is
    /// fused when the kernel makes the four children around it (an old vertex one that can be
    /// inside a grid, an edge one with two faces), and it is written by the face of the
    /// smaller of its edge's two corners or by the face of its vertex's first corner; a face
    /// point by its face when `faces` (per face, [`FACE_BIT`] or 0) says so.
    ///
    /// Only the old vertices `v` and edges `e` for which `vertex_ok(v)` and `edge_ok(e)` hold
    /// are fused (every one for the averaging rules; the smooth ones for classic
    /// Catmull-Clark).
    ///
    /// Point by point, so that each gets one owner by construction; each owner's bit is
    /// checked to name its point again ([`ClosureIds::fine_vertex`]), which is what lets the
    /// sums write unchecked and in parallel.
    fn of(
        coarse: &Level,
        ids: ClosureIds,
        corners: CornerTables,
        faces: Vec<u16>,
        child: impl Fn(u32) -> bool,
        vertex_ok: impl Fn(usize) -> bool,
        edge_ok: impl Fn(usize) -> bool,
    ) -> Result<Owners> {
        let [nv, ne, nf] = ids.sizes();
        let dead = 4 * nf as u32;
        let broken = || Error::Internal("fused points: a level's tables out of range".into());
        if faces.len() != nf {
            return Err(broken());
        }
        let mut owned = faces;
        let mut rest: Vec<u32> = Vec::new();
        let own = |owned: &mut [u16], corner: u32, bit: u16, point: usize| {
            let (f, bit) = ((corner >> 2) as usize, bit << (corner & 3));
            if ids.fine_vertex(bit, f) != point {
                return Err(broken());
            }
            owned[f] |= bit;
            Ok(())
        };
        let leave = |rest: &mut Vec<u32>, point: usize| {
            memory::grow(rest, 1)?;
            rest.push(point as u32);
            Ok::<_, Error>(())
        };
        let (offsets, vertex_corners) = coarse.vertex_corner_table();
        for v in 0..nv {
            let around = &vertex_corners[offsets[v] as usize..offsets[v + 1] as usize];
            if around.iter().any(|&c| c >= dead) {
                return Err(broken());
            }
            match corners.grid(v as u32) && around.iter().all(|&c| child(c)) && vertex_ok(v) {
                true => own(&mut owned, around[0], 1, v)?,
                false => leave(&mut rest, v)?,
            }
        }
        for (e, &[c, _]) in coarse.edge_corners().iter().enumerate() {
            let twin = match c {
                NONE => dead,
                c if c < dead => corners.twin(c),
                _ => return Err(broken()),
            };
            // The four children at the edge's midpoint: at its corners in either face.
            let fused = c != NONE
                && twin < dead
                && edge_ok(e)
                && [c, after(c, 1), twin, after(twin, 1)]
                    .iter()
                    .all(|&c| child(c));
            match fused {
                true => own(&mut owned, c.min(twin), EDGE_BIT, nv + e)?,
                false => leave(&mut rest, nv + e)?,
            }
        }
        for (f, &bits) in owned.iter().enumerate() {
            if bits & FACE_BIT == 0 {
                leave(&mut rest, nv + ne + f)?;
            }
        }
        Ok(Owners { owned, rest })
    }
}

/// The tables of a quad level that name a cell's fine vertices, checked once: a face's, or a
/// vertex's in the dual grid of a drawing step (with its corners' `cycles`).
#[derive(Clone, Copy)]
pub(super) struct ClosureIds<'a> {
    corner_verts: &'a [u32],
    corner_edges: &'a [u32],
    /// A drawing step's four corners per coarse vertex ([`Fused::cycles`]), each below `4 nf`;
    /// empty for primal cells.
    cycles: &'a [u32],
    nv: usize,
    ne: usize,
}

impl<'a> ClosureIds<'a> {
    /// The tables of `coarse`, an [`Error::Internal`] when they do not hold four corners a
    /// face (a bug). Their entries are not checked here: [`Owners::of`] checks the id of
    /// every point it gives an owner, and no other is read.
    fn of(coarse: &'a Level) -> Result<Self> {
        let (nv, ne, nf) = (coarse.num_vertices, coarse.num_edges(), coarse.num_faces());
        let (corner_verts, corner_edges) = (&coarse.corner_verts[..], coarse.corner_edges());
        if corner_verts.len() != 4 * nf || corner_edges.len() != 4 * nf {
            return Err(Error::Internal(
                "fused points: a quad level's corner tables out of range".into(),
            ));
        }
        Ok(ClosureIds {
            corner_verts,
            corner_edges,
            cycles: &[],
            nv,
            ne,
        })
    }

    /// The tables of the level `coarse` whose vertices, edges and faces [`ClosureIds::of`]
    /// found as `sizes`: only the sizes are checked again (a level's tables do not change, and
    /// the windows that hold the points are made with their step's level).
    fn again(coarse: &'a Level, sizes: [usize; 3]) -> Result<Self> {
        match ClosureIds::of(coarse)? {
            ids if ids.sizes() == sizes => Ok(ids),
            _ => Err(Error::Internal(
                "fused points: made for another level".into(),
            )),
        }
    }

    /// The same tables naming the cells of the dual grid by `cycles` ([`Fused::cycles`]; none
    /// when empty), checked: four corners per vertex, each a corner of the level.
    fn with_cycles(self, cycles: &'a [u32]) -> Result<Self> {
        let corners = self.corner_verts.len() as u32;
        let fits = self.with_cycles_of_fused(cycles).is_ok()
            && cycles.iter().fold(0, |m, &c| m.max(c)) < corners;
        if !fits {
            return Err(Error::Internal(
                "fused drawing points: corners of the dual grid out of range".into(),
            ));
        }
        Ok(ClosureIds { cycles, ..self })
    }

    /// [`ClosureIds::with_cycles`] for the cycles of a [`Fused`], whose entries were checked
    /// when it was made (they do not change): only their number is checked again.
    fn with_cycles_of_fused(self, cycles: &'a [u32]) -> Result<Self> {
        let fits = cycles.is_empty() || cycles.len() == 4 * self.nv;
        if !fits {
            return Err(Error::Internal(
                "fused drawing points: corners of the dual grid out of range".into(),
            ));
        }
        Ok(ClosureIds { cycles, ..self })
    }

    /// The level's vertices, edges and faces.
    fn sizes(self) -> [usize; 3] {
        [self.nv, self.ne, self.corner_verts.len() / 4]
    }

    /// The fine vertex of bit `bit` of cell `f`'s closure ([`Fused::owned`]): of a face, the
    /// old vertex at corner `k`, `nv` plus the edge of corner `k`, or `nv + ne + f`; of a
    /// vertex of the dual grid, with `c` its corner `k`, `nv + ne` plus the face of `c`, `nv`
    /// plus the edge of `c`, or `f` itself. `f` a face of the level (a vertex with cycles).
    #[inline(always)]
    pub(super) fn fine_vertex(self, bit: u16, f: usize) -> usize {
        match self.cycles.is_empty() {
            true => self.fine_vertex_of::<false>(bit, f),
            false => self.fine_vertex_of::<true>(bit, f),
        }
    }

    /// [`ClosureIds::fine_vertex`] of cells of the dual grid (`DUAL`, the ids made with cycles)
    /// or of faces, known where the sums are compiled.
    #[inline(always)]
    pub(super) fn fine_vertex_of<const DUAL: bool>(self, bit: u16, f: usize) -> usize {
        let k = (bit.trailing_zeros() % 4) as usize;
        if DUAL {
            debug_assert!(4 * f + k < self.cycles.len());
            // SAFETY: `f` is a vertex of the level, the cycles hold four corners a vertex, each
            // a corner of the level (`ClosureIds::with_cycles`), and the edge table holds one
            // per corner (`ClosureIds::of`).
            return unsafe {
                let c = *self.cycles.get_unchecked(4 * f + k) as usize;
                if bit < EDGE_BIT {
                    self.nv + self.ne + (c >> 2)
                } else if bit < FACE_BIT {
                    self.nv + *self.corner_edges.get_unchecked(c) as usize
                } else {
                    f
                }
            };
        }
        debug_assert!(4 * f + k < self.corner_verts.len());
        // SAFETY: `4 f + k` is a corner of a face of the level, and both tables hold four
        // corners a face (`ClosureIds::of`).
        unsafe {
            if bit < EDGE_BIT {
                *self.corner_verts.get_unchecked(4 * f + k) as usize
            } else if bit < FACE_BIT {
                self.nv + *self.corner_edges.get_unchecked(4 * f + k) as usize
            } else {
                self.nv + self.ne + f
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refinement::Refinement;
    use crate::step::regular::tests::{cube_grid, open_grid};
    use crate::{Options, Rules};

    /// Every bit of [`Fused::owned`].
    const ALL: u16 = 0x1ff;

    /// The nine points of a face's closure from its net `p`, by bit, with the masks of
    /// `degree` (3 or 5).
    fn closure<T: Scalar>(degree: u32, p: &[[T; 3]; NET]) -> [Option<[T; 3]>; 9] {
        let mut points = [None; 9];
        let mut write = |bit: u16, value| points[bit.trailing_zeros() as usize] = Some(value);
        let w = Weights::new(T::from_f64);
        match degree {
            3 => closure_points::<_, 3, false>(ALL, p, w, &mut write),
            _ => closure_points::<_, 5, false>(ALL, p, w, &mut write),
        }
        points
    }

    /// Values whose sums round (mixed magnitudes and signs), from a fixed seed.
    fn net<T: Scalar>(seed: u64) -> [[T; 3]; NET] {
        let mut state = seed;
        std::array::from_fn(|_| {
            std::array::from_fn(|_| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let unit = (state >> 11) as f64 / (1u64 << 53) as f64;
                T::from_f64((unit - 0.3) * 10f64.powi((state % 7) as i32 - 3))
            })
        })
    }

    /// `p` seen from another frame: `q[at(map(x, y))] = p[at(x, y)]` where `map` lands in the
    /// net, the rest of `q` from `fill`.
    fn moved<T: Copy>(
        p: &[[T; 3]; NET],
        fill: &[[T; 3]; NET],
        map: impl Fn(i32, i32) -> (i32, i32),
    ) -> [[T; 3]; NET] {
        let mut q = *fill;
        for y in -1..=2 {
            for x in -1..=2 {
                let (u, v) = map(x, y);
                if (-1..=2).contains(&u) && (-1..=2).contains(&v) {
                    q[at(u, v) as usize] = p[at(x, y) as usize];
                }
            }
        }
        q
    }

    /// A point has the same bits whichever face sums it, in whichever of its frames: the face
    /// turned a quarter (its corner k is the turned face's corner k + 1), and the face across
    /// its edge 0 (the frame turned half about the edge's midpoint, which is how the two faces
    /// of an edge see each other when the other face's corner 0 is at the edge). A partial
    /// level may give a point another owner, and the adaptive points must stay the uniform
    /// ones bit for bit.
    fn same_bits_in_every_frame<T: Scalar + PartialEq>(degree: u32) {
        for seed in 0..50 {
            let p: [[T; 3]; NET] = net(seed);
            let points = closure(degree, &p);
            // A quarter turn about the face's centre: (x, y) -> (1 - y, x).
            let turned = closure(degree, &moved(&p, &p, |x, y| (1 - y, x)));
            for k in 0..4 {
                let next = (k + 1) % 4;
                assert_eq!(points[k], turned[next], "corner {k}, seed {seed}");
                assert_eq!(points[4 + k], turned[4 + next], "edge {k}, seed {seed}");
            }
            assert_eq!(points[8], turned[8], "face point, seed {seed}");
            // The face across edge 0 with its corner 0 at this face's corner 1: (x, y) -> (1 -
            // x, -y); its own far row is other values.
            let across = closure(degree, &moved(&p, &net(seed + 1000), |x, y| (1 - x, -y)));
            // Mirrored (a level whose faces turn the other way): (x, y) -> (y, x), corner k
            // at corner 4 - k, edge k the mirror's edge 3 - k.
            let mirrored = closure(degree, &moved(&p, &p, |x, y| (y, x)));
            for k in 0..4 {
                assert_eq!(
                    points[k],
                    mirrored[(4 - k) % 4],
                    "mirror, corner {k}, seed {seed}"
                );
                assert_eq!(
                    points[4 + k],
                    mirrored[4 + 3 - k],
                    "mirror, edge {k}, seed {seed}"
                );
            }
            assert_eq!(points[8], mirrored[8], "mirror, face point, seed {seed}");
            assert_eq!(points[0], across[1], "corner 0 across edge 0, seed {seed}");
            assert_eq!(points[1], across[0], "corner 1 across edge 0, seed {seed}");
            assert_eq!(points[4], across[4], "edge 0 from across, seed {seed}");
        }
    }

    #[test]
    fn a_point_has_the_same_bits_in_every_frame() {
        for degree in [3, 5] {
            same_bits_in_every_frame::<f32>(degree);
            same_bits_in_every_frame::<f64>(degree);
        }
    }

    /// The sums are the B-spline's masks, written out as the tensor products of the 1-D
    /// masks, to rounding: degree 3's `(1, 6, 1) / 8` at an old vertex and `(1, 1) / 2` at a
    /// midpoint, degree 5's `(3, 10, 3) / 16` and `(1, 15, 15, 1) / 32` (the binomial step
    /// `binom(n + 1, k) / 2^n` split at the coarse vertices and midpoints), on every point of
    /// the closure and both degrees.
    #[test]
    fn the_sums_are_the_b_spline_masks() {
        let p: [[f64; 3]; NET] = net(7);
        let value = |x: i32, y: i32| p[at(x, y) as usize][0];
        for (degree, at_vertex, at_midpoint) in [
            (
                3,
                vec![(-1, 1.0), (0, 6.0), (1, 1.0)],
                vec![(0, 4.0), (1, 4.0)],
            ),
            (
                5,
                vec![(-1, 6.0), (0, 20.0), (1, 6.0)],
                vec![(-1, 1.0), (0, 15.0), (1, 15.0), (2, 1.0)],
            ),
        ] {
            let points = closure(degree, &p);
            let scale = 8f64.powi(2) * if degree == 3 { 1.0 } else { 16.0 };
            // The 1-D mask at frame coordinate `x` (an integer: a vertex; else a midpoint).
            let mask = |twice: i32| match twice % 2 {
                0 => at_vertex
                    .iter()
                    .map(|&(d, w)| (twice / 2 + d, w))
                    .collect::<Vec<_>>(),
                _ => at_midpoint
                    .iter()
                    .map(|&(d, w)| ((twice - 1) / 2 + d, w))
                    .collect(),
            };
            // Twice the frame coordinates of the points by bit: corners, midpoints, centre.
            let spots = [
                (0, 0),
                (2, 0),
                (2, 2),
                (0, 2),
                (1, 0),
                (2, 1),
                (1, 2),
                (0, 1),
                (1, 1),
            ];
            for (bit, &(tx, ty)) in spots.iter().enumerate() {
                let mut want = 0.0;
                for &(x, wx) in &mask(tx) {
                    for &(y, wy) in &mask(ty) {
                        want += wx * wy * value(x, y);
                    }
                }
                want /= scale;
                let got = points[bit].unwrap()[0];
                assert!(
                    (got - want).abs() <= 1e-12 * want.abs().max(1.0),
                    "degree {degree}, point {bit}: {got} against {want}"
                );
            }
        }
    }

    /// Calls `check(j, step, fused, last)` for each step `j` with fused points of `degree` and
    /// `levels` levels on a cube of grids and on an open grid with a crease (`last`: the
    /// run's last step); returns how many there were.
    fn each_fused_step(
        degree: u32,
        levels: u32,
        mut check: impl FnMut(usize, &crate::step::Step, &Fused, bool),
    ) -> usize {
        let options = Options {
            degree,
            levels,
            rules: Rules::Averaging,
            ..Options::default()
        };
        let mut steps = 0;
        for (cage, _) in [cube_grid(3), open_grid(7, 6, 10.0)] {
            let refinement = Refinement::new(&cage, &options).unwrap();
            let n = refinement.curve_networks().len();
            for j in 0..n {
                let step = refinement.step(j);
                if let Some(fused) = step.windows.and_then(|w| w.fused()) {
                    steps += 1;
                    check(j, &step, fused, j + 1 == n);
                }
            }
        }
        steps
    }

    /// The nets of the vectors are the loop's, id for id, on every step with fused points of a
    /// cube of grids and of an open grid with a crease (boundaries: twins at the dead face).
    /// Without AVX2 both are the loop's.
    #[test]
    fn nets_in_vectors_are_the_loops() {
        let steps = each_fused_step(3, 2, |j, step, _, _| {
            let flags = super::super::regular::Flags::of(step.coarse, step.curves).unwrap();
            let nf = step.coarse.num_faces();
            let wide = nets(flags.tables(), nf, true).unwrap();
            assert_eq!(wide, nets(flags.tables(), nf, false).unwrap(), "step {j}");
        });
        // Both steps of the cube; the open grid's second (its first has no clean face).
        assert_eq!(steps, 3, "the steps with fused points");
    }

    /// How many times each of the `n` fine vertices is made: by the cells that own it (named
    /// by `ids`) and by the average (`fused.rest`).
    pub(super) fn times_made(fused: &Fused, ids: ClosureIds, n: usize) -> Vec<u8> {
        let mut made = vec![0u8; n];
        for (cell, &bits) in fused.owned.iter().enumerate() {
            for b in 0..9 {
                if bits & (1 << b) != 0 {
                    made[ids.fine_vertex(1 << b, cell)] += 1;
                }
            }
        }
        for &w in &fused.rest {
            made[w as usize] += 1;
        }
        made
    }

    /// Every fine vertex of every step of degrees 3 and 5 is made once, by the face that owns
    /// it or by the last average; most of a mostly regular mesh's are fused, and none is where
    /// its children are not the tensor product's: curve vertices (the open grid's boundary
    /// and crease) and old vertices of another valence than 4 (the cube's corners).
    #[test]
    fn every_fine_vertex_is_made_once() {
        for degree in [3, 5] {
            every_fine_vertex_is_made_once_at(degree);
        }
    }

    fn every_fine_vertex_is_made_once_at(degree: u32) {
        let steps = each_fused_step(degree, 3, |j, step, fused, last| {
            assert_eq!(fused.degree(), degree);
            let ids = ClosureIds::of(step.coarse).unwrap();
            let n = step.fine.num_vertices;
            let made = times_made(fused, ids, n);
            assert!(
                made.iter().all(|&m| m == 1),
                "step {j}: a vertex made twice or never"
            );
            // The cube's last step: all but the points near its eight corners.
            if last && step.curves.vertices().is_empty() {
                assert!(
                    fused.rest.len() < n / 10,
                    "{} of {n} not fused",
                    fused.rest.len()
                );
            }
            let rest = |w: u32| fused.rest.binary_search(&w).is_ok();
            for cv in step.curves.vertices() {
                assert!(
                    rest(cv.vertex),
                    "step {j}: curve vertex {} fused",
                    cv.vertex
                );
            }
            for v in 0..step.coarse.num_vertices {
                if step.coarse.corners_of_vertex(v).len() != 4 {
                    assert!(
                        rest(v as u32),
                        "step {j}: vertex {v} of another valence fused"
                    );
                }
            }
        });
        assert!(
            steps >= 4,
            "degree {degree}: {steps} steps with fused points"
        );
    }
}
