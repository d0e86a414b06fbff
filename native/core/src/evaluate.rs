//! Evaluation: running points or any per-vertex attribute through a [`Plan`]. Each step of
//! degree n is a replication followed by n centroid averages alternating dual -> primal and
//! primal -> dual (DESIGN.md §1), with the 1-D scheme run in lockstep on curve edges (§2).
//! Every pass is a parallel gather in a fixed order, so the output is bitwise the same whatever
//! the number of threads.
//!
//! Performance notes: a step on primal data over a quad level runs its replication and first
//! two averages as one pass over the coarse faces (nothing of the first average is stored); the
//! other passes gather through the coarse level's tables. The two working buffers are sized for
//! the last level once, hinted to use huge pages, and kept in the plan between evaluations
//! ([`Plan::release_buffers`] frees them), so that a cached re-evaluation pays page faults only
//! for the array it returns.

use std::any::Any;
use std::borrow::Cow;
use std::fmt::Debug;
use std::ops::{Add, Mul};
use std::sync::Mutex;

use rayon::prelude::*;

use crate::classic;
use crate::error::Result;
use crate::mesh::check_values;
use crate::plan::{in_pool, CurveVertex, Plan, Rules, Step};
use crate::topology::{with_capacity_hinted, Level, CHUNK, NONE};

/// Floating-point types that points and attributes can be given in: `f32` and `f64`.
pub trait Scalar:
    Copy
    + Send
    + Sync
    + Default
    + PartialOrd
    + Debug
    + Add<Output = Self>
    + Mul<Output = Self>
    + 'static
{
    /// Converts from f64 (weights are computed in f64).
    fn from_f64(x: f64) -> Self;
    /// Converts to f64.
    fn to_f64(self) -> f64;
    /// True unless NaN or infinite.
    fn is_finite(self) -> bool;
}

impl Scalar for f32 {
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
type Value<T, const N: usize> = [T; N];

/// `a + b`, channel by channel.
#[inline(always)]
pub(crate) fn add<T: Scalar, const N: usize>(a: [T; N], b: [T; N]) -> [T; N] {
    std::array::from_fn(|k| a[k] + b[k])
}

/// `s * a`, channel by channel.
#[inline(always)]
pub(crate) fn scale<T: Scalar, const N: usize>(a: [T; N], s: T) -> [T; N] {
    std::array::from_fn(|k| a[k] * s)
}

/// Precomputed `1/k` for centroid averages, so that a centroid is a sum and one multiply.
/// `1/k` as every centroid computes it (the adaptive evaluation relies on the same bits).
#[inline(always)]
pub(crate) fn reciprocal<T: Scalar>(k: usize) -> T {
    match k {
        2 => T::from_f64(0.5),
        4 => T::from_f64(0.25),
        _ => T::from_f64(1.0 / k as f64),
    }
}

/// 1-D data on the curve network: per curve vertex (primal) or per curve edge (dual) of the
/// previous step, or the cage points themselves before the first step.
enum CurveData<T: Scalar, const N: usize> {
    Cage,
    Primal(Vec<Value<T, N>>),
    Dual(Vec<Value<T, N>>),
}

/// Buffers that evaluations through a plan leave behind for the next ones (so that a cached
/// re-evaluation does not pay page faults for its intermediate data): a few vectors of any
/// value type, behind a mutex that is held only to take or give one.
#[derive(Default)]
pub(crate) struct Scratch(Mutex<Vec<Box<dyn Any + Send>>>);

/// Buffers kept at most (the oldest go first).
const SCRATCH_BUFFERS: usize = 2;

impl Debug for Scratch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Scratch")
    }
}

impl Scratch {
    /// An empty vector with room for `capacity` items: a kept one if it is large enough.
    fn take<V: Send + 'static>(&self, capacity: usize) -> Vec<V> {
        let kept = {
            let mut pool = self.0.lock().unwrap_or_else(|e| e.into_inner());
            pool.iter()
                .position(|b| {
                    b.downcast_ref::<Vec<V>>()
                        .is_some_and(|v| v.capacity() >= capacity)
                })
                .map(|i| pool.remove(i))
        };
        match kept.and_then(|b| b.downcast::<Vec<V>>().ok()) {
            Some(mut v) => {
                v.clear();
                *v
            }
            None => with_capacity_hinted(capacity),
        }
    }

    /// Frees every kept buffer.
    fn clear(&self) {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).clear();
    }

    /// Keeps `v` for later evaluations.
    fn give<V: Send + 'static>(&self, v: Vec<V>) {
        if v.capacity() == 0 {
            return;
        }
        let mut pool = self.0.lock().unwrap_or_else(|e| e.into_inner());
        if pool.len() >= SCRATCH_BUFFERS {
            pool.remove(0);
        }
        pool.push(Box::new(v));
    }
}

/// The state of one evaluation while it runs through the levels. Two buffers carry the 2-D
/// data (per vertex and per face of the current level) and are reused from pass to pass.
struct Run<'a, T: Scalar, const N: usize> {
    /// The cage points (compacted numbering): corners keep these.
    cage: &'a [Value<T, N>],
    /// Primal data, valid when `primal`.
    vertices: Cow<'a, [Value<T, N>]>,
    /// Dual data, valid when not `primal`.
    faces: Vec<Value<T, N>>,
    primal: bool,
    curve: CurveData<T, N>,
    /// Where new buffers come from (with room for the largest level), when given.
    scratch: Option<(&'a Scratch, usize)>,
}

impl<'a, T: Scalar, const N: usize> Run<'a, T, N> {
    fn new(cage: &'a [Value<T, N>]) -> Self {
        Run {
            cage,
            vertices: Cow::Borrowed(cage),
            faces: Vec::new(),
            primal: true,
            curve: CurveData::Cage,
            scratch: None,
        }
    }

    /// A buffer for a new array of values.
    fn fresh(&self) -> Vec<Value<T, N>> {
        match self.scratch {
            Some((scratch, capacity)) => scratch.take(capacity),
            None => Vec::new(),
        }
    }

    /// Replication of the 1-D data: each curve half-edge takes the value of its parent.
    fn replicate_curves(&mut self, step: &Step) {
        let curve = match &self.curve {
            CurveData::Cage => step
                .curve_edges
                .iter()
                .map(|e| self.cage[e.source as usize])
                .collect(),
            CurveData::Primal(v) | CurveData::Dual(v) => step
                .curve_edges
                .iter()
                .map(|e| v[e.source as usize])
                .collect(),
        };
        self.curve = CurveData::Dual(curve);
    }

    /// The 1-D half of a dual -> primal average: curve vertices take the midpoint of their two
    /// curve edges, corners their cage point.
    fn curve_to_primal(&mut self, step: &Step) -> Vec<Value<T, N>> {
        let CurveData::Dual(edge_values) = &self.curve else {
            unreachable!("1-D data out of step")
        };
        let half = T::from_f64(0.5);
        step.curve_vertices
            .iter()
            .map(|cv| match cv.edges {
                Some([a, b]) => scale(add(edge_values[a as usize], edge_values[b as usize]), half),
                None => self.cage[cv.vertex as usize],
            })
            .collect()
    }

    /// Curve vertices and corners take (a blend towards) their 1-D values.
    fn finish_primal(&mut self, mut vertices: Vec<Value<T, N>>, step: &Step) {
        let curve = self.curve_to_primal(step);
        for (cv, &value) in step.curve_vertices.iter().zip(&curve) {
            blend(&mut vertices[cv.vertex as usize], value, cv);
        }
        self.vertices = Cow::Owned(vertices);
        self.curve = CurveData::Primal(curve);
        self.primal = true;
    }

    /// A buffer for new primal data: the old one when it is ours, else a fresh one.
    fn take_vertices(&mut self) -> Vec<Value<T, N>> {
        match std::mem::replace(&mut self.vertices, Cow::Borrowed(&[])) {
            Cow::Owned(v) => v,
            Cow::Borrowed(_) => self.fresh(),
        }
    }

    /// Replication followed by the first dual -> primal average, in closed form on the coarse
    /// level (the replicated face values are never stored): an old vertex takes its own point
    /// (primal) or the centroid of its faces (dual), an edge point the midpoint of its ends
    /// (primal) or of its faces (dual), a face point the centroid of its corners (primal) or its
    /// face's point (dual).
    fn first_average(&mut self, coarse: &Level, fine: &Level, step: &Step) {
        self.replicate_curves(step);
        let (nv, ne) = (coarse.num_vertices, coarse.num_edges());
        let mut out = if self.primal {
            match std::mem::take(&mut self.faces) {
                f if f.capacity() == 0 => self.fresh(),
                f => f,
            }
        } else {
            self.take_vertices()
        };
        if self.primal {
            let v = &self.vertices;
            let half = T::from_f64(0.5);
            gather_sections(
                &mut out,
                [nv, ne, fine.num_vertices - nv - ne],
                |w| v[w],
                |e| {
                    let [a, b] = coarse.edge_verts()[e];
                    scale(add(v[a as usize], v[b as usize]), half)
                },
                |f| {
                    let corners = coarse.face_corners(f);
                    let k = corners.len();
                    let sum =
                        corners.fold(zero(), |s, c| add(s, v[coarse.corner_verts[c] as usize]));
                    scale(sum, reciprocal(k))
                },
            );
            // The coarse primal buffer is free now: keep it for later passes.
            if let Cow::Owned(old) = std::mem::replace(&mut self.vertices, Cow::Borrowed(&[])) {
                self.faces = old;
            }
        } else {
            let f = &self.faces;
            let half = T::from_f64(0.5);
            gather_sections(
                &mut out,
                [nv, ne, fine.num_vertices - nv - ne],
                |w| {
                    let corners = coarse.corners_of_vertex(w);
                    let sum = corners
                        .iter()
                        .fold(zero(), |s, &c| add(s, f[coarse.face_of(c as usize)]));
                    scale(sum, reciprocal(corners.len()))
                },
                |e| match coarse.edge_corners()[e] {
                    [c, NONE] => f[coarse.face_of(c as usize)],
                    [c, d] => scale(
                        add(f[coarse.face_of(c as usize)], f[coarse.face_of(d as usize)]),
                        half,
                    ),
                },
                |face| f[face],
            );
        }
        self.finish_primal(out, step);
    }

    /// Replication, the first dual -> primal and the first primal -> dual average of a step whose
    /// data is primal on a quad level, in one pass over the coarse faces: each computes the
    /// nine child points of its face in closed form (as [`Run::first_average`], never stored)
    /// and the centroids of its four child faces. Faces next to curve vertices use the blended
    /// points. The result is bitwise that of the separate passes.
    fn first_average_to_dual(&mut self, coarse: &Level, fine: &Level, step: &Step) {
        debug_assert!(self.primal && coarse.is_quads());
        self.replicate_curves(step);
        let curve = self.curve_to_primal(step);
        let (nv, ne) = (coarse.num_vertices, coarse.num_edges());
        // Coarse faces whose child faces have a curve vertex among their corners.
        let mut touched = vec![
            false;
            if curve.is_empty() {
                0
            } else {
                coarse.num_faces()
            }
        ];
        for cv in &step.curve_vertices {
            let w = cv.vertex as usize;
            if w < nv {
                for &c in coarse.corners_of_vertex(w) {
                    touched[coarse.face_of(c as usize)] = true;
                }
            } else if w < nv + ne {
                for &c in &coarse.edge_corners()[w - nv] {
                    if c != NONE {
                        touched[coarse.face_of(c as usize)] = true;
                    }
                }
            } else {
                touched[w - nv - ne] = true;
            }
        }
        let n = fine.num_faces();
        let mut out = match std::mem::take(&mut self.faces) {
            f if f.capacity() == 0 => self.fresh(),
            f => f,
        };
        if out.len() < n {
            // Written in parallel, so that a new buffer's pages are touched by both threads.
            gather_into(&mut out, n, |_| zero());
        }
        out.truncate(n);
        let v = &self.vertices;
        let half = T::from_f64(0.5);
        let quarter = T::from_f64(0.25);
        let blended = |w: usize, mut p: Value<T, N>| -> Value<T, N> {
            if let Ok(i) = step
                .curve_vertices
                .binary_search_by_key(&(w as u32), |cv| cv.vertex)
            {
                blend(&mut p, curve[i], &step.curve_vertices[i]);
            }
            p
        };
        out.par_chunks_mut(4 * CHUNK)
            .enumerate()
            .for_each(|(chunk, faces)| {
                for (i, quad) in faces.chunks_exact_mut(4).enumerate() {
                    let f = chunk * CHUNK + i;
                    let q = &coarse.corner_verts[4 * f..4 * f + 4];
                    let mut p = [
                        v[q[0] as usize],
                        v[q[1] as usize],
                        v[q[2] as usize],
                        v[q[3] as usize],
                    ];
                    let centre = scale(p.iter().fold(zero(), |s, &x| add(s, x)), reciprocal(4));
                    // m[k]: the edge point of corner k's outgoing edge.
                    let mut m: [Value<T, N>; 4] =
                        std::array::from_fn(|k| scale(add(p[k], p[(k + 1) & 3]), half));
                    let mut centre = centre;
                    if touched.get(f).copied().unwrap_or(false) {
                        for k in 0..4 {
                            p[k] = blended(q[k] as usize, p[k]);
                            let e = coarse.corner_edges()[4 * f + k] as usize;
                            m[k] = blended(nv + e, m[k]);
                        }
                        centre = blended(nv + ne + f, centre);
                    }
                    for (k, out) in quad.iter_mut().enumerate() {
                        let s = add(add(p[k], m[k]), add(centre, m[(k + 3) & 3]));
                        *out = scale(s, quarter);
                    }
                }
            });
        self.faces = out;
        self.curve = CurveData::Dual(curve_to_dual(step, &curve));
        self.primal = false;
    }

    /// Dual -> primal average on `fine`, gathered through the coarse level's tables: face `c` of
    /// `fine` is corner `c` of `coarse`, so an old vertex's faces are its coarse corners, an edge
    /// point's faces the corners on its edge and their successors, a face point's faces the
    /// corners of its face.
    fn average_to_primal(&mut self, coarse: &Level, fine: &Level, step: &Step) {
        let (nv, ne) = (coarse.num_vertices, coarse.num_edges());
        let mut out = self.take_vertices();
        let f = &self.faces;
        let quarter = T::from_f64(0.25);
        let half = T::from_f64(0.5);
        gather_sections(
            &mut out,
            [nv, ne, fine.num_vertices - nv - ne],
            |w| {
                let corners = coarse.corners_of_vertex(w);
                let sum = corners.iter().fold(zero(), |s, &c| add(s, f[c as usize]));
                scale(sum, reciprocal(corners.len()))
            },
            |e| match coarse.edge_corners()[e] {
                [c, NONE] => scale(add(f[c as usize], f[coarse.next(c as usize)]), half),
                [c, d] => {
                    let (c, d) = (c as usize, d as usize);
                    let s = add(add(f[c], f[coarse.next(c)]), add(f[d], f[coarse.next(d)]));
                    scale(s, quarter)
                }
            },
            |face| {
                let corners = coarse.face_corners(face);
                let k = corners.len();
                let sum = f[corners].iter().fold(zero(), |s, &x| add(s, x));
                scale(sum, reciprocal(k))
            },
        );
        self.finish_primal(out, step);
    }

    /// Primal -> dual average on `fine`: each face takes the centroid of its four corners, each
    /// curve edge the midpoint of its two ends.
    fn average_to_dual(&mut self, fine: &Level, step: &Step) {
        let CurveData::Primal(curve) = &self.curve else {
            unreachable!("1-D data out of step")
        };
        let quarter = T::from_f64(0.25);
        if self.faces.capacity() == 0 {
            self.faces = self.fresh();
        }
        let v = &self.vertices;
        gather_into(&mut self.faces, fine.num_faces(), |f| {
            let q = &fine.corner_verts[4 * f..4 * f + 4];
            let s = add(
                add(v[q[0] as usize], v[q[1] as usize]),
                add(v[q[2] as usize], v[q[3] as usize]),
            );
            scale(s, quarter)
        });
        self.curve = CurveData::Dual(curve_to_dual(step, curve));
        self.primal = false;
    }

    /// One full step `coarse -> fine` of the given degree: replicate, then `degree` averages.
    fn step(&mut self, coarse: &Level, fine: &Level, step: &Step, degree: u32) {
        let first = if self.primal && degree >= 2 && coarse.is_quads() {
            self.first_average_to_dual(coarse, fine, step);
            3
        } else {
            self.first_average(coarse, fine, step);
            2
        };
        for a in first..=degree {
            if a % 2 == 1 {
                self.average_to_primal(coarse, fine, step);
            } else {
                self.average_to_dual(fine, step);
            }
        }
    }
}

#[inline(always)]
fn zero<T: Scalar, const N: usize>() -> Value<T, N> {
    [T::default(); N]
}

/// Runs `per_four` (interleaved values of 4 channels in, the same out) on the channels of
/// `values` four at a time (the last group padded with zeros) and interleaves the results back.
pub(crate) fn in_groups_of_four<T: Scalar>(
    values: &[T],
    channels: usize,
    per_four: impl Fn(Vec<T>) -> Vec<T>,
) -> Vec<T> {
    let items = values.len() / channels;
    let mut out: Vec<T> = Vec::new();
    for first in (0..channels).step_by(4) {
        let width = (channels - first).min(4);
        let group: Vec<T> = (0..items)
            .flat_map(|i| {
                (0..4).map(move |k| {
                    if k < width {
                        values[i * channels + first + k]
                    } else {
                        T::default()
                    }
                })
            })
            .collect();
        let result = per_four(group);
        let count = result.len() / 4;
        if out.is_empty() {
            out = vec![T::default(); count * channels];
        }
        for i in 0..count {
            out[i * channels + first..i * channels + first + width]
                .copy_from_slice(&result[4 * i..4 * i + width]);
        }
    }
    out
}

/// The 1-D half of a primal -> dual average: each curve edge takes the midpoint of its ends.
fn curve_to_dual<T: Scalar, const N: usize>(
    step: &Step,
    curve: &[Value<T, N>],
) -> Vec<Value<T, N>> {
    let half = T::from_f64(0.5);
    step.curve_edges
        .iter()
        .map(|e| {
            scale(
                add(curve[e.ends[0] as usize], curve[e.ends[1] as usize]),
                half,
            )
        })
        .collect()
}

/// Sets a vertex to `w * curve + (1 - w) * centroid` (exactly the curve value when w = 1).
#[inline]
fn blend<T: Scalar, const N: usize>(
    vertex: &mut Value<T, N>,
    curve: Value<T, N>,
    cv: &CurveVertex,
) {
    blend_weight(vertex, curve, cv.weight);
}

/// Sets a vertex to `w * curve + (1 - w) * centroid` (`w` the blend weight of a curve vertex).
#[inline]
pub(crate) fn blend_weight<T: Scalar, const N: usize>(
    vertex: &mut Value<T, N>,
    curve: Value<T, N>,
    weight: f64,
) {
    if weight >= 1.0 {
        *vertex = curve;
    } else if weight > 0.0 {
        *vertex = add(
            scale(curve, T::from_f64(weight)),
            scale(*vertex, T::from_f64(1.0 - weight)),
        );
    }
}

/// Fills `out`, rows of `row` values, with `fill(i, row_i)` in parallel chunks of rows (each
/// row written by one task, whatever the number of threads).
fn fill_rows<T: Send>(out: &mut [T], row: usize, fill: impl Fn(usize, &mut [T]) + Sync) {
    if row == 0 {
        return;
    }
    out.par_chunks_mut(row * CHUNK)
        .enumerate()
        .for_each(|(chunk, rows)| {
            for (i, values) in rows.chunks_exact_mut(row).enumerate() {
                fill(chunk * CHUNK + i, values);
            }
        });
}

/// `out[i] = f(i)` for `i < n`, in parallel chunks.
pub(crate) fn gather<V: Send, F: Fn(usize) -> V + Sync + Send>(n: usize, f: F) -> Vec<V> {
    let mut out = Vec::new();
    gather_into(&mut out, n, f);
    out
}

/// As [`gather`], reusing the allocation of `out`.
pub(crate) fn gather_into<V: Send, F: Fn(usize) -> V + Sync + Send>(
    out: &mut Vec<V>,
    n: usize,
    f: F,
) {
    if out.capacity() < n {
        *out = with_capacity_hinted(n);
    }
    (0..n)
        .into_par_iter()
        .with_min_len(CHUNK)
        .map(f)
        .collect_into_vec(out);
}

/// As [`gather_into`] for data on the vertices of a child level, whose three sections (old
/// vertices, edge points, face points, of the given sizes) each get their own function.
fn gather_sections<V: Send>(
    out: &mut Vec<V>,
    sizes: [usize; 3],
    old: impl Fn(usize) -> V + Sync + Send,
    edge: impl Fn(usize) -> V + Sync + Send,
    face: impl Fn(usize) -> V + Sync + Send,
) {
    let n = sizes.iter().sum();
    if out.capacity() < n {
        *out = with_capacity_hinted(n);
    }
    let section = |len: usize| (0..len).into_par_iter().with_min_len(CHUNK);
    section(sizes[0])
        .map(old)
        .chain(section(sizes[1]).map(edge))
        .chain(section(sizes[2]).map(face))
        .collect_into_vec(out);
}

/// What the evaluation hands to the output stage: values at the last level, primal (per vertex)
/// or dual (per face, plus the 1-D values of the last step's curve edges).
pub(crate) enum Final<T: Scalar, const N: usize> {
    Primal(Vec<Value<T, N>>),
    Dual {
        faces: Vec<Value<T, N>>,
        curve_edges: Vec<Value<T, N>>,
    },
}

impl Plan {
    /// Runs `cage` (one value per vertex of `M_0`) through every level. `want_dual` selects the
    /// final kind: the drawing mesh wants primal data, the true dual mesh dual data; the extra
    /// average that converts is the paper's drawing step.
    pub(crate) fn run<T: Scalar, const N: usize>(
        &self,
        cage: &[Value<T, N>],
        want_dual: bool,
    ) -> Final<T, N> {
        let degree = self.options().degree;
        let levels = self.levels_as_built();
        if let Some(catmark) = self.catmark() {
            // Classic Catmull-Clark (crate::classic): primal data all the way, between two
            // buffers kept in the plan (the result is one of them; the other goes back).
            let capacity = levels.last().map_or(0, |l| l.num_vertices);
            let mut points: Vec<Value<T, N>> = self.scratch().take(capacity);
            let mut spare: Vec<Value<T, N>> = self.scratch().take(capacity);
            points.extend_from_slice(cage);
            for j in 0..self.steps().len() {
                catmark.step_into(j, &levels[j], &levels[j + 1], &points, &mut spare);
                std::mem::swap(&mut points, &mut spare);
            }
            self.scratch().give(spare);
            let Some(last) = self.steps().last().filter(|_| want_dual) else {
                return Final::Primal(points);
            };
            let mut run = Run::new(cage);
            run.curve = CurveData::Primal(
                last.curve_vertices
                    .iter()
                    .map(|cv| points[cv.vertex as usize])
                    .collect(),
            );
            run.vertices = Cow::Owned(points);
            run.average_to_dual(&levels[levels.len() - 1], last);
            let CurveData::Dual(curve_edges) = run.curve else {
                unreachable!("dual 1-D data")
            };
            return Final::Dual {
                faces: run.faces,
                curve_edges,
            };
        }
        let doo_sabin = self.options().rules == Rules::Classic && degree == 2;
        let mut run = Run::new(cage);
        if let Some(last) = levels.last().filter(|_| levels.len() > 1) {
            let curve = self.steps().last().map_or(0, |s| s.curve_edges.len());
            let capacity = last.num_vertices.max(last.num_faces() + curve);
            run.scratch = Some((self.scratch(), capacity));
        }
        for (j, step) in self.steps().iter().enumerate() {
            if doo_sabin {
                // Classic Doo-Sabin: the averaged faces away from curves are replaced.
                let before = if run.primal {
                    run.vertices.to_vec()
                } else {
                    run.faces.clone()
                };
                let primal = run.primal;
                run.step(&levels[j], &levels[j + 1], step, degree);
                run.faces = classic::doo_sabin_step(&levels[j], step, &before, primal, &run.faces);
            } else {
                run.step(&levels[j], &levels[j + 1], step, degree);
            }
        }
        if let Some(last) = self.steps().last() {
            let (coarse, fine) = (&levels[levels.len() - 2], &levels[levels.len() - 1]);
            match (run.primal, want_dual) {
                (true, true) => run.average_to_dual(fine, last),
                (false, false) => run.average_to_primal(coarse, fine, last),
                _ => {}
            }
        }
        if run.primal {
            self.scratch().give(std::mem::take(&mut run.faces));
            return Final::Primal(run.vertices.into_owned());
        }
        if let Cow::Owned(v) = std::mem::replace(&mut run.vertices, Cow::Borrowed(&[])) {
            self.scratch().give(v);
        }
        let CurveData::Dual(curve_edges) = run.curve else {
            unreachable!("dual 1-D data")
        };
        Final::Dual {
            faces: run.faces,
            curve_edges,
        }
    }

    /// Frees the working buffers that evaluations keep in the plan for the next ones (up to two
    /// arrays of the last level's size); the next evaluation allocates them again.
    pub fn release_buffers(&self) {
        self.scratch().clear();
    }

    /// Evaluates per-vertex values of the cage (`channels` interleaved values per cage vertex,
    /// in the user's numbering) and returns the values at the output vertices, interleaved.
    pub fn evaluate<T: Scalar>(&self, values: &[T], channels: usize) -> Result<Vec<T>> {
        check_values(values, channels, self.num_input_vertices())?;
        Ok(in_pool(|| match channels {
            1 => self.evaluate_n::<T, 1>(values),
            2 => self.evaluate_n::<T, 2>(values),
            3 => self.evaluate_n::<T, 3>(values),
            4 => self.evaluate_n::<T, 4>(values),
            _ => in_groups_of_four(values, channels, |group| self.evaluate_n::<T, 4>(&group)),
        }))
    }

    fn evaluate_n<T: Scalar, const N: usize>(&self, values: &[T]) -> Vec<T> {
        let (points, _) = values.as_chunks::<N>();
        let compact: Cow<[Value<T, N>]> = match self.vertex_map() {
            None => Cow::Borrowed(points),
            Some(map) => Cow::Owned(map.iter().map(|&v| points[v as usize]).collect()),
        };
        self.finish(self.run(&compact, self.wants_dual()))
            .into_flattened()
    }

    /// Evaluates face-varying values (one per corner of the cage, e.g. UVs) with linear
    /// (bilinear per face) interpolation and returns one value per corner of the output faces.
    pub fn evaluate_face_varying<T: Scalar>(
        &self,
        values: &[T],
        channels: usize,
    ) -> Result<Vec<T>> {
        let levels = self.levels_as_built();
        check_values(values, channels, levels[0].num_corners())?;
        let half = T::from_f64(0.5);
        let current = in_pool(|| {
            let mut current: Vec<T> = values.to_vec();
            for level in &levels[..levels.len() - 1] {
                let mut centres = vec![T::default(); level.num_faces() * channels];
                fill_rows(&mut centres, channels, |f, centre| {
                    let corners = level.face_corners(f);
                    let w = reciprocal::<T>(corners.len());
                    for (k, out) in centre.iter_mut().enumerate() {
                        let sum = corners
                            .clone()
                            .fold(T::default(), |s, c| s + current[c * channels + k]);
                        *out = sum * w;
                    }
                });
                // Corner c of this level becomes the quad c, midpoint(c, next), centre,
                // midpoint(prev, c) of the next one.
                let mut next = vec![T::default(); 4 * level.num_corners() * channels];
                fill_rows(&mut next, 4 * channels, |c, quad| {
                    let at = |c: usize, k: usize| current[c * channels + k];
                    let (n, p) = (level.next(c), level.prev(c));
                    let centre = &centres[level.face_of(c) * channels..][..channels];
                    let (own, rest) = quad.split_at_mut(channels);
                    let (to_next, rest) = rest.split_at_mut(channels);
                    let (middle, from_prev) = rest.split_at_mut(channels);
                    for k in 0..channels {
                        own[k] = at(c, k);
                        to_next[k] = (at(c, k) + at(n, k)) * half;
                        middle[k] = centre[k];
                        from_prev[k] = (at(p, k) + at(c, k)) * half;
                    }
                });
                current = next;
            }
            current
        });
        Ok(self.face_varying_output(current, channels))
    }
}

impl Plan {
    /// One step `M_j -> M_{j+1}` (`j >= 1`) applied to arbitrary scalar data of the kind the
    /// scheme carries at level `j` (per vertex for odd degrees, per face for even ones); the
    /// analysis builds subdivision matrices from it. Curve 1-D data is read off the 2-D data
    /// (vertex values, or the value of an edge's face); corners are pinned at zero.
    pub(crate) fn step_scalar(&self, j: usize, data: &[f64]) -> Vec<f64> {
        let (levels, steps) = (self.levels(), self.steps());
        assert!(
            j >= 1 && j < steps.len(),
            "step_scalar needs 1 <= j < levels"
        );
        let (coarse, previous) = (&levels[j], &steps[j - 1]);
        let cage = vec![[0.0f64]; levels[0].num_vertices];
        let values: Vec<[f64; 1]> = data.iter().map(|&x| [x]).collect();
        let primal = self.options().degree % 2 == 1;
        let mut run = Run::new(&cage);
        run.primal = primal;
        if primal {
            run.curve = CurveData::Primal(
                previous
                    .curve_vertices
                    .iter()
                    .map(|cv| values[cv.vertex as usize])
                    .collect(),
            );
            run.vertices = Cow::Owned(values);
        } else {
            let face_of_edge =
                |e: u32| coarse.face_of(coarse.edge_corners()[e as usize][0] as usize);
            run.curve = CurveData::Dual(
                previous
                    .curve_edges
                    .iter()
                    .map(|ce| values[face_of_edge(ce.edge)])
                    .collect(),
            );
            run.faces = values;
        }
        run.step(coarse, &levels[j + 1], &steps[j], self.options().degree);
        let out = if run.primal {
            run.vertices.into_owned()
        } else {
            run.faces
        };
        out.into_iter().map(|[x]| x).collect()
    }
}

#[cfg(test)]
mod tests {
    use crate::{Cage, Options, Plan, Rules};

    /// Kept buffers change nothing: repeated evaluations (f32 and f64, with and without the
    /// buffers of the previous ones) give the same bits.
    #[test]
    fn kept_buffers_do_not_change_results() {
        let points = [
            0.0f64, 0.0, 1.0, -1.0, -1.0, 0.0, 1.0, -1.0, 0.0, 1.0, 1.0, 0.0, -1.0, 1.0, 0.0,
        ];
        let cage =
            Cage::from_indices(5, &[3, 3, 3, 3], &[0, 1, 2, 0, 2, 3, 0, 3, 4, 0, 4, 1]).unwrap();
        let classic = (3, Rules::Classic);
        for (degree, rules) in (1..=5).map(|d| (d, Rules::Averaging)).chain([classic]) {
            let options = Options {
                degree,
                levels: 3,
                rules,
                ..Options::default()
            };
            let plan = Plan::new(&cage, &options).unwrap();
            let first = plan.evaluate(&points, 3).unwrap();
            let first32 = plan.evaluate(&points.map(|x| x as f32), 3).unwrap();
            for _ in 0..2 {
                assert_eq!(plan.evaluate(&points, 3).unwrap(), first);
                assert_eq!(
                    plan.evaluate(&points.map(|x| x as f32), 3).unwrap(),
                    first32
                );
            }
            plan.release_buffers();
            assert_eq!(plan.evaluate(&points, 3).unwrap(), first);
        }
    }
}
