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
//! On a quad level whose fine faces fit [`FINE_FACES_BYTES`] (every level after the first, up to
//! level 4 of the 3,840-quad sphere in f32) the smooth points come from the averaging form of the
//! same rules ([`bilinear_children`]): the fine faces' bilinear values first, four per coarse face,
//! then each face point, smooth edge point and smooth valence-4 vertex point as the mean of its
//! four fine faces; the classic masks only at the other vertices and edges. The results equal the
//! masks' in exact arithmetic (within 1e-12 of the data's scale in f64, tested; the summation order
//! differs) with fewer instructions: cached classic 3 on the callgrind driver's 3,840-quad sphere,
//! one thread, with every quad level by fine faces, 7.10M / 29.47M / 118.9M -> 5.71M / 23.60M /
//! 95.1M at levels 2 / 3 / 4 (2026-12-04). But the buffer of fine faces is four times the coarse
//! level's faces and a cached plan keeps it: larger levels keep the masks (the constant's figures).

use std::borrow::Cow;
use std::mem::MaybeUninit;

use super::{quad_edge_mean, quad_mean, vertex_corner_mean, CurveData, LevelData, Step, Tables};
use crate::curves::LevelSharpness;
use crate::error::{Error, Result};
use crate::options::Creasing;
use crate::parallel::{fill, fill_zip, hinted_or_abort};
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
        // The dual buffer is free while the data is primal: it holds the fine faces' values of
        // a small quad level ([`step_into`]), and stays there for the next step.
        let mut fine_faces = self.take_faces();
        step_into(step, creasing, &self.vertices, &mut out, &mut fine_faces)?;
        self.faces = Cow::Owned(fine_faces);
        if let Cow::Owned(old) = std::mem::replace(&mut self.vertices, Cow::Owned(out)) {
            self.spare = old;
        }
        self.curve = CurveData::OnVertices;
        Ok(())
    }
}

/// One step of `values` (per vertex of `step.coarse`) into `out` (its previous contents are
/// dropped; its allocation is reused when large enough). `fine_faces` is a buffer for the fine
/// faces' values on a quad level ([`bilinear_children`]; its contents are dropped too). A step
/// without the levels' sharpness tables (which `Refinement` builds for these rules) is an
/// internal error.
pub(crate) fn step_into<T: Scalar, const N: usize>(
    step: &Step,
    creasing: Creasing,
    values: &[Value<T, N>],
    out: &mut Vec<Value<T, N>>,
    fine_faces: &mut Vec<Value<T, N>>,
) -> Result<()> {
    let coarse = step.coarse;
    let buffer = 4 * coarse.num_faces() * std::mem::size_of::<Value<T, N>>();
    let by_fine_faces = buffer <= FINE_FACES_BYTES && coarse.all_quads();
    step_by(step, creasing, values, out, fine_faces, by_fine_faces)
}

/// Largest buffer of fine faces' values (bytes) for which a quad level takes its smooth points
/// from the fine faces (module documentation): the buffer is four times the coarse level's face
/// count and a cached plan keeps it, so the bound is also what the path may add to a plan's
/// memory. Measured 2026-12-04 23:20 UTC (cached classic 3 on the 3,840-quad sphere, f32 points,
/// interleaved wall times of the callgrind driver, medians of 5-9 rounds, load 1.2-1.4) against
/// the bound of 1 MiB before: cached level 3 19 % / 13 % faster on one / two threads (2.9 MiB of
/// fine faces), level 4 22 % / 27 % (11.8 MiB); a new plan's first evaluation 11 % slower at
/// level 3 (the new buffer's first touch; 10 % fewer instructions), 8 % faster at level 4. The
/// same comparison at 16:00 had found level 3 equal on one thread and level 4 15 % slower; what
/// changed between the two was not isolated (README, History).
const FINE_FACES_BYTES: usize = 1 << 24;

/// [`step_into`], the smooth points from the fine faces when `by_fine_faces` (a level of quads
/// only), else by the masks over the coarse level (any level; the tests compare the two).
pub(crate) fn step_by<T: Scalar, const N: usize>(
    step: &Step,
    creasing: Creasing,
    values: &[Value<T, N>],
    out: &mut Vec<Value<T, N>>,
    fine_faces: &mut Vec<Value<T, N>>,
    by_fine_faces: bool,
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
    let (old, edges) = head.split_at_mut(nv);
    // The tables looked up once, not per vertex (see [`Tables`]).
    let t = Tables::of(coarse);
    if by_fine_faces {
        if !t.quads {
            return Err(Error::Internal(
                "Catmull-Clark by fine faces on a level that is not all quads".into(),
            ));
        }
        let fine = bilinear_children(&t, values, fine_faces);
        let quarter = T::from_f64(0.25);
        fill_zip(faces, fine, |_, q| quad_mean(q, quarter));
        // SAFETY: `fill_zip` wrote every item of `faces` (a panic would have unwound past
        // here), and `MaybeUninit<V>` has the layout of `V`.
        let faces = unsafe { assume_init(faces) };
        let flat = fine.as_flattened();
        vertex_and_edge_points(
            &t,
            (this, child, creasing),
            values,
            faces,
            old,
            edges,
            #[inline(always)]
            |v| match t.corners_of_vertex(v).len() {
                4 => vertex_corner_mean(&t, flat, v),
                _ => smooth_vertex(&t, v, values, faces),
            },
            #[inline(always)]
            |_, &corners| quad_edge_mean(fine, corners),
        );
    } else {
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
        // SAFETY: as above.
        let faces = unsafe { assume_init(faces) };
        vertex_and_edge_points(
            &t,
            (this, child, creasing),
            values,
            faces,
            old,
            edges,
            #[inline(always)]
            |v| smooth_vertex(&t, v, values, faces),
            #[inline(always)]
            |e, _| smooth_edge(&t, e, values, faces),
        );
    }
    // SAFETY: the three sections, written completely above, are the first `n` items.
    unsafe { out.set_len(n) };
    Ok(())
}

/// `items`, every one of which has been written, as initialised values.
///
/// # Safety
/// Every item of `items` must be initialised.
unsafe fn assume_init<V>(items: &mut [MaybeUninit<V>]) -> &[V] {
    // SAFETY: the caller's promise, and `MaybeUninit<V>` has the layout of `V`.
    unsafe { &*(items as *const [MaybeUninit<V>] as *const [V]) }
}

/// The old vertices' and the edge points of a step (`old` and `edges`) from the coarse
/// `values` and the new face points `faces`: smooth vertices and edges by `smooth_vertex_at`
/// and `smooth_edge_at` (the smooth masks; an edge's with its two corners), the others by the rules
/// of `sharpness` (this level's, the child's, and the creasing method).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn vertex_and_edge_points<T: Scalar, const N: usize>(
    t: &Tables,
    sharpness: (&LevelSharpness, &LevelSharpness, Creasing),
    values: &[Value<T, N>],
    faces: &[Value<T, N>],
    old: &mut [MaybeUninit<Value<T, N>>],
    edges: &mut [MaybeUninit<Value<T, N>>],
    smooth_vertex_at: impl Fn(usize) -> Value<T, N> + Sync + Send,
    smooth_edge_at: impl Fn(usize, &[u32; 2]) -> Value<T, N> + Sync + Send,
) {
    let (this, child, creasing) = sharpness;
    let (coarse, nv) = (t.level, old.len());
    // The old vertices and edges walk a table of their own only to go through `fill_zip`: with
    // the plain `fill` LLVM stopped inlining the smooth closures (cached classic 3: +10 %
    // instructions), as in the averaging step's `gather_primal`.
    if this.is_smooth() {
        fill_zip(old, &t.vertex_offsets[..nv], |v, _| smooth_vertex_at(v));
    } else {
        // Most vertices of a level with curves are smooth (a face-varying mesh has boundaries
        // everywhere its seams run): their mask inline, the rule machinery for the rest.
        fill(old, |v| {
            if this.rule(v).is_smooth() {
                smooth_vertex_at(v)
            } else {
                vertex_point(t, this, child, creasing, v, values, faces)
            }
        });
    }
    if this.has_sharp_edges() {
        // Likewise for edges: the smooth edge point is `edge_point` at sharpness 0.
        fill_zip(edges, t.edge_corners, |e, corners| {
            if this.edge(e) <= 0.0 && corners[1] != NONE {
                smooth_edge_at(e, corners)
            } else {
                edge_point(coarse, this, child, e, nv + e, values, faces)
            }
        });
    } else {
        fill_zip(edges, t.edge_corners, smooth_edge_at);
    }
}

/// The values of a quad level's fine faces in the averaging form of Catmull-Clark (DESIGN.md §1;
/// the paper's degree 3: replication, then one centroid average): each takes the bilinear value
/// at its centre, `(9 p_k + 3 p_(k+1) + 3 p_(k-1) + p_(k+2)) / 16` over its parent's corners
/// `p`, four per coarse face (face `4 f + k` of the fine level is corner `k` of face `f`), in
/// `buffer` (its contents are dropped).
///
/// The mean of a fine vertex's fine faces is then Catmull-Clark's face point, its smooth edge
/// point (an edge of two quads) and its smooth vertex point at valence 4, in exact arithmetic;
/// at other valences the two differ, and those vertices keep the classic mask. Four gathers of
/// a coarse face's corners make its four fine faces, and the edge and face points read those in
/// place: fewer scattered reads than the masks over the coarse level (module documentation).
fn bilinear_children<'b, T: Scalar, const N: usize>(
    t: &Tables,
    values: &[Value<T, N>],
    buffer: &'b mut Vec<Value<T, N>>,
) -> &'b [[Value<T, N>; 4]] {
    let (quads, _) = t.corner_verts.as_chunks::<4>();
    let n = 4 * quads.len();
    buffer.clear();
    if buffer.capacity() < n {
        *buffer = hinted_or_abort(n);
    }
    let (groups, _) = buffer.spare_capacity_mut()[..n].as_chunks_mut::<4>();
    // SAFETY: `[MaybeUninit<V>; 4]` has the layout of `MaybeUninit<[V; 4]>`.
    let groups: &mut [MaybeUninit<[Value<T, N>; 4]>] =
        unsafe { std::slice::from_raw_parts_mut(groups.as_mut_ptr().cast(), groups.len()) };
    let (half, eighth, sixteenth) = (T::from_f64(0.5), T::from_f64(0.125), T::from_f64(0.0625));
    fill_zip(groups, quads, |_, q| {
        let p: [Value<T, N>; 4] = std::array::from_fn(|k| values[q[k] as usize]);
        let centre = scale(add(add(p[0], p[1]), add(p[2], p[3])), sixteenth);
        std::array::from_fn(|k| {
            let sides = add(p[(k + 1) & 3], p[(k + 3) & 3]);
            mad(mad(centre, half, p[k]), eighth, sides)
        })
    });
    // SAFETY: `fill_zip` wrote every group (a panic would have unwound past here).
    unsafe { buffer.set_len(n) };
    buffer.as_chunks::<4>().0
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

/// The smooth edge point `1/4 (a + b + f_0 + f_1)` of an interior edge `e` of two faces, by the
/// mask (on a level that takes the fine faces, [`bilinear_children`] make it instead).
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
