//! The classic Catmull-Clark step (OpenSubdiv's `catmark` through `Far::PrimvarRefiner`), one
//! pass per level on primal data: face points (centroids), edge points (smooth, crease or the
//! fractional blend of the two), vertex points (smooth, crease or corner masks, blended where
//! the rule changes), with the weights of [`crate::scheme::catmark`] and the sharpness and rules
//! of [`LevelSharpness`].
//!
//! The face points are written straight into the last section of the output (the fine level
//! numbers old vertices, then edge points, then face points), then the vertex and edge points
//! read them from there: no copy, and no per-vertex branch on the section.
//!
//! On a quad level, a face point, the smooth edge point of an edge between two quads and the
//! smooth vertex point of an interior vertex of valence 4 are the cubic B-spline's masks over
//! the coarse vertices, the sums of the averaging rules' fused step of degree 3
//! ([`super::fused`]): `(a + c + b + d) / 4`, `(6 (a + b) + S) / 16`, `(36 v + 6 E + D) / 64`.
//! This step computes those points by those functions on every path ([`cubic_face`],
//! [`cubic_edge`], [`cubic_vertex`]), so their bits are the same whichever path makes them; a
//! plan makes them from each face's 4 x 4 net of coarse vertices ([`SmoothPoints`]: each point
//! once, from the face that owns it), and the classic masks only at the other vertices and
//! edges (creases, boundaries, other valences). The results equal the masks' in exact
//! arithmetic (within 1e-12 of the data's scale in f64, tested; the summation order differs).

use std::borrow::Cow;
use std::mem::MaybeUninit;

use super::fused::{cubic_edge, cubic_face, cubic_vertex, Fused, Weights};
use super::regular::{after, Flags};
use super::{CurveData, LevelData, Step, Tables};
use crate::curves::{CurveNetwork, LevelSharpness};
use crate::error::{Error, Result};
use crate::options::Creasing;
use crate::parallel::{fill, fill_zip, hinted_or_abort, scatter_uninit};
use crate::scalar::{add, lerp, mad, scale, zero, Scalar, Value};
use crate::scheme::catmark::{
    blended_edge_weights, fractional_weight, smooth_vertex_weights, VertexRule, CREASE_EDGE_WEIGHT,
    CREASE_VERTEX_WEIGHTS, SMOOTH_EDGE_WEIGHTS,
};
use crate::scheme::is_sharp;
use crate::topology::{Level, NONE};

impl<T: Scalar, const N: usize> LevelData<'_, T, N> {
    /// The Catmull-Clark step (see the module documentation); the data stays primal.
    pub(super) fn catmark(&mut self, step: &Step, creasing: Creasing) -> Result<()> {
        debug_assert!(self.primal, "Catmull-Clark data is primal");
        let mut out = self.fresh();
        step_into(step, creasing, &self.vertices, &mut out)?;
        if let Cow::Owned(old) = std::mem::replace(&mut self.vertices, Cow::Owned(out)) {
            self.spare = old;
        }
        self.curve = CurveData::OnVertices;
        Ok(())
    }
}

/// A classic step's points that a quad level makes by the fused sums of degree 3 (module
/// documentation): every face point, the edge points of its smooth edges between two quads,
/// the vertex points of its smooth vertices inside a grid. Topology and sharpness only: a plan
/// makes them once per step ([`crate::refinement::Refinement`]).
///
/// Measured (2026-12-07, callgrind driver, 3,840-quad sphere, one thread), against the masks
/// with the smooth points of small quad levels as means of bilinear fine faces (the path
/// before): a cached evaluation of classic 3 at levels 2 / 3 / 4 5.69M / 23.35M / 93.95M ->
/// 2.22M / 8.86M / 35.38M instructions, cached UVs of classic 3 at level 3 38.74M -> 21.29M;
/// a new plan and its evaluation 12.70M / 38.13M / 139.74M -> 15.29M / 49.22M / 181.05M (the
/// owners' serial pass, about 160 instructions a coarse face, the nets and the twin table).
/// Results of f64 data moved by at most 3.3e-16 of the largest coordinate (the sums' order).
#[derive(Debug)]
pub(crate) struct SmoothPoints(Fused);

impl SmoothPoints {
    /// The smooth points of the step from `coarse` with the sharpness and rules `this` of
    /// that level; `None` unless the level is of quads (and has a point to fuse).
    pub(crate) fn of(coarse: &Level, this: &LevelSharpness) -> Result<Option<SmoothPoints>> {
        if !coarse.all_quads() || coarse.num_faces() == 0 {
            return Ok(None);
        }
        // The walk's tables without curves: the classic rules read the sharpness instead.
        let flags = Flags::of(coarse, &CurveNetwork::default())?;
        let fused = Fused::classic(
            coarse,
            flags.tables(),
            |v| this.rule(v).is_smooth(),
            |e| this.edge(e) <= 0.0,
        )?;
        Ok(fused.map(SmoothPoints))
    }

    /// The bytes of the points' tables (tests: what the estimate counts).
    #[cfg(test)]
    pub(crate) fn bytes(&self) -> usize {
        let fused = &self.0;
        4 * fused.nets().len() + 2 * fused.owned().len() + 4 * fused.rest().len()
    }
}

/// One step of `values` (per vertex of `step.coarse`) into `out` (its previous contents are
/// dropped; its allocation is reused when large enough), the smooth points by the step's
/// [`SmoothPoints`] when it has them. A step without the levels' sharpness tables (which
/// `Refinement` builds for these rules) is an internal error.
pub(crate) fn step_into<T: Scalar, const N: usize>(
    step: &Step,
    creasing: Creasing,
    values: &[Value<T, N>],
    out: &mut Vec<Value<T, N>>,
) -> Result<()> {
    step_by(step, creasing, values, out, true)
}

/// [`step_into`], the smooth points by the step's [`SmoothPoints`] when `fused` and the step
/// has them, else each by its own rule over the coarse level (the same bits: the tests compare
/// the two).
pub(crate) fn step_by<T: Scalar, const N: usize>(
    step: &Step,
    creasing: Creasing,
    values: &[Value<T, N>],
    out: &mut Vec<Value<T, N>>,
    fused: bool,
) -> Result<()> {
    let (coarse, fine) = (step.coarse, step.fine);
    let (this, child) = step.sharpness.ok_or_else(|| {
        Error::Internal("a Catmull-Clark step needs its levels' sharpness tables".into())
    })?;
    let (nv, ne) = (coarse.num_vertices, coarse.num_edges());
    let n = fine.num_vertices;
    out.clear();
    if out.capacity() < n {
        *out = hinted_or_abort(n);
    }
    // The tables looked up once, not per vertex (see [`Tables`]).
    let t = Tables::of(coarse);
    let w = Weights::new(T::from_f64);
    let rules = Rules {
        t: &t,
        this,
        child,
        creasing,
        w,
    };
    match step.smooth_points.filter(|_| fused) {
        Some(SmoothPoints(points)) => {
            // Every face point is fused (a quad level), so the rest is old vertices and edges.
            let every_face = points.whole()
                && n == nv + ne + coarse.num_faces()
                && points.rest().last().is_none_or(|&w| (w as usize) < nv + ne);
            if !every_face {
                return Err(Error::Internal(
                    "Catmull-Clark: fused points without every face point".into(),
                ));
            }
            let out = &mut out.spare_capacity_mut()[..n];
            points.apply(values, coarse, out)?;
            let (head, faces) = out.split_at_mut(nv + ne);
            // SAFETY: `Fused::apply` wrote every point some face owns, and each face owns its
            // own point: `whole` says that the owned points and the rest are every fine vertex
            // (the level's `n`), and the rest holds no face point (both checked above).
            let faces = unsafe { assume_init(faces) };
            scatter_uninit(head, points.rest(), |w| match w < nv {
                true => [rules.vertex_point(w, values, faces)],
                false => [rules.edge_point(w - nv, values, faces)],
            })?;
        }
        None => {
            let (head, faces) = out.spare_capacity_mut()[..n].split_at_mut(nv + ne);
            let (old, edges) = head.split_at_mut(nv);
            fill(faces, |f| rules.face_point(f, values));
            // SAFETY: `fill` wrote every item of `faces` (a panic would have unwound past
            // here), and `MaybeUninit<V>` has the layout of `V`.
            let faces = unsafe { assume_init(faces) };
            rules.vertex_and_edge_points(values, faces, old, edges);
        }
    }
    // SAFETY: the three sections, written completely above, are the first `n` items.
    unsafe { out.set_len(n) };
    Ok(())
}

/// What the classic rules read besides the data: the coarse level's tables, the sharpness and
/// rules of both levels, the creasing method, and the weights of the fused sums.
#[derive(Clone, Copy)]
struct Rules<'a, T: Scalar> {
    t: &'a Tables<'a>,
    this: &'a LevelSharpness,
    child: &'a LevelSharpness,
    creasing: Creasing,
    w: Weights<T>,
}

impl<T: Scalar> Rules<'_, T> {
    /// The face point of face `f`: the mean of its corners (a quad's by [`cubic_face`]).
    #[inline(always)]
    fn face_point<const N: usize>(&self, f: usize, values: &[Value<T, N>]) -> Value<T, N> {
        let t = self.t;
        if t.quads {
            let corners = t.at_corners(values, f);
            return cubic_face(|k| corners[k as usize], &[0, 1, 2, 3], self.w);
        }
        let corners = t.face_corners(f);
        let w = T::from_f64(1.0 / corners.len() as f64);
        let sum = corners.fold(zero(), |s, c| add(s, values[t.corner_verts[c] as usize]));
        scale(sum, w)
    }

    /// The old vertices' and the edge points of a step (`old` and `edges`) from the coarse
    /// `values` and the new face points `faces`.
    #[inline(always)]
    fn vertex_and_edge_points<const N: usize>(
        &self,
        values: &[Value<T, N>],
        faces: &[Value<T, N>],
        old: &mut [MaybeUninit<Value<T, N>>],
        edges: &mut [MaybeUninit<Value<T, N>>],
    ) {
        let (t, this, nv) = (self.t, self.this, old.len());
        // The old vertices and edges walk a table of their own only to go through `fill_zip`:
        // with the plain `fill` LLVM stopped inlining the smooth closures (cached classic 3: +10
        // %), as in the averaging step's `gather_primal`.
        if this.is_smooth() {
            fill_zip(old, &t.vertex_offsets[..nv], |v, _| {
                self.smooth_vertex(v, values, faces)
            });
        } else {
            // Most vertices of a level with curves are smooth (a face-varying mesh has
            // boundaries everywhere its seams run): their mask inline, the rule machinery for
            // the rest.
            fill(old, |v| self.vertex_point(v, values, faces));
        }
        if this.has_sharp_edges() {
            fill(edges, |e| self.edge_point(e, values, faces));
        } else {
            fill_zip(edges, t.edge_corners, |e, &corners| {
                self.smooth_edge(e, corners, values, faces)
            });
        }
    }

    /// The vertex point of old vertex `v` (OpenSubdiv's `ComputeVertexVertexMask` with the
    /// parent and child rules known).
    #[inline(always)]
    fn vertex_point<const N: usize>(
        &self,
        v: usize,
        values: &[Value<T, N>],
        faces: &[Value<T, N>],
    ) -> Value<T, N> {
        let (coarse, this, child) = (self.t.level, self.this, self.child);
        let parent_rule = this.rule(v);
        if parent_rule.is_smooth() {
            return self.smooth_vertex(v, values, faces);
        }
        let parent_mask = match parent_rule {
            VertexRule::Crease => crease_vertex(coarse, v, values, |e| this.edge(e as usize)),
            _ => values[v],
        };
        let child_rule = child.rule(v);
        if child_rule == parent_rule {
            return parent_mask;
        }
        let child_mask = match child_rule {
            VertexRule::Smooth | VertexRule::Dart => self.smooth_vertex(v, values, faces),
            VertexRule::Crease => crease_vertex(coarse, v, values, |e| {
                child.edge(coarse.child_half(e, v as u32) as usize)
            }),
            VertexRule::Corner => values[v],
        };
        let p = this.with_edge_sharpness(coarse, v, Some(child), |pe, ce| {
            fractional_weight(this.vertex(v), child.vertex(v), pe, ce, self.creasing)
        });
        lerp(parent_mask, child_mask, p as f64)
    }

    /// The smooth vertex mask `(k-2)/k v + 1/k^2 sum e_i + 1/k^2 sum f_i` (interior vertex of
    /// `k` faces; `e_i` the edge neighbours, `f_i` the face points); inside a grid of quads,
    /// [`cubic_vertex`] over its neighbours.
    #[inline(always)]
    fn smooth_vertex<const N: usize>(
        &self,
        v: usize,
        values: &[Value<T, N>],
        faces: &[Value<T, N>],
    ) -> Value<T, N> {
        let t = self.t;
        let corners = t.corners_of_vertex(v);
        if let Some(fan) = self.grid_fan(v, corners) {
            let at = |c: u32| values[t.corner_verts[c as usize] as usize];
            let edge = |k: usize| at(after(fan[k], 1));
            let diagonal = |k: usize| at(after(fan[k], 2));
            // Opposite neighbours in pairs: the fan's corners 0 and 2, 1 and 3.
            let points = [
                values[v],
                edge(0),
                edge(2),
                edge(1),
                edge(3),
                diagonal(0),
                diagonal(2),
                diagonal(1),
                diagonal(3),
            ];
            return cubic_vertex(|i| points[i as usize], &[0, 1, 2, 3, 4, 5, 6, 7, 8], self.w);
        }
        let mut sum = zero();
        for &c in corners {
            let c = c as usize;
            let neighbour = values[t.corner_verts[t.next(c)] as usize];
            sum = add(sum, add(neighbour, faces[t.face_of(c)]));
        }
        let (vertex, ring) = smooth_vertex_weights(corners.len());
        mad(
            scale(values[v], T::from_f64(vertex)),
            T::from_f64(ring),
            sum,
        )
    }

    /// The four `corners` of vertex `v` of a quad level in their order around it (each across
    /// the outgoing edge of the one before) when `v` is inside a grid: interior, manifold, of
    /// valence 4 (what the fused sums' walk takes, [`Flags`]); `None` otherwise.
    #[inline(always)]
    fn grid_fan(&self, v: usize, corners: &[u32]) -> Option<[u32; 4]> {
        let t = self.t;
        let coarse = t.level;
        if !t.quads || corners.len() != 4 {
            return None;
        }
        let non_manifold = coarse.is_non_manifold();
        if non_manifold && coarse.is_non_manifold_vertex(v) {
            return None;
        }
        let mut fan = [corners[0]; 4];
        for i in 1..=4 {
            let c = fan[i - 1];
            let e = t.corner_edges[c as usize] as usize;
            let [a, b] = t.edge_corners[e];
            if a == NONE || b == NONE || (non_manifold && coarse.is_non_manifold_edge(e)) {
                return None;
            }
            let twin = if a == c { b } else { a };
            // The twin is at the edge's other end; the corner after it is at `v` again.
            let next = after(twin, 1);
            match i {
                4 if next != fan[0] => return None,
                4 => {}
                _ => fan[i] = next,
            }
        }
        let distinct = fan[0] != fan[1] && fan[0] != fan[2] && fan[0] != fan[3];
        (distinct && fan[1] != fan[2] && fan[1] != fan[3] && fan[2] != fan[3]).then_some(fan)
    }

    /// The edge point of edge `e`: smooth (interior and of sharpness 0: [`Rules::smooth_edge`])
    /// or by [`edge_point_of_sharp`].
    #[inline(always)]
    fn edge_point<const N: usize>(
        &self,
        e: usize,
        values: &[Value<T, N>],
        faces: &[Value<T, N>],
    ) -> Value<T, N> {
        let corners = self.t.edge_corners[e];
        if self.this.edge(e) <= 0.0 && corners[1] != NONE {
            self.smooth_edge(e, corners, values, faces)
        } else {
            let nv = self.t.level.num_vertices;
            edge_point_of_sharp(
                self.t.level,
                self.this,
                self.child,
                e,
                nv + e,
                values,
                faces,
            )
        }
    }

    /// The smooth edge point `1/4 (a + b + f_0 + f_1)` of an interior edge `e` of two faces
    /// with `corners`, by the mask; between two quads, by [`cubic_edge`].
    #[inline(always)]
    fn smooth_edge<const N: usize>(
        &self,
        e: usize,
        corners: [u32; 2],
        values: &[Value<T, N>],
        faces: &[Value<T, N>],
    ) -> Value<T, N> {
        let t = self.t;
        let [c0, c1] = corners;
        debug_assert!(c1 != NONE, "a smooth edge is interior");
        if t.quads {
            let at = |c: u32| values[t.corner_verts[c as usize] as usize];
            // The ends, then the other two corners of each quad.
            let points = [
                at(c0),
                at(after(c0, 1)),
                at(after(c0, 2)),
                at(after(c0, 3)),
                at(after(c1, 2)),
                at(after(c1, 3)),
            ];
            return cubic_edge(|i| points[i as usize], &[0, 1, 2, 3, 4, 5], self.w);
        }
        let [a, b] = t.edge_verts[e];
        // The operations of `edge_point_of_sharp` at sharpness 0 (bitwise equal).
        let (ends, face_total) = SMOOTH_EDGE_WEIGHTS;
        let f = add(faces[t.face_of(c0 as usize)], faces[t.face_of(c1 as usize)]);
        mad(
            scale(f, T::from_f64(face_total / 2.0)),
            T::from_f64(ends),
            add(values[a as usize], values[b as usize]),
        )
    }
}

/// `items`, every one of which has been written, as initialised values.
///
/// # Safety
/// Every item of `items` must be initialised.
unsafe fn assume_init<V>(items: &mut [MaybeUninit<V>]) -> &[V] {
    // SAFETY: the caller's promise, and `MaybeUninit<V>` has the layout of `V`.
    unsafe { &*(items as *const [MaybeUninit<V>] as *const [V]) }
}

/// The crease vertex mask `3/4 v + 1/8 (a + b)`, `a` and `b` the other ends of the first two
/// edges at `v` whose `sharpness` is positive.
#[inline]
fn crease_vertex<T: Scalar, const N: usize>(
    coarse: &Level,
    v: usize,
    values: &[Value<T, N>],
    sharpness: impl Fn(u32) -> f32,
) -> Value<T, N> {
    let ends = coarse.sharp_neighbours(v, |e| is_sharp(sharpness(e)));
    let (vertex, neighbour) = CREASE_VERTEX_WEIGHTS;
    mad(
        scale(values[v], T::from_f64(vertex)),
        T::from_f64(neighbour),
        add(values[ends[0]], values[ends[1]]),
    )
}

/// The edge point of edge `e` (fine vertex `w`): smooth `1/4 (a + b + f_0 + f_1)`, crease
/// midpoint, or for a semi-sharp edge whose child is no crease the blend with weight `s`
/// (OpenSubdiv's `ComputeEdgeVertexMask`).
#[inline]
fn edge_point_of_sharp<T: Scalar, const N: usize>(
    coarse: &Level,
    this: &LevelSharpness,
    child: &LevelSharpness,
    e: usize,
    w: usize,
    values: &[Value<T, N>],
    faces: &[Value<T, N>],
) -> Value<T, N> {
    let [a, b] = coarse.edge_verts()[e];
    let ends = add(values[a as usize], values[b as usize]);
    let s = this.edge(e);
    // `total` shared by the faces of the edge (OpenSubdiv's `0.5 / faceCount` each when smooth;
    // a smooth boundary edge cannot occur, boundaries being infinitely sharp).
    let face_sum = |total: f64| {
        let mut sum = zero();
        let mut count = 0usize;
        for &c in &coarse.edge_corners()[e] {
            if c != NONE {
                sum = add(sum, faces[coarse.face_of(c as usize)]);
                count += 1;
            }
        }
        scale(sum, T::from_f64(total / count.max(1) as f64))
    };
    if s <= 0.0 {
        let (end_weight, face_total) = SMOOTH_EDGE_WEIGHTS;
        return mad(face_sum(face_total), T::from_f64(end_weight), ends);
    }
    if child.rule(w) == VertexRule::Crease {
        return scale(ends, T::from_f64(CREASE_EDGE_WEIGHT));
    }
    let (end_weight, face_total) = blended_edge_weights(s);
    mad(face_sum(face_total), T::from_f64(end_weight), ends)
}
