//! Classic rule sets on the same levels as the averaging schemes (DESIGN.md §3):
//!
//! - degree 3: Catmull-Clark exactly as OpenSubdiv's `catmark` scheme (Sdc `catmarkScheme.h`,
//!   `scheme.h`, `crease.cpp`, Vtr `refinement.cpp`): smooth, dart, crease and corner vertex
//!   rules, n-gons, infinitely sharp and semi-sharp edges and vertices, creasing method uniform
//!   or Chaikin, sharpness decremented per level with the fractional blend of parent and child
//!   masks where a rule changes between levels, and limit positions;
//! - degree 2: the original Doo-Sabin weights `a_0 = 1/4 + 5/(4k)`,
//!   `a_i = (3 + 2 cos(2 i pi / k)) / (4k)` at every face of `M_{j+1}` whose coarse vertex is
//!   not on the step's curve network; faces at curve vertices and corners keep the averaging
//!   scheme's values, so boundaries and creases are treated as in the averaging scheme.
//!
//! [`Catmark::new`] lays out the sharpness of every level from the cage's (one call from
//! `Plan::new`); [`Catmark::step`] refines per-vertex data one level, [`Catmark::limit`] gives
//! limit positions at the vertices of a quad level and [`doo_sabin_step`] replaces the averaged
//! faces of one degree-2 step. All are parallel gathers over fixed chunks (bitwise the same
//! whatever the number of threads).
//!
//! Sharpness follows OpenSubdiv: 0 is smooth, [`SHARPNESS_INFINITE`] (10) and above infinitely
//! sharp; boundary edges are infinitely sharp.

use crate::evaluate::{add, gather, scale, Scalar};
use crate::plan::Step;
use crate::topology::{with_capacity_hinted, Level, CHUNK, NONE};
use rayon::prelude::*;
use std::mem::MaybeUninit;

/// Sharpness of an infinitely sharp edge or vertex (OpenSubdiv's `SHARPNESS_INFINITE`).
pub const SHARPNESS_INFINITE: f32 = 10.0;

/// The subdivision rule of a vertex (OpenSubdiv's `Crease::Rule`), from its sharpness and the
/// number of sharp edges at it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(u8)]
pub enum Rule {
    /// No sharp edge.
    #[default]
    Smooth = 1,
    /// One sharp edge (smooth masks).
    Dart = 2,
    /// Two sharp edges.
    Crease = 4,
    /// Sharp vertex or more than two sharp edges.
    Corner = 8,
}

impl Rule {
    /// True for the rules that use the smooth masks.
    #[inline]
    pub fn is_smooth(self) -> bool {
        matches!(self, Rule::Smooth | Rule::Dart)
    }
}

/// How semi-sharp edge sharpness decreases from level to level.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Creasing {
    /// Minus one per level (OpenSubdiv's `CREASE_UNIFORM`, Blender's choice).
    #[default]
    Uniform,
    /// Chaikin: each half takes 3/4 of its own sharpness and 1/4 of the mean of the other
    /// semi-sharp edges at its vertex, minus one (OpenSubdiv's `CREASE_CHAIKIN`).
    Chaikin,
}

/// True if `s` is sharp (positive).
#[inline]
fn is_sharp(s: f32) -> bool {
    s > 0.0
}

/// True if `s` is semi-sharp (positive and finite).
#[inline]
fn is_semi_sharp(s: f32) -> bool {
    s > 0.0 && s < SHARPNESS_INFINITE
}

/// Sharpness one level down (OpenSubdiv's `Crease::decrementSharpness`).
#[inline]
pub fn decrement(s: f32) -> f32 {
    if s <= 0.0 {
        0.0
    } else if s >= SHARPNESS_INFINITE {
        SHARPNESS_INFINITE
    } else if s > 1.0 {
        s - 1.0
    } else {
        0.0
    }
}

/// Sharpness of the half of an edge of sharpness `s` at a vertex whose edges have the
/// sharpness values `incident` (the edge itself included): OpenSubdiv's
/// `Crease::SubdivideEdgeSharpnessAtVertex`.
pub fn subdivide_edge_sharpness(s: f32, incident: &[f32], creasing: Creasing) -> f32 {
    if creasing == Creasing::Uniform || incident.len() < 2 {
        return decrement(s);
    }
    if s <= 0.0 {
        return 0.0;
    }
    if s >= SHARPNESS_INFINITE {
        return SHARPNESS_INFINITE;
    }
    let (mut sum, mut count) = (0.0f32, 0u32);
    for &x in incident {
        if is_semi_sharp(x) {
            sum += x;
            count += 1;
        }
    }
    let mut s = s;
    if count > 1 {
        let average = (sum - s) / (count - 1) as f32;
        s = 0.75 * s + 0.25 * average;
    }
    s -= 1.0;
    if is_sharp(s) {
        s
    } else {
        0.0
    }
}

/// The rule of a vertex of sharpness `vertex` with `sharp_edges` sharp edges (OpenSubdiv's
/// `Crease::DetermineVertexVertexRule`).
#[inline]
pub fn vertex_rule(vertex: f32, sharp_edges: usize) -> Rule {
    if is_sharp(vertex) {
        return Rule::Corner;
    }
    match sharp_edges {
        0 => Rule::Smooth,
        1 => Rule::Dart,
        2 => Rule::Crease,
        _ => Rule::Corner,
    }
}

/// Weight of the parent mask when a vertex changes rule between levels (OpenSubdiv's
/// `Crease::ComputeFractionalWeightAtVertex`): `parent` and `child` are the sharpness values of
/// its edges at the two levels, in the same order.
pub fn fractional_weight(
    parent_vertex: f32,
    child_vertex: f32,
    parent: &[f32],
    child: &[f32],
    creasing: Creasing,
) -> f32 {
    let (mut count, mut sum) = (0u32, 0.0f32);
    if is_sharp(parent_vertex) && !is_sharp(child_vertex) {
        count = 1;
        sum = parent_vertex;
    }
    for (&p, &c) in parent.iter().zip(child) {
        let transition = match creasing {
            Creasing::Uniform => is_sharp(p) && p <= 1.0,
            Creasing::Chaikin => is_sharp(p) && !is_sharp(c),
        };
        if transition {
            sum += p;
            count += 1;
        }
    }
    if count == 0 {
        return 0.0;
    }
    (sum / count as f32).min(1.0)
}

/// Doo-Sabin weight `a_i` of a face of `k` corners (`i = 0` is the corner's own point).
pub fn doo_sabin_weight(i: usize, k: usize) -> f64 {
    let kf = k as f64;
    if i == 0 {
        0.25 + 5.0 / (4.0 * kf)
    } else {
        (3.0 + 2.0 * (2.0 * std::f64::consts::PI * i as f64 / kf).cos()) / (4.0 * kf)
    }
}

/// The edges at vertex `v`: the outgoing edge of each of its corners, and the incoming edge of
/// a corner when that edge is on the boundary (so that every edge comes once).
#[inline]
pub fn vertex_edges(level: &Level, v: usize) -> impl Iterator<Item = u32> + '_ {
    level.corners_of_vertex(v).iter().flat_map(move |&c| {
        let c = c as usize;
        let incoming = level.corner_edges()[level.prev(c)];
        let extra = level
            .is_boundary_edge(incoming as usize)
            .then_some(incoming);
        std::iter::once(level.corner_edges()[c]).chain(extra)
    })
}

/// The other end of edge `e` from `v`.
#[inline]
fn other_end(level: &Level, e: u32, v: usize) -> usize {
    let [a, b] = level.edge_verts()[e as usize];
    if a as usize == v {
        b as usize
    } else {
        a as usize
    }
}

/// The half (child edge at the next level) of edge `e` that contains its end `v`.
#[inline]
fn child_half(level: &Level, e: u32, v: usize) -> usize {
    2 * e as usize + (level.edge_verts()[e as usize][0] as usize != v) as usize
}

/// Sharpness and rules of one level. Empty tables mean "all smooth" (no sharp edge or vertex).
#[derive(Debug, Clone, Default)]
pub struct LevelSharpness {
    /// Sharpness of each edge (empty: all zero).
    pub edges: Vec<f32>,
    /// Sharpness of each vertex (empty: all zero).
    pub vertices: Vec<f32>,
    /// Rule of each vertex (empty: all smooth).
    pub rules: Vec<Rule>,
}

impl LevelSharpness {
    /// Sharpness of edge `e`.
    #[inline]
    pub fn edge(&self, e: usize) -> f32 {
        if self.edges.is_empty() {
            0.0
        } else {
            self.edges[e]
        }
    }

    /// Sharpness of vertex `v`.
    #[inline]
    pub fn vertex(&self, v: usize) -> f32 {
        if self.vertices.is_empty() {
            0.0
        } else {
            self.vertices[v]
        }
    }

    /// Rule of vertex `v`.
    #[inline]
    pub fn rule(&self, v: usize) -> Rule {
        if self.rules.is_empty() {
            Rule::Smooth
        } else {
            self.rules[v]
        }
    }

    /// Rules from the sharpness tables.
    fn classify(&mut self, level: &Level) {
        if self.edges.is_empty() && self.vertices.is_empty() {
            self.rules = Vec::new();
            return;
        }
        let this = &*self;
        let rules = gather(level.num_vertices, |v| {
            let sharp = vertex_edges(level, v)
                .filter(|&e| is_sharp(this.edge(e as usize)))
                .count();
            vertex_rule(this.vertex(v), sharp)
        });
        self.rules = rules;
    }
}

/// Catmull-Clark as OpenSubdiv's `catmark`: the sharpness and rules of every level of a plan.
#[derive(Debug, Clone, Default)]
pub struct Catmark {
    /// How semi-sharp sharpness decreases.
    pub creasing: Creasing,
    /// Sharpness and rules of `M_0..M_L`.
    pub levels: Vec<LevelSharpness>,
}

/// Up to this valence the per-vertex sharpness lists live on the stack.
const STACK_VALENCE: usize = 32;

/// Calls `f` with the sharpness of the edges at `v` (in [`vertex_edges`] order) at this level
/// and, when `child` is given, of their halves at `v` one level down.
fn with_edge_sharpness<R>(
    level: &Level,
    v: usize,
    this: &LevelSharpness,
    child: Option<&LevelSharpness>,
    f: impl FnOnce(&[f32], &[f32]) -> R,
) -> R {
    let k = vertex_edges(level, v).count();
    let fill = |p: &mut [f32], c: &mut [f32]| {
        for (i, e) in vertex_edges(level, v).enumerate() {
            p[i] = this.edge(e as usize);
            if let Some(child) = child {
                c[i] = child.edge(child_half(level, e, v));
            }
        }
    };
    if k <= STACK_VALENCE {
        let (mut p, mut c) = ([0.0f32; STACK_VALENCE], [0.0f32; STACK_VALENCE]);
        fill(&mut p[..k], &mut c[..k]);
        f(&p[..k], &c[..k])
    } else {
        let (mut p, mut c) = (vec![0.0f32; k], vec![0.0f32; k]);
        fill(&mut p, &mut c);
        f(&p, &c)
    }
}

#[inline(always)]
fn zero<T: Scalar, const N: usize>() -> [T; N] {
    [T::default(); N]
}

/// `acc + w * x`.
#[inline(always)]
fn mad<T: Scalar, const N: usize>(acc: [T; N], w: T, x: [T; N]) -> [T; N] {
    std::array::from_fn(|k| acc[k] + w * x[k])
}

/// `p * a + (1 - p) * b`.
#[inline(always)]
fn lerp<T: Scalar, const N: usize>(a: [T; N], b: [T; N], p: f64) -> [T; N] {
    add(scale(a, T::from_f64(p)), scale(b, T::from_f64(1.0 - p)))
}

impl Catmark {
    /// Lays out sharpness and rules of every level: `edge_sharpness` gives the sharpness of each
    /// edge of `levels[0]` (boundary edges included; values at or above
    /// [`SHARPNESS_INFINITE`], or infinite, are infinitely sharp), `vertex_sharpness` the sharp
    /// vertices of `levels[0]` (corners, with the topological corners of edge-and-corner
    /// boundary interpolation among them).
    pub fn new(
        levels: &[Level],
        edge_sharpness: &[f32],
        vertex_sharpness: &[(u32, f32)],
        creasing: Creasing,
    ) -> Catmark {
        let clamp = |s: f32| {
            if s >= SHARPNESS_INFINITE {
                SHARPNESS_INFINITE
            } else if s > 0.0 {
                s
            } else {
                0.0
            }
        };
        let mut first = LevelSharpness::default();
        if edge_sharpness.iter().any(|&s| s > 0.0) {
            first.edges = edge_sharpness.iter().map(|&s| clamp(s)).collect();
        }
        if vertex_sharpness.iter().any(|t| t.1 > 0.0) {
            first.vertices = vec![0.0; levels[0].num_vertices];
            for &(v, s) in vertex_sharpness {
                let slot = &mut first.vertices[v as usize];
                *slot = slot.max(clamp(s));
            }
        }
        first.classify(&levels[0]);
        let mut out = Vec::with_capacity(levels.len());
        out.push(first);
        for j in 1..levels.len() {
            let next = Self::refine_sharpness(&levels[j - 1], &levels[j], &out[j - 1], creasing);
            out.push(next);
        }
        Catmark {
            creasing,
            levels: out,
        }
    }

    /// Sharpness and rules of `fine` from those of `coarse`: halves of sharp edges decrease
    /// (uniform or Chaikin, per end), interior edges are smooth, old vertices decrease, new
    /// vertices are smooth.
    fn refine_sharpness(
        coarse: &Level,
        fine: &Level,
        this: &LevelSharpness,
        creasing: Creasing,
    ) -> LevelSharpness {
        let mut next = LevelSharpness::default();
        let ne = coarse.num_edges();
        if !this.edges.is_empty() {
            next.edges = gather(fine.num_edges(), |child| {
                if child >= 2 * ne {
                    return 0.0;
                }
                let e = child / 2;
                let s = this.edges[e];
                if s <= 0.0 {
                    return 0.0;
                }
                match creasing {
                    Creasing::Uniform => decrement(s),
                    Creasing::Chaikin => {
                        let v = coarse.edge_verts()[e][child & 1] as usize;
                        with_edge_sharpness(coarse, v, this, None, |p, _| {
                            subdivide_edge_sharpness(s, p, creasing)
                        })
                    }
                }
            });
            if next.edges.iter().all(|&s| s <= 0.0) {
                next.edges = Vec::new();
            }
        }
        if !this.vertices.is_empty() {
            let nv = coarse.num_vertices;
            next.vertices = gather(fine.num_vertices, |w| {
                if w < nv {
                    decrement(this.vertices[w])
                } else {
                    0.0
                }
            });
            if next.vertices.iter().all(|&s| s <= 0.0) {
                next.vertices = Vec::new();
            }
        }
        if !(next.edges.is_empty() && next.vertices.is_empty()) {
            // The rules need the edges at each vertex (a plan's last level has no edge or
            // vertex -> corner tables yet).
            fine.complete_from(coarse);
        }
        next.classify(fine);
        next
    }

    /// True when no level has a sharp edge or vertex.
    pub fn is_smooth(&self) -> bool {
        self.levels.iter().all(|l| l.rules.is_empty())
    }

    /// One Catmull-Clark step `levels[j] -> levels[j + 1]` of per-vertex data: face points
    /// (centroids), edge points (smooth, crease or the fractional blend of the two), vertex
    /// points (smooth, crease or corner masks, blended where the rule changes).
    ///
    /// The face points are written straight into the last section of the output (the fine
    /// level numbers old vertices, then edge points, then face points), then the vertex and
    /// edge points read them from there: one allocation per step, no copy, and no per-vertex
    /// branch on the section.
    pub fn step<T: Scalar, const N: usize>(
        &self,
        j: usize,
        coarse: &Level,
        fine: &Level,
        values: &[[T; N]],
    ) -> Vec<[T; N]> {
        let mut out = Vec::new();
        self.step_into(j, coarse, fine, values, &mut out);
        out
    }

    /// As [`Catmark::step`], into `out` (its previous contents are dropped; its allocation is
    /// reused when large enough, which spares the page faults of a fresh one: a caller that
    /// keeps two buffers and swaps them level by level allocates nothing on a cached run).
    pub fn step_into<T: Scalar, const N: usize>(
        &self,
        j: usize,
        coarse: &Level,
        fine: &Level,
        values: &[[T; N]],
        out: &mut Vec<[T; N]>,
    ) {
        let (nv, ne) = (coarse.num_vertices, coarse.num_edges());
        let n = fine.num_vertices;
        out.clear();
        if out.capacity() < n {
            *out = with_capacity_hinted(n);
        }
        let (head, faces) = out.spare_capacity_mut()[..n].split_at_mut(nv + ne);
        let quads = coarse.is_quads();
        fill(faces, |f| {
            if quads {
                let c = 4 * f;
                // The additions of the general case below, in the same order.
                let at = |i: usize| values[coarse.corner_verts[c + i] as usize];
                let sum = add(add(add(at(0), at(1)), at(2)), at(3));
                return scale(sum, T::from_f64(0.25));
            }
            let corners = coarse.face_corners(f);
            let w = T::from_f64(1.0 / corners.len() as f64);
            let sum = corners.fold(zero(), |s, c| {
                add(s, values[coarse.corner_verts[c] as usize])
            });
            scale(sum, w)
        });
        // SAFETY: `fill` wrote every item of `faces` (a panic would have unwound past here),
        // and `MaybeUninit<V>` has the layout of `V`.
        let faces: &[[T; N]] =
            unsafe { &*(faces as *const [MaybeUninit<[T; N]>] as *const [[T; N]]) };
        let (old, edges) = head.split_at_mut(nv);
        let (this, child) = (&self.levels[j], &self.levels[j + 1]);
        if this.rules.is_empty() {
            fill(old, |v| smooth_vertex(coarse, v, values, faces));
        } else {
            fill(old, |v| {
                self.vertex_point(coarse, this, child, v, values, faces)
            });
        }
        if this.edges.is_empty() {
            fill(edges, |e| smooth_edge(coarse, e, values, faces));
        } else {
            fill(edges, |e| {
                edge_point(coarse, this, child, e, nv + e, values, faces)
            });
        }
        // SAFETY: the three sections, which `fill` wrote completely, are the first `n` items.
        unsafe { out.set_len(n) };
    }

    /// The vertex point of old vertex `v` (OpenSubdiv's `ComputeVertexVertexMask` with the
    /// parent and child rules known).
    fn vertex_point<T: Scalar, const N: usize>(
        &self,
        coarse: &Level,
        this: &LevelSharpness,
        child: &LevelSharpness,
        v: usize,
        values: &[[T; N]],
        faces: &[[T; N]],
    ) -> [T; N] {
        let parent_rule = this.rule(v);
        if parent_rule.is_smooth() {
            return smooth_vertex(coarse, v, values, faces);
        }
        let parent_mask = match parent_rule {
            Rule::Crease => crease_vertex(coarse, v, values, |e| this.edge(e as usize)),
            _ => values[v],
        };
        let child_rule = child.rule(v);
        if child_rule == parent_rule {
            return parent_mask;
        }
        let child_mask = match child_rule {
            Rule::Smooth | Rule::Dart => smooth_vertex(coarse, v, values, faces),
            Rule::Crease => {
                crease_vertex(coarse, v, values, |e| child.edge(child_half(coarse, e, v)))
            }
            Rule::Corner => values[v],
        };
        let p = with_edge_sharpness(coarse, v, this, Some(child), |pe, ce| {
            fractional_weight(this.vertex(v), child.vertex(v), pe, ce, self.creasing)
        });
        lerp(parent_mask, child_mask, p as f64)
    }

    /// Limit positions at the vertices of `levels[j]`, which must be a quad level (`j >= 1`):
    /// the regular mask `[1 4 1]^T [1 4 1] / 36`, the extraordinary smooth mask with weights
    /// `1/(k(k+5))` on the opposite corners, `4/(k(k+5))` on the edge neighbours, crease
    /// `(1/6, 2/3, 1/6)` along the crease, corners interpolated (OpenSubdiv's limit masks; at a
    /// level where a semi-sharp feature is still sharp, its current rule is used as OpenSubdiv's
    /// `PrimvarRefiner::Limit` does). An interior vertex of valence 2 takes the general smooth
    /// mask (its true limit, which Blender's limit surface gives), where Sdc's limit mask would
    /// keep the vertex itself. At an infinitely sharp dart the smooth mask is not the limit
    /// (Sdc uses it anyway; Blender's limit surface is the true limit): there the mask is the
    /// dominant left eigenvector of the dart's 1-ring subdivision matrix ([`dart_limit_mask`]).
    pub fn limit<T: Scalar, const N: usize>(
        &self,
        j: usize,
        level: &Level,
        values: &[[T; N]],
    ) -> Vec<[T; N]> {
        assert!(level.is_quads(), "limit positions need a quad level");
        let this = &self.levels[j];
        gather(level.num_vertices, |v| match this.rule(v) {
            Rule::Dart
                if vertex_edges(level, v).any(|e| this.edge(e as usize) >= SHARPNESS_INFINITE) =>
            {
                // A dart for good (a semi-sharp dart becomes smooth later: smooth mask).
                dart_limit(level, this, v, values)
            }
            Rule::Smooth | Rule::Dart => {
                let corners = level.corners_of_vertex(v);
                let k = corners.len();
                let (fw, ew, vw) = if k == 4 {
                    (1.0 / 36.0, 1.0 / 9.0, 4.0 / 9.0)
                } else {
                    let kf = k as f64;
                    let f = 1.0 / (kf * (kf + 5.0));
                    (f, 4.0 * f, 1.0 - kf * 5.0 * f)
                };
                let mut sum = zero();
                let mut opposite = zero();
                for &c in corners {
                    let n = level.next(c as usize);
                    sum = add(sum, values[level.corner_verts[n] as usize]);
                    opposite = add(opposite, values[level.corner_verts[level.next(n)] as usize]);
                }
                let out = scale(values[v], T::from_f64(vw));
                let out = mad(out, T::from_f64(ew), sum);
                mad(out, T::from_f64(fw), opposite)
            }
            Rule::Crease => {
                let mut ends = [v; 2];
                let mut found = 0;
                for e in vertex_edges(level, v) {
                    if found < 2 && is_sharp(this.edge(e as usize)) {
                        ends[found] = other_end(level, e, v);
                        found += 1;
                    }
                }
                let out = scale(values[v], T::from_f64(2.0 / 3.0));
                mad(
                    out,
                    T::from_f64(1.0 / 6.0),
                    add(values[ends[0]], values[ends[1]]),
                )
            }
            Rule::Corner => values[v],
        })
    }
}

/// The limit of an infinitely sharp dart `v` of a quad level from its 1-ring.
fn dart_limit<T: Scalar, const N: usize>(
    level: &Level,
    this: &LevelSharpness,
    v: usize,
    values: &[[T; N]],
) -> [T; N] {
    // The ring in rotation order: corner c_i has edge neighbour e_i = next(c_i), opposite
    // f_i = next(next(c_i)), and face i is (v, e_i, f_i, e_{i+1}).
    let k = level.corners_of_vertex(v).len();
    let mut ring = Vec::with_capacity(k);
    let mut at = level.corners_of_vertex(v)[0] as usize;
    for _ in 0..k {
        ring.push(at);
        let p = level.prev(at);
        let [x, y] = level.edge_corners()[level.corner_edges()[p] as usize];
        at = if x as usize == p { y } else { x } as usize;
        if at == NONE as usize {
            // Not a closed ring (cannot happen for a dart): keep the vertex.
            return values[v];
        }
    }
    let sharp = ring
        .iter()
        .position(|&c| is_sharp(this.edge(level.corner_edges()[c] as usize)))
        .unwrap_or(0);
    let mask = dart_limit_mask(k, sharp);
    let mut out = scale(values[v], T::from_f64(mask[0]));
    for (i, &c) in ring.iter().enumerate() {
        let n = level.next(c);
        out = mad(
            out,
            T::from_f64(mask[1 + i]),
            values[level.corner_verts[n] as usize],
        );
        out = mad(
            out,
            T::from_f64(mask[1 + k + i]),
            values[level.corner_verts[level.next(n)] as usize],
        );
    }
    out
}

/// Limit mask of an infinitely sharp dart of valence `k` whose sharp edge is edge `sharp` of
/// its 1-ring: weights on `(v, e_0..e_{k-1}, f_0..f_{k-1})` (edge neighbours and opposite
/// corners, face `i` being `(v, e_i, f_i, e_{i+1})`), the left eigenvector of eigenvalue 1 of
/// the 1-ring's Catmull-Clark matrix (smooth vertex rule, midpoint on the sharp edge), found
/// by power iteration from the smooth limit mask.
pub fn dart_limit_mask(k: usize, sharp: usize) -> Vec<f64> {
    let n = 2 * k + 1;
    let kf = k as f64;
    // Rows of S: new ring values from old ones.
    let mut s = vec![0.0f64; n * n];
    let face = |s: &mut [f64], row: usize, i: usize, w: f64| {
        // w * F_i, F_i = (v + e_i + f_i + e_{i+1}) / 4.
        for col in [0, 1 + i, 1 + k + i, 1 + (i + 1) % k] {
            s[row * n + col] += w / 4.0;
        }
    };
    s[0] = (kf - 2.0) / kf;
    for i in 0..k {
        s[1 + i] += 1.0 / (kf * kf);
        face(&mut s, 0, i, 1.0 / (kf * kf));
        let row = 1 + i;
        if i == sharp {
            s[row * n] += 0.5;
            s[row * n + 1 + i] += 0.5;
        } else {
            s[row * n] += 0.25;
            s[row * n + 1 + i] += 0.25;
            face(&mut s, row, (i + k - 1) % k, 0.25);
            face(&mut s, row, i, 0.25);
        }
        face(&mut s, 1 + k + i, i, 1.0);
    }
    let f = 1.0 / (kf * (kf + 5.0));
    let mut l = vec![0.0f64; n];
    l[0] = 1.0 - kf * 5.0 * f;
    l[1..=k].fill(4.0 * f);
    l[k + 1..].fill(f);
    let mut next = vec![0.0f64; n];
    for _ in 0..500 {
        next.fill(0.0);
        for row in 0..n {
            for col in 0..n {
                next[col] += l[row] * s[row * n + col];
            }
        }
        let sum: f64 = next.iter().sum();
        let change = next
            .iter()
            .zip(&l)
            .map(|(a, b)| (a / sum - b).abs())
            .fold(0.0, f64::max);
        for (a, b) in l.iter_mut().zip(&next) {
            *a = b / sum;
        }
        if change < 1e-16 {
            break;
        }
    }
    l
}

/// The smooth vertex mask `(k-2)/k v + 1/k^2 sum e_i + 1/k^2 sum f_i` (interior vertex of `k`
/// faces; `e_i` the edge neighbours, `f_i` the face points).
#[inline]
fn smooth_vertex<T: Scalar, const N: usize>(
    coarse: &Level,
    v: usize,
    values: &[[T; N]],
    faces: &[[T; N]],
) -> [T; N] {
    let corners = coarse.corners_of_vertex(v);
    let k = corners.len();
    let sum = corners.iter().fold(zero(), |s, &c| {
        let c = c as usize;
        let neighbour = values[coarse.corner_verts[coarse.next(c)] as usize];
        add(s, add(neighbour, faces[coarse.face_of(c)]))
    });
    let kf = k as f64;
    mad(
        scale(values[v], T::from_f64((kf - 2.0) / kf)),
        T::from_f64(1.0 / (kf * kf)),
        sum,
    )
}

/// The crease vertex mask `3/4 v + 1/8 (a + b)`, `a` and `b` the other ends of the first two
/// edges at `v` whose `sharpness` is positive.
#[inline]
fn crease_vertex<T: Scalar, const N: usize>(
    coarse: &Level,
    v: usize,
    values: &[[T; N]],
    sharpness: impl Fn(u32) -> f32,
) -> [T; N] {
    let mut ends = [v; 2];
    let mut found = 0;
    for e in vertex_edges(coarse, v) {
        if found < 2 && is_sharp(sharpness(e)) {
            ends[found] = other_end(coarse, e, v);
            found += 1;
        }
    }
    mad(
        scale(values[v], T::from_f64(0.75)),
        T::from_f64(0.125),
        add(values[ends[0]], values[ends[1]]),
    )
}

/// `out[i] = f(i)` (initialising every item), in parallel chunks of [`CHUNK`] items, each
/// item written by one task, so the result does not depend on the number of threads.
fn fill<V: Send, F: Fn(usize) -> V + Sync + Send>(out: &mut [MaybeUninit<V>], f: F) {
    out.par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(chunk, items)| {
            let start = chunk * CHUNK;
            for (i, item) in items.iter_mut().enumerate() {
                item.write(f(start + i));
            }
        });
}

/// The smooth edge point `1/4 (a + b + f_0 + f_1)` of an interior edge `e` of a level
/// without sharp edges (where every edge has two faces: boundaries are sharp).
#[inline]
fn smooth_edge<T: Scalar, const N: usize>(
    coarse: &Level,
    e: usize,
    values: &[[T; N]],
    faces: &[[T; N]],
) -> [T; N] {
    let [a, b] = coarse.edge_verts()[e];
    let [c0, c1] = coarse.edge_corners()[e];
    debug_assert!(c1 != NONE, "a smooth level has no boundary edge");
    // The operations of `edge_point` at sharpness 0 (bitwise equal).
    let f = add(
        faces[coarse.face_of(c0 as usize)],
        faces[coarse.face_of(c1 as usize)],
    );
    mad(
        scale(f, T::from_f64(0.25)),
        T::from_f64(0.25),
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
    values: &[[T; N]],
    faces: &[[T; N]],
) -> [T; N] {
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
        return mad(face_sum(0.5), T::from_f64(0.25), ends);
    }
    if child.rule(w) == Rule::Crease {
        return scale(ends, T::from_f64(0.5));
    }
    let p = s as f64;
    let vertex_weight = p * 0.5 + (1.0 - p) * 0.25;
    mad(face_sum(0.5 * (1.0 - p)), T::from_f64(vertex_weight), ends)
}

/// Doo-Sabin replacement for one degree-2 step `coarse -> fine`: `before` is the data the step
/// started from (per vertex of `coarse` when `primal`, the first step from the cage; per face
/// of `coarse` otherwise), `averaged` the faces of `fine` the averaging step produced. Face `c`
/// of `fine` (corner `c` of `coarse`, at vertex `v`) takes the Doo-Sabin combination of the
/// points of the polygon it belongs to (the corners of `c`'s face when primal, the faces around
/// `v` when dual), unless `v` is a curve vertex or corner of `step`, where the averaged value
/// (the averaging scheme's boundary and crease treatment) stays.
pub fn doo_sabin_step<T: Scalar, const N: usize>(
    coarse: &Level,
    step: &Step,
    before: &[[T; N]],
    primal: bool,
    averaged: &[[T; N]],
) -> Vec<[T; N]> {
    const TABLE: usize = 16;
    let table: Vec<Vec<T>> = (0..=TABLE)
        .map(|k| {
            (0..k)
                .map(|i| T::from_f64(doo_sabin_weight(i, k)))
                .collect()
        })
        .collect();
    let weight = |i: usize, k: usize| {
        if k <= TABLE {
            table[k][i]
        } else {
            T::from_f64(doo_sabin_weight(i, k))
        }
    };
    gather(coarse.num_corners(), |c| {
        let v = coarse.corner_verts[c];
        if step
            .curve_vertices
            .binary_search_by_key(&v, |cv| cv.vertex)
            .is_ok()
        {
            return averaged[c];
        }
        let mut out = zero();
        if primal {
            let k = coarse.face_corners(coarse.face_of(c)).len();
            let mut at = c;
            for i in 0..k {
                out = mad(out, weight(i, k), before[coarse.corner_verts[at] as usize]);
                at = coarse.next(at);
            }
        } else {
            let k = coarse.corners_of_vertex(v as usize).len();
            let mut at = c;
            for i in 0..k {
                out = mad(out, weight(i, k), before[coarse.face_of(at)]);
                // Rotate around v: the other corner of the edge arriving at v in this face.
                let p = coarse.prev(at);
                let [x, y] = coarse.edge_corners()[coarse.corner_edges()[p] as usize];
                at = if x as usize == p { y } else { x } as usize;
                debug_assert!(at != NONE as usize, "interior vertex");
            }
        }
        out
    })
}
