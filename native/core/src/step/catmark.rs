//! The classic Catmull-Clark step (OpenSubdiv's `catmark` through `Far::PrimvarRefiner`), one
//! pass per level on primal data: face points (centroids), edge points (smooth, crease or the
//! fractional blend of the two), vertex points (smooth, crease or corner masks, blended where
//! the rule changes), with the weights of [`crate::scheme::catmark`] and the sharpness and rules
//! of [`LevelSharpness`].
//!
//! The face points are written straight into the last section of the output (the fine level
//! numbers old vertices, then edge points, then face points), then the vertex and edge points
//! read them from there: one buffer per step, no copy, and no per-vertex branch on the section.

use std::borrow::Cow;
use std::mem::MaybeUninit;

use super::{CurveData, LevelData, Step, Tables};
use crate::curves::LevelSharpness;
use crate::error::{Error, Result};
use crate::options::Creasing;
use crate::parallel::{fill, hinted_or_abort};
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

/// One step of `values` (per vertex of `step.coarse`) into `out` (its previous contents are
/// dropped; its allocation is reused when large enough). A step without the levels' sharpness
/// tables (which `Refinement` builds for these rules) is an internal error.
pub(crate) fn step_into<T: Scalar, const N: usize>(
    step: &Step,
    creasing: Creasing,
    values: &[Value<T, N>],
    out: &mut Vec<Value<T, N>>,
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
    let (head, faces) = out.spare_capacity_mut()[..n].split_at_mut(nv + ne);
    // The tables looked up once, not per vertex (see [`Tables`]).
    let t = Tables::of(coarse);
    fill(faces, |f| {
        if t.quads {
            // The additions of the general case below, in the same order.
            let [a, b, c, d] = t.at_corners(values, f);
            return scale(add(add(add(a, b), c), d), T::from_f64(0.25));
        }
        let corners = coarse.face_corners(f);
        let w = T::from_f64(1.0 / corners.len() as f64);
        let sum = corners.fold(zero(), |s, c| {
            add(s, values[coarse.corner_verts[c] as usize])
        });
        scale(sum, w)
    });
    // SAFETY: `fill` wrote every item of `faces` (a panic would have unwound past here), and
    // `MaybeUninit<V>` has the layout of `V`.
    let faces: &[Value<T, N>] =
        unsafe { &*(faces as *const [MaybeUninit<Value<T, N>>] as *const [Value<T, N>]) };
    let (old, edges) = head.split_at_mut(nv);
    if this.is_smooth() {
        fill(old, |v| smooth_vertex(&t, v, values, faces));
    } else {
        // Most vertices of a level with curves are smooth (a face-varying mesh has boundaries
        // everywhere its seams run): their mask inline, the rule machinery for the rest.
        fill(old, |v| {
            if this.rule(v).is_smooth() {
                smooth_vertex(&t, v, values, faces)
            } else {
                vertex_point(&t, this, child, creasing, v, values, faces)
            }
        });
    }
    if this.has_sharp_edges() {
        // Likewise for edges: `smooth_edge` is `edge_point` at sharpness 0, in the same order.
        fill(edges, |e| {
            if this.edge(e) <= 0.0 && t.edge_corners[e][1] != NONE {
                smooth_edge(&t, e, values, faces)
            } else {
                edge_point(coarse, this, child, e, nv + e, values, faces)
            }
        });
    } else {
        fill(edges, |e| smooth_edge(&t, e, values, faces));
    }
    // SAFETY: the three sections, which `fill` wrote completely, are the first `n` items.
    unsafe { out.set_len(n) };
    Ok(())
}

/// The vertex point of old vertex `v` (OpenSubdiv's `ComputeVertexVertexMask` with the parent
/// and child rules known).
fn vertex_point<T: Scalar, const N: usize>(
    t: &Tables,
    this: &LevelSharpness,
    child: &LevelSharpness,
    creasing: Creasing,
    v: usize,
    values: &[Value<T, N>],
    faces: &[Value<T, N>],
) -> Value<T, N> {
    let coarse = t.level;
    let parent_rule = this.rule(v);
    if parent_rule.is_smooth() {
        return smooth_vertex(t, v, values, faces);
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
        VertexRule::Smooth | VertexRule::Dart => smooth_vertex(t, v, values, faces),
        VertexRule::Crease => crease_vertex(coarse, v, values, |e| {
            child.edge(coarse.child_half(e, v as u32) as usize)
        }),
        VertexRule::Corner => values[v],
    };
    let p = this.with_edge_sharpness(coarse, v, Some(child), |pe, ce| {
        fractional_weight(this.vertex(v), child.vertex(v), pe, ce, creasing)
    });
    lerp(parent_mask, child_mask, p as f64)
}

/// The smooth vertex mask `(k-2)/k v + 1/k^2 sum e_i + 1/k^2 sum f_i` (interior vertex of `k`
/// faces; `e_i` the edge neighbours, `f_i` the face points).
#[inline(always)]
fn smooth_vertex<T: Scalar, const N: usize>(
    t: &Tables,
    v: usize,
    values: &[Value<T, N>],
    faces: &[Value<T, N>],
) -> Value<T, N> {
    let corners = t.corners_of_vertex(v);
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

/// The smooth edge point `1/4 (a + b + f_0 + f_1)` of an interior edge `e` of a level without
/// sharp edges (where every edge has two faces: boundaries are sharp), or of a level with sharp
/// edges where `e` is smooth and has two faces.
#[inline(always)]
fn smooth_edge<T: Scalar, const N: usize>(
    t: &Tables,
    e: usize,
    values: &[Value<T, N>],
    faces: &[Value<T, N>],
) -> Value<T, N> {
    let [a, b] = t.edge_verts[e];
    let [c0, c1] = t.edge_corners[e];
    debug_assert!(c1 != NONE, "a smooth level has no boundary edge");
    // The operations of `edge_point` at sharpness 0 (bitwise equal).
    let (ends, face_total) = SMOOTH_EDGE_WEIGHTS;
    let f = add(faces[t.face_of(c0 as usize)], faces[t.face_of(c1 as usize)]);
    mad(
        scale(f, T::from_f64(face_total / 2.0)),
        T::from_f64(ends),
        add(values[a as usize], values[b as usize]),
    )
}

/// The edge point of edge `e` (fine vertex `w`): smooth `1/4 (a + b + f_0 + f_1)`, crease
/// midpoint, or for a semi-sharp edge whose child is no crease the blend with weight `s`
/// (OpenSubdiv's `ComputeEdgeVertexMask`).
#[inline]
fn edge_point<T: Scalar, const N: usize>(
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
