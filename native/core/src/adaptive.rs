//! Adaptive subdivision (the paper's §3): a forest of quadtrees over the quads of `M_1`, refined
//! where an error measure asks, balanced by the vertex restriction criterion, with points computed
//! exactly as the uniform scheme computes them and a crack-free triangulation.
//!
//! This module owns the quadtree forest, the partial levels it evaluates on, the error measure,
//! the restriction criterion and the triangulation templates. It reuses [`Level`] (the refined
//! topology), the curve network construction ([`CurveNetwork::build`]) and the step primitive
//! ([`LevelData::step`]) of the uniform plans: a step on a partial level is the same code as on
//! a full one.
//!
//! # Nodes
//! A node is a face of the uniform level `M_j` (`j >= 1`), named by its uniform face id. Face `c`
//! of `M_{j+1}` is corner `c` of `M_j`, so on quad levels the children of face `f` are
//! `4f..4f + 4`: the uniform numbering is the hierarchy. The roots are all faces of `M_1` (one per
//! corner of the cage). Vertices are named by their uniform ids too; an old vertex keeps its id
//! from level to level, so a vertex id names the same surface vertex at every level.
//!
//! # Partial levels and exactness
//! Level `j` is kept only on a subset `P_j` of the faces of `M_j`, stored as a [`Level`] whose
//! numbering preserves the relative order of the uniform ids (faces, corners, edges, vertices
//! sorted by uniform id; every vertex's corner list in the uniform order). `P_{j+1}` is the
//! refinement of `P_j` restricted to the faces that are needed (the margin rings around the
//! parents of its seeds, below), its curve network and 1-D data restricted alike
//! ([`CurveNetwork::restrict`]). The step primitive then accumulates every sum over the same
//! terms in the same order as in the uniform [`crate::Plan`], so every value whose stencil lies
//! inside the exact data of `P_j` is bitwise the uniform value by construction (and checked
//! against the uniform plan in `tests/adaptive.rs` for degrees 1-5 and 9, with boundaries,
//! creases and corners).
//!
//! Margin. One step of degree n is a replication followed by n averages. Backwards from a set
//! `S` of fine faces (their dual points, or the primal points at their vertices), the n averages
//! reach `k = ceil(n/2)` vertex rings of fine faces, and the replication reads the coarse parents
//! of those. Fine rings relate to coarse ones by `ring_k(children(Y)) ⊆ children(ring_ceil(k/2)(Y))`,
//! so the data of `S = ring_r(children(Y))` is exact when `P_j ⊇ ring_(ceil(r/2) + m)(Y)` with
//! `m = ceil(ceil(n/2) / 2)`. Keeping `P_j = ring_r(S_j)` around the seed faces `S_j` of every
//! level, with `S_{j+1} ⊆ children(S_j)`, is therefore exact when `r >= ceil(r/2) + m`, i.e. with
//! the margin `r = 2m` rings (2 for degrees 1-4, 4 for 5-8, 6 for 9-12, ...). `P_{j+1}` is made
//! as the whole refinement of `ring_r(Y)` in `P_j`, `Y` the parents of its seeds: its data are
//! exact on `ring_r(S_{j+1})` and not on its outer faces, which nothing reads (every read, by the
//! steps of the next level, the decisions, the measures and the drawing, lies within the margin
//! rings of some level's seeds). Cutting `P_{j+1}` down to `ring_r(S_{j+1})` would cost more than
//! the refinement that made it, for little less data. This is a
//! sufficient margin derived from the stencil sizes, not a minimal one (the seeds themselves
//! already carry rings of nodes, from the restriction criterion and the measured children): in
//! `tests/adaptive.rs`, no margin at all fails for degrees 2-5 on a bumped grid, while one ring
//! is enough there. The 1-D curve data lives on the edges and vertices of the same faces and
//! reaches no farther. The same margin also makes every vertex of `ring_1` of the seeds complete
//! (all its uniform faces present), which the drawing step, the restriction criterion and the
//! triangulation need; a query that meets an incomplete vertex is reported as
//! [`Error::Internal`] rather than answered wrongly.
//!
//! Bookkeeping. Making a partial level (the margin rings around its seeds' parents, the
//! restriction of the coarser level to them and its refinement, uniform ids and data), deciding
//! and measuring its nodes and writing the output triangles are gathers and prefix sums in fixed
//! chunks ([`crate::parallel`]): parallel, with results that do not depend on the number of
//! threads. The uniform ids of a whole refined level are plain section copies of the coarse
//! ones ([`whole_ids`]), serial: a few instructions per item, fewer than a parallel gather's.
//! Threads: the partial levels are small (1k-54k faces in `adaptive-flat-4-6`), so a run is some
//! 380 short parallel passes (about 36 us each on one thread, 2026-12-04), which one at a time
//! leave a second thread mostly waking up. Tables that do not depend on each other are made side
//! by side (`rayon::join`): a level's faces, edge tables and vertex corners ([`Level::refine`])
//! beside its curve network, its regular windows beside the copies of its ids, the ids and then
//! the tables of a restriction ([`restrict`]), the decisions' two tables ([`regular_faces`],
//! [`grid_twins`]); the sibling blocks of the decisions (about 8k
//! instructions each) go in tasks of [`BLOCK_GRAIN`]. Still serial (one thread, `4-6`, 22 ms a
//! run under load): the triangulation's vertex numbering (0.9 ms), the restriction criterion's
//! set inserts and sorts (part of its 1.6 ms), the node lists and leaves (0.6 ms).
//! Lookups by uniform id go through the sorted id lists (merge walks) and flat per-level tables,
//! not hash maps; the refined sets are the only ones, read by the restriction criterion (the
//! node lists are made from them only when they grow).
//!
//! Measured (instructions, callgrind driver `examples/callgrind.rs`, one thread, 2026-12-04,
//! 97d4a81): `adaptive-flat-4-6` 382M against 718M for `adaptive-uniform-4-6` in the same build
//! (0.53x; 0.62x for 3-5, 0.56x for 4-5). Of the 382M, the partial levels take 178M
//! (`extend_pass`: the topology's refinement 53M, the restrictions around the parents 35M, the
//! regular windows 22M), the closed-form decisions 105M (about 8k instructions per sibling
//! block, 12k blocks, with the per-level tables), the triangulation 66M and the restriction
//! criterion 19M. Sibling blocks evaluated with their side as a constant ([`block_errors`],
//! 2026-12-04, same build before/after): the decisions 110.8M -> 104.8M (`block_errors` 86.9M ->
//! 80.9M over 12.1k blocks); `adaptive-flat-4-6` 391.1M -> 387.2M (uniform 707.5M), 4-5 107.6M ->
//! 106.3M (uniform 184.0M), 3-5 82.1M -> 81.0M (uniform 127.2M). The ids and counts of a
//! whole refined level as section copies ([`whole_ids`]) rather than per-item gathers (about
//! 20M of `extend_pass`): `adaptive-flat-4-6` 387.2M -> 366.7M (0.52x uniform), 4-5 106.3M ->
//! 100.7M (0.55x), 3-5 81.0M -> 75.8M (0.60x).
//!
//! # Refinement
//! Levels are decided one at a time: level j's nodes are evaluated together with their children
//! (the partial levels are extended up to level j + 1), each node's error measured
//! and the nodes above the tolerance refined. Refining a node at level j requires every face of
//! `M_j` sharing a vertex with it to be a node (the vertex restriction criterion: leaves sharing
//! an edge or a corner differ by at most one level); parents that are leaves are refined in turn,
//! down to the roots. The partial levels are kept from one decision to the next: level j + 1 was
//! made around the children of every node of level j, a superset of the nodes it ends up with,
//! so its data stays exact; only when the restriction criterion adds nodes at a level below j
//! are the levels above that one made again (from the last valid one, not from the cage).
//!
//! Error measure (flatness): for a node f at level j, the 3 x 3 grid of its children's points at
//! level j + 1 (its 4 corners, 4 edge points, 1 face point) against the bilinear patch of the 4
//! corners: the largest distance of an edge point from the midpoint of its corners and of the
//! face point from the mean of the 4 corners, divided by the diagonal of the cage's bounding box.
//! A node is refined when this is above `tolerance`; a tolerance of 0 refines every node (the
//! result is then uniform level `max_level`).
//!
//! # Output
//! Points are the drawing points of each level: the primal points for odd degrees, and for even
//! degrees the paper's drawing step (Fig. 14: one more dual -> primal centroid average), computed
//! exactly as the uniform drawing mesh at that level (where the paper forms corner and edge
//! averages at level transitions, the partial levels hold the finer faces around every drawn
//! vertex, so even the transition points are exact uniform points). A vertex shared by leaves of
//! two levels is drawn at the finer one (its position in the finer uniform level), and is one
//! output vertex. Each leaf quad is triangulated by one of 16 templates chosen by which of its
//! four edge neighbours is refined once more (the cases of the paper's Fig. 13; the templates
//! are fans of our own): the midpoints of those edges (vertices
//! of the finer leaves) are inserted and the quad is fanned from the first of them; without such a
//! neighbour the quad is split along the diagonal through its corner 0 and corner 2 (the parent's
//! face point), so that the diagonals of four siblings meet at their parent's centre (the 4-8
//! tiling of Fig. 13). No T-junctions arise: both sides of every edge use the same vertices.

use std::collections::HashSet;
use std::hash::{BuildHasherDefault, Hasher};
use std::mem::MaybeUninit;

use rayon::prelude::*;

use crate::curves::{CageFeatures, Curve, CurveNetwork};
use crate::error::{AdaptiveStage, Error, Result};
use crate::face_varying::{face_varying_mesh, FaceVaryingMode, Topology};
use crate::memory;
use crate::mesh::{check_values, validate_geometry, Cage};
use crate::options::{check_degree, check_levels, Boundary, Options};
use crate::parallel::{
    fill_csr, gather_grain, gather_hinted, in_pool, prefix_offsets, with_capacity_hinted,
    zeroed_hinted,
};
use crate::refinement::Refinement;
use crate::scalar::{reciprocal, Scalar};
use crate::scheme::{decrement, Scheme};
use crate::step::{primal_input, Drawing, LevelData, Parts, Scratch, Step, Windows};
use crate::topology::{Edges, Level, NONE};

/// Hasher of uniform ids (u64 keys): one multiply and a fold, plenty for ids that are spread
/// over the whole range anyway. Iteration order never reaches a result (sets are sorted first).
#[derive(Default)]
struct IdHasher(u64);

impl Hasher for IdHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(b as u64);
        }
    }
    fn write_u64(&mut self, x: u64) {
        let m = (self.0 ^ x).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        self.0 = m ^ (m >> 29);
    }
}

type IdSet = HashSet<u64, BuildHasherDefault<IdHasher>>;

/// Options of an adaptive subdivision request.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdaptiveOptions {
    /// Number of averaging steps per level (as [`Options::degree`]), 1..=31.
    pub degree: u32,
    /// Deepest level a leaf may reach, 1..=16 (level 1 is the quads of `M_1`, the roots).
    pub max_level: u32,
    /// Flatness tolerance, relative to the diagonal of the cage's bounding box (see the module
    /// documentation); 0 refines everywhere to `max_level`.
    pub tolerance: f64,
    /// Boundary interpolation.
    pub boundary: Boundary,
    /// Largest memory, in bytes, the partial levels, the bookkeeping and the output may need
    /// (estimated before each level's work; default [`memory::default_memory_budget`]).
    pub memory_budget: u64,
    /// Also measure the error of every leaf (one more level is evaluated around each leaf);
    /// the largest is reported as [`AdaptiveMesh::max_error`].
    pub measure_leaves: bool,
}

impl Default for AdaptiveOptions {
    fn default() -> Self {
        AdaptiveOptions {
            degree: 4,
            max_level: 4,
            tolerance: 1e-3,
            boundary: Boundary::EdgeOnly,
            memory_budget: memory::default_memory_budget(),
            measure_leaves: false,
        }
    }
}

/// The result of [`subdivide_adaptive`]: a crack-free triangle mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct AdaptiveMesh<T> {
    /// Points, 3 values per vertex, in the scalar type of the input.
    pub points: Vec<T>,
    /// Triangles (counter-clockwise as the cage's faces), indices into the points.
    pub triangles: Vec<[u32; 3]>,
    /// Cage face each triangle comes from.
    pub face_origin: Vec<u32>,
    /// Level of the leaf each triangle comes from.
    pub triangle_level: Vec<u32>,
    /// Level whose point each vertex carries (the finest level of the leaves around it).
    pub vertex_level: Vec<u32>,
    /// Uniform vertex id of each vertex at its level: vertex `i` is vertex `vertex_id[i]` of the
    /// uniform level `vertex_level[i]`, which has the same point bit for bit.
    pub vertex_id: Vec<u64>,
    /// Per vertex: the cage vertex (the user's numbering) it is, [`crate::Level::NONE`] for a
    /// vertex made by refinement (for vertex attributes such as Blender's vertex crease).
    pub cage_vertex: Vec<u32>,
    /// Per vertex: the corner sharpness it keeps at its level (OpenSubdiv's convention, 10
    /// infinitely sharp; the cage's corners and the topological ones of the boundary rule and
    /// of non-manifold vertices, lowered once per level as the edges' in `edge_sharpness`):
    /// what one more level would use; 0 for a vertex that is not a cage corner.
    pub vertex_sharpness: Vec<f32>,
    /// Number of leaves at each level (index = level; index 0 is always 0).
    pub leaves_per_level: Vec<u64>,
    /// With [`AdaptiveOptions::measure_leaves`], the largest error measure over all leaves
    /// (relative to the cage diagonal, as the tolerance).
    pub max_error: Option<f64>,
    /// With [`AdaptiveData::vertex_values`]: those values at the output vertices (the same
    /// channels, interleaved), each at its vertex's level, bit for bit the uniform
    /// [`crate::Plan::evaluate`] there; empty otherwise.
    pub vertex_values: Vec<T>,
    /// Per triangle corner `3t + i`: the cage edge (index into `cage_edges`) that the
    /// triangle's edge from corner `i` to corner `i + 1` lies on, [`crate::Level::NONE`] inside
    /// a cage face (for edge attributes, as [`crate::Plan::output_edge_origin`]).
    pub edge_origin: Vec<u32>,
    /// Per triangle corner: the level of that edge (a leaf's edge, or half of it where the
    /// finer neighbour's midpoint is inserted).
    pub edge_level: Vec<u32>,
    /// Per triangle corner: the sharpness that edge keeps at its level (the cage edge's,
    /// lowered once per level, as [`crate::Plan::output_edge_sharpness`] with the averaging
    /// rules; 0 inside cage faces, 10 on boundaries).
    pub edge_sharpness: Vec<f32>,
    /// The edges of the cage as pairs of cage vertices (the user's numbering, smaller first),
    /// ordered by pair, as [`crate::Plan::cage_edges`].
    pub cage_edges: Vec<[u32; 2]>,
    /// One entry per [`AdaptiveData::face_varying`] set: its values at the triangle corners
    /// (3 per triangle, its channels interleaved), each at its vertex's level, bit for bit the
    /// uniform [`crate::Plan::evaluate_face_varying`] at that level on the same side of a seam.
    pub face_varying: Vec<Vec<T>>,
}

/// Further data carried through the same adaptive forest as the points (the leaves are chosen
/// by the points alone).
#[derive(Debug, Clone, Default)]
pub struct AdaptiveData<'a, T> {
    /// Per-vertex values of the cage (any attribute, in the cage's numbering) and their
    /// channel count: evaluated as the points.
    pub vertex_values: Option<(&'a [T], usize)>,
    /// Face-varying sets (UVs): values per cage face corner, their channel count and the mode
    /// (as [`crate::Plan::evaluate_face_varying`]; each set is welded on its own).
    pub face_varying: Vec<(&'a [T], usize, FaceVaryingMode)>,
    /// The face-varying topology of the sets of `face_varying` (one entry per set, or none at
    /// all): one index per cage corner, corners of one cage vertex with the same index share
    /// one value (OpenSubdiv's index buffer, as [`crate::Plan::evaluate_face_varying_indexed`]);
    /// `None` welds the set by value.
    pub face_varying_indices: Vec<Option<&'a [u32]>>,
}

impl<T> AdaptiveMesh<T> {
    /// Number of leaves (quads of the adaptive surface before triangulation).
    pub fn num_leaves(&self) -> u64 {
        self.leaves_per_level.iter().sum()
    }
}

type P<T> = [T; 3];

/// A partial level's 2-D data (borrowed) and 1-D data, as a step takes them.
type LevelParts<'a, T> = (&'a [P<T>], Vec<P<T>>);

/// One partial level: a subset of the faces of uniform `M_j`, with its data (exact on the
/// margin rings around the seeds it was made for; module documentation).
#[derive(Debug)]
struct Part<T> {
    level: Level,
    face_uid: Vec<u64>,
    vert_uid: Vec<u64>,
    edge_uid: Vec<u64>,
    /// Per edge: its number of faces in the uniform level.
    edge_faces: Vec<u32>,
    /// Per vertex: its number of corners in the uniform level.
    vert_faces: Vec<u32>,
    /// The curve edges of the step from this level, with their sharpness.
    curves: Vec<Curve>,
    /// The curve network of the step that made this level, restricted to it (`None` at
    /// level 0).
    network: Option<CurveNetwork>,
    /// Scheme data: per vertex (odd degree) or per face (even degree); the cage at level 0.
    data: Vec<P<T>>,
    /// 1-D curve data of the step that made this level: per curve vertex (odd) or curve edge
    /// (even) of `network`.
    curve: Vec<P<T>>,
    /// Drawing points per vertex (empty at level 0).
    points: Vec<P<T>>,
    /// Uniform counts of this level: vertices, edges, faces, corners.
    counts: [u64; 4],
}

impl<T> Part<T> {
    fn face_of_uid(&self, uid: u64) -> Option<usize> {
        self.face_uid.binary_search(&uid).ok()
    }

    /// True when every uniform face around vertex `v` is present (every sheet of a
    /// non-manifold vertex included).
    #[inline]
    fn is_complete(&self, v: usize) -> bool {
        self.level.corners_of_vertex(v).len() == self.vert_faces[v] as usize
    }
}

/// What does not change between passes.
struct Context<T> {
    cage: Vec<P<T>>,
    level0: Level,
    features: CageFeatures,
    scheme: Scheme,
    degree: u32,
    margin: usize,
    budget: u64,
    diagonal: f64,
    /// Per cage face: a hole (refined where its neighbours need it, never drawn or measured).
    holes: Vec<bool>,
}

impl<T> Context<T> {
    /// True when node `uid` of level `t >= 1` lies in a hole face of the cage.
    fn is_hole(&self, t: usize, uid: u64) -> bool {
        !self.features.holes.is_empty()
            && self.holes[self.level0.corner_faces[(uid >> (2 * (t - 1))) as usize] as usize]
    }

    /// Refuses, before the work of `stage`, what is estimated at more than the budget or the
    /// machine's memory ([`memory::check_request`]), saying when ([`Error::AdaptiveStopped`]).
    fn check(&self, stage: AdaptiveStage, required: f64, faces: f64) -> Result<()> {
        memory::check_request(
            required.min(u64::MAX as f64) as u64,
            faces.min(u64::MAX as f64) as u64,
            self.budget,
        )
        .map_err(|error| Error::AdaptiveStopped {
            stage,
            error: Box::new(error),
        })
    }
}

/// Rings of margin kept around the seed faces of every level for degree `n` (module docs).
pub fn margin_rings(degree: u32) -> usize {
    2 * (degree.div_ceil(2).div_ceil(2) as usize)
}

/// Subdivides `points` (3 values per cage vertex) adaptively; see the module documentation for
/// the forest, the error measure and the output.
pub fn subdivide_adaptive<T: Scalar>(
    cage: &Cage,
    points: &[T],
    options: &AdaptiveOptions,
) -> Result<AdaptiveMesh<T>> {
    subdivide_adaptive_with_margin(cage, points, options, margin_rings(options.degree))
}

/// [`subdivide_adaptive`], also carrying `data` (per-vertex and face-varying values) through
/// the forest: [`AdaptiveMesh::vertex_values`] and [`AdaptiveMesh::face_varying`].
pub fn subdivide_adaptive_with_data<T: Scalar>(
    cage: &Cage,
    points: &[T],
    options: &AdaptiveOptions,
    data: &AdaptiveData<T>,
) -> Result<AdaptiveMesh<T>> {
    adaptive(cage, points, options, margin_rings(options.degree), data)
}

/// [`subdivide_adaptive`] with another margin than [`margin_rings`]; for the tests that show
/// that a smaller margin breaks the equality with the uniform points.
#[doc(hidden)]
pub fn subdivide_adaptive_with_margin<T: Scalar>(
    cage: &Cage,
    points: &[T],
    options: &AdaptiveOptions,
    margin: usize,
) -> Result<AdaptiveMesh<T>> {
    adaptive(cage, points, options, margin, &AdaptiveData::default())
}

/// The adaptive subdivision of every entry point, run on a thread of rayon's pool: its many
/// short parallel loops then split and join there ([`in_pool`]).
fn adaptive<T: Scalar>(
    cage: &Cage,
    points: &[T],
    options: &AdaptiveOptions,
    margin: usize,
    extra: &AdaptiveData<T>,
) -> Result<AdaptiveMesh<T>> {
    in_pool(|| adaptive_in_pool(cage, points, options, margin, extra))
}

/// [`adaptive`], on a thread of the pool.
fn adaptive_in_pool<T: Scalar>(
    cage: &Cage,
    points: &[T],
    options: &AdaptiveOptions,
    margin: usize,
    extra: &AdaptiveData<T>,
) -> Result<AdaptiveMesh<T>> {
    check_degree(options.degree)?;
    check_levels(options.max_level, 1)?;
    if !options.tolerance.is_finite() || options.tolerance < 0.0 {
        return Err(Error::InvalidInput(format!(
            "the tolerance must be finite and at least 0, not {}",
            options.tolerance
        )));
    }
    validate_geometry(cage, points, 3)?;
    if let Some((values, channels)) = extra.vertex_values {
        check_values(values, channels, cage.num_vertices())?;
    }
    for &(values, channels, _) in &extra.face_varying {
        check_values(values, channels, cage.face_vertices().len())?;
    }
    let topologies = &extra.face_varying_indices;
    if !topologies.is_empty() && topologies.len() != extra.face_varying.len() {
        return Err(Error::InvalidInput(format!(
            "{} face-varying topologies for {} face-varying sets",
            topologies.len(),
            extra.face_varying.len()
        )));
    }
    for indices in topologies.iter().flatten() {
        if indices.len() != cage.face_vertices().len() {
            return Err(Error::InvalidInput(format!(
                "{} face-varying indices for a cage of {} face corners",
                indices.len(),
                cage.face_vertices().len()
            )));
        }
    }
    let (base, ctx) = context(cage, points, options, margin)?;

    let max_level = options.max_level as usize;
    let roots = ctx.level0.num_corners() as u64;
    let grid = Grid::new::<T>(&ctx);
    // refined[j]: uniform ids of the refined nodes at level j (1 <= j < max_level).
    let mut refined: Vec<IdSet> = vec![IdSet::default(); max_level];
    let mut node_lists = NodeLists::default();
    // Partial levels kept from decision to decision: level j + 1 is made for the children of
    // every node of level j, a superset of the nodes it ends up with, so it stays exact unless
    // the restriction criterion adds nodes below (then the levels above are made again).
    let mut parts: Vec<Part<T>> = Vec::new();
    if options.tolerance == 0.0 {
        // The result is uniform level `max_level`: its size is known before any work.
        let leaves = roots as f64 * 4f64.powi(max_level as i32 - 1);
        let required = leaves * (BYTES_PER_NODE + BYTES_PER_LEAF + 4.0 / 3.0 * BYTES_PER_FACE);
        ctx.check(AdaptiveStage::BeforeTheWork, required, leaves)?;
    }
    // Uniform ids held by the bookkeeping (nodes, refined sets, seeds), in nodes.
    let mut held = roots;
    for j in 1..max_level {
        // Before any of this level's work: its nodes, and their children's partial level.
        let count = if j == 1 {
            roots
        } else {
            4 * refined[j - 1].len() as u64
        };
        held += count;
        ctx.check(
            AdaptiveStage::Level(j as u32),
            retained(&parts) + BYTES_PER_NODE * held as f64 + 4.0 * BYTES_PER_FACE * count as f64,
            4.0 * count as f64,
        )?;
        let mut nodes = node_lists.upto(&refined, roots, j)?[j].clone();
        // Holes are refined only where the restriction criterion asks.
        nodes.retain(|&u| !ctx.is_hole(j, u));
        if options.tolerance == 0.0 {
            try_insert(&mut refined[j], &nodes)?;
            continue;
        }
        let mut seeds = node_lists.upto(&refined, roots, j)?.to_vec();
        extend_pass(&ctx, &mut parts, &seeds, held)?;
        let decided = decide(&ctx, &grid, j, &parts[j], &nodes, options.tolerance)?;
        // The nodes decided above the tolerance are refined whatever the measurements say: the
        // nodes that the restriction criterion adds below level j for them are known before
        // level j + 1 is made, and the levels they change are made again first (not after
        // level j + 1 was made on the old ones, to be made again in the next decision).
        let above =
            (nodes.iter().zip(&decided)).filter_map(|(&u, &d)| (d == Some(true)).then_some(u));
        let lowest = restrict_refine(&parts, &mut refined, j, above)?;
        if lowest < j {
            parts.truncate(lowest + 1);
            seeds = node_lists.upto(&refined, roots, j)?.to_vec();
            extend_pass(&ctx, &mut parts, &seeds, held)?;
        }
        // The nodes that the grid's closed form decides need no children; the others' children
        // are the next level's seeds (a superset of its nodes), where the undecided ones are
        // measured.
        let pick = |keep: fn(Option<bool>) -> bool| -> Vec<u64> {
            (nodes.iter().zip(&decided))
                .filter(|&(_, &d)| keep(d))
                .map(|(&u, _)| u)
                .collect()
        };
        seeds.push(children(&pick(|d| d != Some(false)))?);
        extend_pass(&ctx, &mut parts, &seeds, held)?;
        let undecided = pick(|d| d.is_none());
        let errors = measure(&ctx, &parts, j, &undecided)?;
        let above = (undecided.iter().zip(&errors))
            .filter_map(|(&u, &error)| (error > options.tolerance).then_some(u));
        let lowest = restrict_refine(&parts, &mut refined, j, above)?;
        if lowest < j {
            parts.truncate(lowest + 1);
        }
    }

    let mut seeds = node_lists.upto(&refined, roots, max_level)?.to_vec();
    // The refined nodes of every level, sorted: the parents of the next level's nodes (every
    // fourth one).
    let refined: Vec<Vec<u64>> = (0..=max_level)
        .map(|t| match seeds.get(t + 1) {
            Some(children) if t >= 1 => {
                memory::collect(children.iter().step_by(4).map(|&c| c >> 2))
            }
            _ => Ok(Vec::new()),
        })
        .collect::<Result<_>>()?;
    // The leaves: the nodes not refined (both lists sorted: a merge walk) and not in holes.
    let leaves: Vec<Vec<u64>> = (0..=max_level)
        .map(|t| {
            if t == 0 {
                return Vec::new();
            }
            let r = &refined[t];
            let mut i = 0;
            (seeds[t].iter().copied())
                .filter(|&u| {
                    while i < r.len() && r[i] < u {
                        i += 1;
                    }
                    r.get(i) != Some(&u) && !ctx.is_hole(t, u)
                })
                .collect()
        })
        .collect();
    let mut max_error = None;
    if options.measure_leaves {
        // Every leaf's children are seeds one level down.
        let mut measured = seeds.clone();
        measured.push(Vec::new());
        for t in 1..=max_level {
            let mut more = children(&leaves[t])?;
            more.extend_from_slice(&measured[t + 1]);
            more.sort_unstable();
            more.dedup();
            measured[t + 1] = more;
        }
        let parts = run_pass(&ctx, &measured, held)?;
        let mut worst = 0.0f64;
        for (t, leaves) in leaves.iter().enumerate().skip(1) {
            for e in measure(&ctx, &parts, t, leaves)? {
                worst = worst.max(e);
            }
        }
        max_error = Some(worst);
    }
    seeds.truncate(max_level + 1);
    extend_pass(&ctx, &mut parts, &seeds, held)?;
    let num_leaves: u64 = leaves.iter().map(|l| l.len() as u64).sum();
    ctx.check(
        AdaptiveStage::Output,
        retained(&parts) + BYTES_PER_NODE * held as f64 + BYTES_PER_LEAF * num_leaves as f64,
        num_leaves as f64,
    )?;
    let drawn = triangulate(&ctx, &parts, &refined, &leaves)?;
    let mut mesh = drawn.mesh;
    mesh.max_error = max_error;
    vertex_creases(&ctx, &base, &mut mesh);
    mesh.cage_edges = (ctx.level0.edge_verts().iter())
        .map(|&[a, b]| {
            let (a, b) = (base.cage_vertex(a), base.cage_vertex(b));
            [a.min(b), a.max(b)]
        })
        .collect();
    let held = retained(&parts) + BYTES_PER_NODE * held as f64;
    if let Some((values, channels)) = extra.vertex_values {
        mesh.vertex_values = carry_vertex_values(
            &ctx,
            &base,
            &parts,
            &drawn.vertex_at,
            values,
            channels,
            held,
        )?;
    }
    for (i, &(values, channels, mode)) in extra.face_varying.iter().enumerate() {
        let topology = match topologies.get(i) {
            Some(Some(indices)) => Topology::Indexed(indices),
            _ => Topology::ByValue,
        };
        let carried = if mode == FaceVaryingMode::All {
            linear_face_varying(&ctx, &parts, &drawn.corner_at, values, channels)?
        } else {
            carry_face_varying(
                &ctx,
                &base,
                &parts,
                &mesh,
                &drawn.corner_at,
                values,
                channels,
                topology,
                mode,
                held,
            )?
        };
        mesh.face_varying.push(carried);
    }
    Ok(mesh)
}

/// The cage level, its vertex compaction and its curve features, as the uniform plan has them,
/// and the context of a run on them.
fn context<T: Scalar>(
    cage: &Cage,
    points: &[T],
    options: &AdaptiveOptions,
    margin: usize,
) -> Result<(Refinement, Context<T>)> {
    let options0 = Options {
        degree: options.degree,
        levels: 0,
        boundary: options.boundary,
        memory_budget: options.memory_budget,
        ..Options::default()
    };
    let base = Refinement::new(cage, &options0)?;
    let (given, _) = points.as_chunks::<3>();
    let compact: Vec<P<T>> = base.compact(given).into_owned();
    let level0 = base.cage_level().clone();
    let features = base.features().clone();
    let mut holes = vec![false; level0.num_faces()];
    for &f in &features.holes {
        holes[f as usize] = true;
    }
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in &compact {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k].to_f64());
            hi[k] = hi[k].max(p[k].to_f64());
        }
    }
    let diagonal = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt();
    let ctx = Context {
        cage: compact,
        level0,
        features,
        scheme: Scheme::new(&options0),
        degree: options.degree,
        margin,
        budget: options.memory_budget,
        diagonal,
        holes,
    };
    Ok((base, ctx))
}

/// [`AdaptiveMesh::cage_vertex`] and [`AdaptiveMesh::vertex_sharpness`]: an old vertex keeps
/// its uniform id from level to level, so the vertices of `M_0` are the ids below its count.
fn vertex_creases<T>(ctx: &Context<T>, base: &Refinement, mesh: &mut AdaptiveMesh<T>) {
    let nv0 = ctx.level0.num_vertices as u64;
    let mut corner = vec![0.0f32; ctx.level0.num_vertices];
    for &(v, s) in &ctx.features.corners {
        corner[v as usize] = s;
    }
    mesh.cage_vertex = (mesh.vertex_id.iter())
        .map(|&u| {
            if u < nv0 {
                base.cage_vertex(u as u32)
            } else {
                NONE
            }
        })
        .collect();
    mesh.vertex_sharpness = (mesh.vertex_id.iter().zip(&mesh.vertex_level))
        .map(|(&u, &level)| {
            if u < nv0 {
                (0..level).fold(corner[u as usize], |s, _| decrement(s))
            } else {
                0.0
            }
        })
        .collect();
}

/// The values of groups of 3 channels (the last padded) as the points of a cage, compacted
/// as `base` compacts the cage: one [`Context::cage`] per group.
fn groups_of_three<T: Scalar>(
    base: &Refinement,
    values: &[T],
    channels: usize,
) -> Result<Vec<Vec<P<T>>>> {
    let items = values.len() / channels;
    (0..channels)
        .step_by(3)
        .map(|first| {
            let mut group: Vec<P<T>> = memory::with_capacity(items)?;
            group.extend((0..items).map(|i| {
                [0, 1, 2].map(|k| {
                    let c = first + k;
                    if c < channels {
                        values[i * channels + c]
                    } else {
                        T::default()
                    }
                })
            }));
            Ok(base.compact(&group).into_owned())
        })
        .collect()
}

/// Scatters the first `channels - first` (at most 3) channels of `values` into `out` (rows
/// of `channels`) at channel `first`.
fn put_group<T: Scalar>(out: &mut [T], channels: usize, first: usize, values: &[P<T>]) {
    let width = (channels - first).min(3);
    for (row, v) in out.chunks_exact_mut(channels).zip(values) {
        row[first..first + width].copy_from_slice(&v[..width]);
    }
}

/// Per-vertex values through the forest of `parts`: the same steps on the same partial
/// levels, 3 channels at a time; `vertex_at` is each output vertex's (level, vertex).
fn carry_vertex_values<T: Scalar>(
    ctx: &Context<T>,
    base: &Refinement,
    parts: &[Part<T>],
    vertex_at: &[(u32, u32)],
    values: &[T],
    channels: usize,
    held: f64,
) -> Result<Vec<T>> {
    let mut out = memory::filled(vertex_at.len() * channels, T::default())?;
    for (g, cage) in groups_of_three(base, values, channels)?
        .into_iter()
        .enumerate()
    {
        let other = Context {
            cage,
            level0: ctx.level0.clone(),
            features: ctx.features.clone(),
            holes: ctx.holes.clone(),
            ..*ctx
        };
        let carried = follow_pass(&other, parts, held)?;
        let at: Vec<P<T>> = (vertex_at.iter())
            .map(|&(t, v)| carried[t as usize].points[v as usize])
            .collect();
        put_group(&mut out, channels, 3 * g, &at);
    }
    Ok(out)
}

/// Face-varying values in a smooth `mode` through the forest of `parts`: the face-varying
/// mesh `M^fv` ([`face_varying_mesh`]: the same faces, so the same partial levels by face
/// id, which hold every `M^fv` stencil their cage stencils hold) stepped 3 channels at a
/// time; each triangle corner (`corner_at`: leaf level, leaf, template slot) takes its
/// `M^fv` vertex at the level of its output vertex.
#[allow(clippy::too_many_arguments)]
fn carry_face_varying<T: Scalar>(
    ctx: &Context<T>,
    base: &Refinement,
    parts: &[Part<T>],
    mesh: &AdaptiveMesh<T>,
    corner_at: &[CornerAt],
    values: &[T],
    channels: usize,
    topology: Topology,
    mode: FaceVaryingMode,
    held: f64,
) -> Result<Vec<T>> {
    let (fv_cage, per_value) = face_varying_mesh(base, values, channels, mode, topology)?;
    let fv_options = Options {
        degree: ctx.degree,
        levels: 0,
        boundary: Boundary::EdgeOnly,
        memory_budget: ctx.budget,
        ..Options::default()
    };
    let fv_base = Refinement::new(&fv_cage, &fv_options)?;
    let fv_level0 = fv_base.cage_level().clone();
    let fv_features = fv_base.features().clone();
    let corners = mesh.triangles.as_flattened();
    let mut out = memory::filled(corner_at.len() * channels, T::default())?;
    for (g, cage) in groups_of_three(&fv_base, &per_value, channels)?
        .into_iter()
        .enumerate()
    {
        let other = Context {
            cage,
            level0: fv_level0.clone(),
            features: fv_features.clone(),
            holes: ctx.holes.clone(),
            ..*ctx
        };
        let carried = follow_pass(&other, parts, held)?;
        let at: Vec<P<T>> = (corner_at.iter().zip(corners))
            .map(|(&(t, f, slot), &v)| {
                let part = &carried[t as usize];
                let corner = 4 * f as usize + (slot / 2) as usize;
                let uid = if slot % 2 == 0 {
                    part.vert_uid[part.level.corner_verts[corner] as usize]
                } else {
                    part.counts[0] + part.edge_uid[part.level.corner_edges()[corner] as usize]
                };
                let drawn = &carried[mesh.vertex_level[v as usize] as usize];
                let i = drawn.vert_uid.binary_search(&uid).map_err(|_| {
                    Error::Internal(format!(
                        "adaptive: face-varying vertex {uid} of level {} missing",
                        mesh.vertex_level[v as usize]
                    ))
                })?;
                Ok(drawn.points[i])
            })
            .collect::<Result<_>>()?;
        put_group(&mut out, channels, 3 * g, &at);
    }
    Ok(out)
}

/// Face-varying values in [`FaceVaryingMode::All`] (bilinear per cage face) at the triangle
/// corners, exactly as the uniform [`crate::Plan::evaluate_face_varying`] computes them: each
/// leaf's corner values come down its quadtree from the cage face (own value, edge midpoints,
/// face centre), and a vertex keeps its value from the level where it appears on.
fn linear_face_varying<T: Scalar>(
    ctx: &Context<T>,
    parts: &[Part<T>],
    corner_at: &[CornerAt],
    values: &[T],
    channels: usize,
) -> Result<Vec<T>> {
    let level0 = &ctx.level0;
    let half = T::from_f64(0.5);
    let at = |c: usize, k: usize| values[c * channels + k];
    let mut out = memory::filled(corner_at.len() * channels, T::default())?;
    let mut quad = vec![T::default(); 4 * channels];
    let mut next = vec![T::default(); 4 * channels];
    for (row, &(t, f, slot)) in out.chunks_exact_mut(channels).zip(corner_at) {
        let t = t as usize;
        let uid = parts[t].face_uid[f as usize];
        // Level 1: the quad of cage corner c0.
        let c0 = (uid >> (2 * (t - 1))) as usize;
        let (n, p) = (level0.next(c0), level0.prev(c0));
        let corners = level0.face_corners(level0.face_of(c0));
        let w = reciprocal::<T>(corners.len());
        for k in 0..channels {
            let sum = corners.clone().fold(T::default(), |s, c| s + at(c, k));
            quad[k] = at(c0, k);
            quad[channels + k] = (at(c0, k) + at(n, k)) * half;
            quad[2 * channels + k] = sum * w;
            quad[3 * channels + k] = (at(p, k) + at(c0, k)) * half;
        }
        let quarter = reciprocal::<T>(4);
        for i in 1..t {
            let d = ((uid >> (2 * (t - 1 - i))) & 3) as usize;
            let q = |j: usize, k: usize| quad[(j & 3) * channels + k];
            for k in 0..channels {
                let sum = (0..4).fold(T::default(), |s, j| s + q(j, k));
                next[k] = q(d, k);
                next[channels + k] = (q(d, k) + q(d + 1, k)) * half;
                next[2 * channels + k] = sum * quarter;
                next[3 * channels + k] = (q(d + 3, k) + q(d, k)) * half;
            }
            std::mem::swap(&mut quad, &mut next);
        }
        let k0 = (slot / 2) as usize;
        for k in 0..channels {
            let own = quad[k0 * channels + k];
            row[k] = if slot % 2 == 0 {
                own
            } else {
                (own + quad[((k0 + 1) & 3) * channels + k]) * half
            };
        }
    }
    Ok(out)
}

/// Runs the partial levels of another cage with the faces of `reference` (the same face ids
/// at every level: the levels of `ctx`'s cage, which must have the faces of the reference's
/// cage in the same order); `held` bytes are held meanwhile (for the budget).
fn follow_pass<T: Scalar>(
    ctx: &Context<T>,
    reference: &[Part<T>],
    held: f64,
) -> Result<Vec<Part<T>>> {
    let mut parts = vec![cage_part(ctx)];
    let mut retained = held + retained(&parts);
    for t in 0..reference.len() - 1 {
        let fine_corners = 4 * parts[t].level.num_corners() as u64;
        ctx.check(
            AdaptiveStage::Level(t as u32 + 1),
            retained + BYTES_PER_CORNER as f64 * fine_corners as f64,
            fine_corners as f64 / 4.0,
        )?;
        let next = refine_part(ctx, t, &parts[t], Keep::Faces(&reference[t + 1].face_uid))?;
        retained += BYTES_PER_CORNER as f64 * next.level.num_corners() as f64;
        parts.push(next);
    }
    Ok(parts)
}

/// The nodes of every level (sorted uniform ids), kept from decision to decision: every face
/// of `M_1` at level 1, the children of the refined nodes of level `t - 1` above. The refined
/// sets only grow, so a level's list is made again (its parents sorted) only when the set of
/// its parents has grown, not on every request.
#[derive(Default)]
struct NodeLists {
    lists: Vec<Vec<u64>>,
    /// Per level: the size of the parents' refined set when its list was made.
    made_from: Vec<Option<usize>>,
}

impl NodeLists {
    /// The nodes of levels `0..=top`.
    fn upto(&mut self, refined: &[IdSet], roots: u64, top: usize) -> Result<&[Vec<u64>]> {
        if self.lists.len() <= top {
            self.lists.resize(top + 1, Vec::new());
            self.made_from.resize(top + 1, None);
        }
        for t in 0..=top {
            let parents = match t {
                0 | 1 => 0,
                _ => refined.get(t - 1).map_or(0, |r| r.len()),
            };
            if self.made_from[t] == Some(parents) {
                continue;
            }
            self.lists[t] = match t {
                0 => Vec::new(),
                1 => {
                    let mut nodes = try_vec(roots)?;
                    nodes.extend(0..roots);
                    nodes
                }
                _ => {
                    let mut sorted = try_vec(parents as u64)?;
                    if let Some(r) = refined.get(t - 1) {
                        sorted.extend(r.iter().copied());
                    }
                    sorted.sort_unstable();
                    children(&sorted)?
                }
            };
            self.made_from[t] = Some(parents);
        }
        Ok(&self.lists[..=top])
    }
}

/// The children of sorted quad-level faces, sorted.
fn children(faces: &[u64]) -> Result<Vec<u64>> {
    let mut out = try_vec(4 * faces.len() as u64)?;
    out.extend(faces.iter().flat_map(|&f| (0..4).map(move |k| 4 * f + k)));
    Ok(out)
}

/// Estimated bytes of a partial level per corner (topology tables, ids, values and 1-D data,
/// and the transient tables of its refinement), measured as the peak resident memory of
/// uniform runs (`tolerance = 0`) divided by their corners.
const BYTES_PER_CORNER: u64 = 160;
/// [`BYTES_PER_CORNER`] per quad face.
const BYTES_PER_FACE: f64 = 4.0 * BYTES_PER_CORNER as f64;
/// Estimated bytes of the bookkeeping per uniform id it holds (the node lists, the seeds and
/// the refined sets with their growth).
const BYTES_PER_NODE: f64 = 64.0;
/// Estimated bytes of the output per leaf (its triangles, origins and levels, its share of the
/// points and of the vertex index).
const BYTES_PER_LEAF: f64 = 160.0;

/// Estimated bytes the partial levels in `parts` hold.
fn retained<T>(parts: &[Part<T>]) -> f64 {
    parts
        .iter()
        .map(|p| BYTES_PER_CORNER as f64 * p.level.num_corners() as f64)
        .sum()
}

/// An empty vector with room for `len` uniform ids ([`memory::with_capacity`]).
fn try_vec(len: u64) -> Result<Vec<u64>> {
    memory::with_capacity(usize::try_from(len).unwrap_or(usize::MAX))
}

/// Adds `nodes` to the set `refined`, reserving first (an allocation failure is
/// [`Error::OutOfMemory`], as from [`memory`]).
fn try_insert(refined: &mut IdSet, nodes: &[u64]) -> Result<()> {
    reserve_set(refined, nodes.len())?;
    refined.extend(nodes.iter().copied());
    Ok(())
}

/// Room for `more` ids in `set`, or [`Error::OutOfMemory`].
fn reserve_set(set: &mut IdSet, more: usize) -> Result<()> {
    set.try_reserve(more)
        .map_err(|_| memory::refused_bytes((BYTES_PER_NODE * (set.len() + more) as f64) as u64))
}

/// Evaluates the partial levels `P_0..P_T` (T = `seeds.len() - 1`) from scratch: `P_0` is the
/// cage, `P_{t+1}` is `P_t.refine()` restricted to the margin rings around `seeds[t + 1]`
/// (uniform face ids, sorted, children of `seeds[t]`).
fn run_pass<T: Scalar>(ctx: &Context<T>, seeds: &[Vec<u64>], held: u64) -> Result<Vec<Part<T>>> {
    let mut parts = Vec::new();
    extend_pass(ctx, &mut parts, seeds, held)?;
    Ok(parts)
}

/// As [`run_pass`], keeping the partial levels already in `parts` (which must have been made
/// for seeds containing these seeds: a superset of the margin rings is exact as well). `held`
/// uniform ids are held by the bookkeeping meanwhile (for the budget).
fn extend_pass<T: Scalar>(
    ctx: &Context<T>,
    parts: &mut Vec<Part<T>>,
    seeds: &[Vec<u64>],
    held: u64,
) -> Result<()> {
    if parts.is_empty() {
        parts.push(cage_part(ctx));
    }
    let mut retained = retained(parts) + BYTES_PER_NODE * held as f64;
    for t in parts.len() - 1..seeds.len() - 1 {
        let coarse = &parts[t];
        let fine_corners = 4 * coarse.level.num_corners() as u64;
        if fine_corners >= u32::MAX as u64 {
            return Err(Error::InvalidInput(format!(
                "{} faces at level {} is more than 32-bit indices can address",
                fine_corners / 4,
                t + 1
            )));
        }
        ctx.check(
            AdaptiveStage::Level(t as u32 + 1),
            retained + BYTES_PER_CORNER as f64 * fine_corners as f64,
            fine_corners as f64 / 4.0,
        )?;
        let next = match around_parents(ctx, t, coarse, &seeds[t + 1])? {
            Some(sub) => refine_part(ctx, t, &sub, Keep::All)?,
            None => refine_part(ctx, t, coarse, Keep::All)?,
        };
        retained += BYTES_PER_CORNER as f64 * next.level.num_corners() as f64;
        parts.push(next);
    }
    Ok(())
}

/// The faces of `coarse` (level `t >= 1`) that a step needs for its children kept around
/// `seeds` (sorted uniform ids at level `t + 1`), as a part of its own: the margin rings around
/// the seeds' parents. The kept children and their data are those of the whole `coarse`
/// (module documentation: the data of `ring_r(children(Y))` is exact on `ring_(ceil(r/2) + m)(Y)`,
/// here `r = 2m`), without refining the faces that no seed needs. `None` when that is all of
/// `coarse` (and on the cage level, where every face is a root's parent).
fn around_parents<T: Scalar>(
    ctx: &Context<T>,
    t: usize,
    coarse: &Part<T>,
    seeds: &[u64],
) -> Result<Option<Part<T>>> {
    if t == 0 {
        return Ok(None);
    }
    let mut keep = memory::filled(coarse.level.num_faces(), false)?;
    // Both lists are sorted, and a seed's parent is its id over 4: one merge walk.
    let mut f = 0;
    for &s in seeds {
        let parent = s >> 2;
        while f < coarse.face_uid.len() && coarse.face_uid[f] < parent {
            f += 1;
        }
        if coarse.face_uid.get(f) != Some(&parent) {
            return Err(Error::Internal(format!(
                "adaptive: parent {parent} of seed {s} (level {}) missing",
                t + 1
            )));
        }
        keep[f] = true;
    }
    let keep = grow_rings(&coarse.level, keep, ctx.margin)?;
    if keep.iter().all(|&k| k) {
        return Ok(None);
    }
    let sub = restrict(&coarse.level, &keep)?;
    let network = (coarse.network.as_ref()).map(|n| n.restrict(&sub.vertex_map, &sub.edge_map));
    let odd = ctx.degree % 2 == 1;
    let pick =
        |values: &[P<T>], keep: &[u32]| gather_hinted(keep.len(), |i| values[keep[i] as usize]);
    let pick_ids =
        |values: &[u64], keep: &[u32]| gather_hinted(keep.len(), |i| values[keep[i] as usize]);
    let pick_counts =
        |values: &[u32], keep: &[u32]| gather_hinted(keep.len(), |i| values[keep[i] as usize]);
    let (network, curve) = match network {
        Some((network, kept_vertices, kept_edges)) => {
            let kept = if odd { kept_vertices } else { kept_edges };
            (Some(network), pick(&coarse.curve, &kept)?)
        }
        None => (None, Vec::new()),
    };
    let curves = (coarse.curves.iter())
        .filter_map(|c| {
            let edge = sub.edge_map[c.edge as usize];
            (edge != NONE).then_some(Curve { edge, ..*c })
        })
        .collect();
    Ok(Some(Part {
        face_uid: pick_ids(&coarse.face_uid, &sub.faces)?,
        vert_uid: pick_ids(&coarse.vert_uid, &sub.vertices)?,
        edge_uid: pick_ids(&coarse.edge_uid, &sub.edges)?,
        edge_faces: pick_counts(&coarse.edge_faces, &sub.edges)?,
        vert_faces: pick_counts(&coarse.vert_faces, &sub.vertices)?,
        curves,
        network,
        data: pick(&coarse.data, if odd { &sub.vertices } else { &sub.faces })?,
        curve,
        points: Vec::new(),
        counts: coarse.counts,
        level: sub.level,
    }))
}

/// `P_0`: the whole cage level with the cage points.
fn cage_part<T: Scalar>(ctx: &Context<T>) -> Part<T> {
    let level0 = ctx.level0.clone();
    let counts = [
        level0.num_vertices as u64,
        level0.num_edges() as u64,
        level0.num_faces() as u64,
        level0.num_corners() as u64,
    ];
    Part {
        face_uid: (0..level0.num_faces() as u64).collect(),
        vert_uid: (0..level0.num_vertices as u64).collect(),
        edge_uid: (0..level0.num_edges() as u64).collect(),
        edge_faces: (0..level0.num_edges())
            .map(|e| level0.edge_valence(e) as u32)
            .collect(),
        vert_faces: (0..level0.num_vertices)
            .map(|v| level0.corners_of_vertex(v).len() as u32)
            .collect(),
        curves: ctx.features.curves(),
        network: None,
        data: ctx.cage.clone(),
        curve: Vec::new(),
        points: Vec::new(),
        counts,
        level: level0,
    }
}

/// The partial levels past a plan's last level `L >= 1` (its refinement, all tables
/// complete) around `seeds` (sorted faces of `M_L`) and those of their descendants that lie near
/// some target vertices, with the margin rings of the degree at every level: the limit's local
/// extension. Their topology does not depend on the data, so it is made once
/// ([`LocalLevels::new`]) and every evaluation runs only the steps on them
/// ([`LocalLevels::evaluate`]). Every value whose stencil lies in the seeds kept at the last
/// level is bitwise the uniform value of that level (module documentation).
///
/// A step refines the whole part but the next part keeps about a quarter of the children (the
/// seeds' and their margin rings), and nothing else of its output is read: with the averaging
/// rules each step makes only the kept items and what they read ([`Windows::for_items`], the
/// same values bit for bit). Cached limits on the callgrind driver (one thread, instructions):
/// `limit-semisharp-4` 30.1M -> 19.4M, `-3` 13.4M -> 11.3M; `limit-ico-9` 294M -> 238M (level
/// 2: 186M -> 130M), `limit-ico-4` 96.4M -> 89.9M (level 2: 44.9M -> 38.5M); first calls from
/// 3.7 % cheaper (`limit-first-semisharp-4`) to 0.6 % dearer (`-3`: the windows are made again
/// for the kept items).
#[derive(Debug)]
pub(crate) struct LocalLevels {
    scheme: Scheme,
    odd: bool,
    /// The items of `M_L` the first partial level keeps: vertices (odd degrees) or faces (even),
    /// and the last step's curve vertices or curve edges.
    keep: Vec<u32>,
    keep_curve: Vec<u32>,
    /// `P_L, P_{L+1}, ...`: the coarse level of each step.
    levels: Vec<Level>,
    steps: Vec<PartStep>,
    /// The last partial level: its topology, uniform ids and curve network (no data).
    last: Part<f64>,
    /// The level of `last`.
    top: usize,
}

impl LocalLevels {
    /// The `extra` partial levels past `refinement`'s last level around `seeds`, whose seeds at
    /// the last level are the faces within `rings` face rings of the `targets` (vertices of
    /// `M_L`; old vertices keep their ids), which `seeds` must hold at `M_L`'s spacing.
    /// Each level keeps only the children of its seeds within `ceil(rings / 2^k)` rings of the
    /// targets, `k` levels above the last (the children of `r` rings hold `2r` rings): along a
    /// curve of targets the levels grow about 2x per level, not 4x as all descendants would.
    pub(crate) fn new(
        refinement: &Refinement,
        seeds: &[u64],
        extra: u32,
        targets: &[u32],
        rings: usize,
    ) -> Result<LocalLevels> {
        let levels = refinement.try_levels()?;
        let last = levels
            .last()
            .ok_or_else(|| Error::Internal("local levels: a refinement without levels".into()))?;
        let network = refinement.last_network("the local levels")?;
        let top = levels.len() - 1;
        let from = (last, network, None, top);
        LocalLevels::grow(refinement, from, seeds, extra, targets, rings)
    }

    /// The `extra` partial levels past this one's last level, as [`LocalLevels::new`] makes
    /// them past a plan's: `seeds` are faces of [`LocalLevels::level`] (sorted), `targets`
    /// still vertices of the plan's last level. Its evaluation starts from this one's.
    pub(crate) fn extend(
        &self,
        refinement: &Refinement,
        seeds: &[u64],
        extra: u32,
        targets: &[u32],
        rings: usize,
    ) -> Result<LocalLevels> {
        let network = self.network()?;
        let from = (&self.last.level, network, Some(&self.last), self.top);
        LocalLevels::grow(refinement, from, seeds, extra, targets, rings)
    }

    /// The partial levels past `from` (a level, the network of the step that made it, its
    /// part when it is partial, and its level index): see [`LocalLevels::new`].
    fn grow(
        refinement: &Refinement,
        from: (&Level, &CurveNetwork, Option<&Part<f64>>, usize),
        seeds: &[u64],
        extra: u32,
        targets: &[u32],
        rings: usize,
    ) -> Result<LocalLevels> {
        let (last, network, ids, top) = from;
        let options = refinement.options();
        let degree = options.degree;
        let ctx: Context<f64> = Context {
            cage: Vec::new(),
            level0: refinement.cage_level().clone(),
            features: refinement.features().clone(),
            scheme: refinement.scheme(),
            degree,
            margin: margin_rings(degree),
            budget: options.memory_budget,
            diagonal: 0.0,
            holes: Vec::new(),
        };
        // The first partial level: the margin rings around the seeds.
        let mut kept = memory::filled(last.num_faces(), false)?;
        let frontier: Vec<usize> = seeds.iter().map(|&f| f as usize).collect();
        for &f in &frontier {
            kept[f] = true;
        }
        last.grow_face_rings(&mut kept, frontier, ctx.margin);
        let sub = restrict(last, &kept)?;
        let (network, kept_vertices, kept_edges) = network.restrict(&sub.vertex_map, &sub.edge_map);
        let odd = degree % 2 == 1;
        // Uniform ids and counts (a plan's level is numbered by them, a partial one has its own).
        let widen = |ids: &[u32], of: Option<&[u64]>| -> Vec<u64> {
            match of {
                Some(uids) => ids.iter().map(|&i| uids[i as usize]).collect(),
                None => ids.iter().map(|&i| i as u64).collect(),
            }
        };
        let (keep, keep_curve) = match odd {
            true => (sub.vertices.clone(), kept_vertices),
            false => (sub.faces.clone(), kept_edges),
        };
        let face_uid = widen(&sub.faces, ids.map(|p| &p.face_uid[..]));
        let mut part: Part<f64> = Part {
            vert_uid: widen(&sub.vertices, ids.map(|p| &p.vert_uid[..])),
            edge_uid: widen(&sub.edges, ids.map(|p| &p.edge_uid[..])),
            edge_faces: (sub.edges.iter())
                .map(|&e| match ids {
                    Some(p) => p.edge_faces[e as usize],
                    None => last.edge_valence(e as usize) as u32,
                })
                .collect(),
            vert_faces: (sub.vertices.iter())
                .map(|&v| match ids {
                    Some(p) => p.vert_faces[v as usize],
                    None => last.corners_of_vertex(v as usize).len() as u32,
                })
                .collect(),
            curves: network.next_curves(),
            network: Some(network),
            data: Vec::new(),
            curve: Vec::new(),
            points: Vec::new(),
            counts: match ids {
                Some(p) => p.counts,
                None => [
                    last.num_vertices as u64,
                    last.num_edges() as u64,
                    last.num_faces() as u64,
                    last.num_corners() as u64,
                ],
            },
            face_uid,
            level: sub.level,
        };
        let mut seeds: Vec<u64> = match ids {
            Some(p) => seeds.iter().map(|&f| p.face_uid[f as usize]).collect(),
            None => seeds.to_vec(),
        };
        let mut levels = Vec::with_capacity(extra as usize);
        let mut steps = Vec::with_capacity(extra as usize);
        let mut held = 0u64;
        for (k, t) in (top..top + extra as usize).enumerate() {
            // The refined level and what is kept so far, asked for before it is made: a typed
            // refusal under the budget, and room that the address space must have (a level's
            // own tables are not allocated fallibly one by one).
            let fine = 4 * part.level.num_faces() as u64;
            let bytes = fine.saturating_mul(4 * BYTES_PER_CORNER);
            memory::check_request(held.saturating_add(bytes), fine, options.memory_budget)?;
            drop(memory::with_capacity::<u8>(
                usize::try_from(bytes).map_err(|_| memory::refused_bytes(bytes))?,
            )?);
            held = held.saturating_add(bytes);
            let near = rings.div_ceil(1 << (extra as usize - k));
            seeds = children(&near_targets(&part, &seeds, targets, near)?)?;
            let (mut step, next) = refine_topology(&ctx, t, &part, Keep::Around(&seeds), false)?;
            // Of each step's output only the items the next part keeps are read (and the
            // stencils read only the last part's): the step makes those alone.
            if let Scheme::Averaging { degree } = ctx.scheme {
                step.windows = Windows::for_items(
                    step.windows.take(),
                    &part.level,
                    &step.fine,
                    degree,
                    primal_input(degree, t),
                    step.keep(odd),
                )?;
            }
            levels.push(std::mem::replace(&mut part, next).level);
            steps.push(step);
        }
        Ok(LocalLevels {
            scheme: ctx.scheme,
            odd,
            keep,
            keep_curve,
            levels,
            steps,
            last: part,
            top: top + extra as usize,
        })
    }

    /// The faces of the refined levels its evaluation makes: the work of one evaluation.
    pub(crate) fn num_faces(&self) -> u64 {
        self.steps.iter().map(|s| s.fine.num_faces() as u64).sum()
    }

    /// The last partial level.
    pub(crate) fn level(&self) -> &Level {
        &self.last.level
    }

    /// The uniform ids of the last level's faces (sorted).
    pub(crate) fn face_uid(&self) -> &[u64] {
        &self.last.face_uid
    }

    /// The uniform ids of the last level's vertices (sorted).
    pub(crate) fn vert_uid(&self) -> &[u64] {
        &self.last.vert_uid
    }

    /// The curve network of the step that made the last level, restricted to it.
    pub(crate) fn network(&self) -> Result<&CurveNetwork> {
        (self.last.network.as_ref()).ok_or_else(|| {
            Error::Internal("local levels: a refined part without its network".into())
        })
    }

    /// The data of the last partial level as a plan's run leaves it (per vertex for odd degrees,
    /// per face for even ones; 1-D data per curve vertex or edge), from the `cage` points and
    /// the plan's last level's `data` and 1-D `curve` data as its run leaves them.
    pub(crate) fn evaluate<T: Scalar>(
        &self,
        cage: &[P<T>],
        data: &[P<T>],
        curve: &[P<T>],
    ) -> Result<Parts<T, 3>> {
        let pick = |values: &[P<T>], keep: &[u32]| -> Result<Vec<P<T>>> {
            memory::collect(keep.iter().map(|&i| values[i as usize]))
        };
        let mut data = pick(data, &self.keep)?;
        let mut curve = pick(curve, &self.keep_curve)?;
        let scratch = Scratch::default();
        for (step, coarse) in self.steps.iter().zip(&self.levels) {
            let at = Some((&data[..], curve));
            let (fine_data, fine_curve) = step
                .advance(self.scheme, self.odd, coarse, cage, at, &scratch)?
                .into_parts();
            data = pick(&fine_data, step.keep(self.odd))?;
            curve = pick(&fine_curve, &step.keep_curve)?;
            scratch.give(fine_data);
        }
        Ok((data, curve))
    }
}

/// The faces of `seeds` (sorted uniform ids of faces of `part`) within `rings` face rings (at
/// least one: the faces at the vertex) of the `targets` (uniform vertex ids, all in `part`).
fn near_targets<T>(
    part: &Part<T>,
    seeds: &[u64],
    targets: &[u32],
    rings: usize,
) -> Result<Vec<u64>> {
    let level = &part.level;
    let mut marked = memory::filled(level.num_faces(), false)?;
    let mut frontier = Vec::new();
    for &v in targets {
        let w = (part.vert_uid.binary_search(&(v as u64)))
            .map_err(|_| Error::Internal(format!("local levels: target vertex {v} missing")))?;
        for &c in level.corners_of_vertex(w) {
            let f = level.face_of(c as usize);
            if !marked[f] {
                marked[f] = true;
                frontier.push(f);
            }
        }
    }
    level.grow_face_rings(&mut marked, frontier, rings.max(1) - 1);
    Ok((seeds.iter().copied())
        .filter(|&uid| part.face_of_uid(uid).is_some_and(|f| marked[f]))
        .collect())
}

/// Which faces of a refined partial level are kept.
#[derive(Clone, Copy)]
enum Keep<'a> {
    /// The margin rings around these seeds (sorted uniform ids).
    Around(&'a [u64]),
    /// Exactly these faces (sorted uniform ids).
    Faces(&'a [u64]),
    /// Every face of the refined level: made from the margin rings around the parents of its
    /// seeds ([`around_parents`]), its data are exact on the margin rings around the seeds,
    /// which is all that is read of it, and a restriction to them would cost more than the
    /// refinement that made them.
    All,
}

/// The topology of one step `P_t -> P_{t+1}` ([`refine_topology`]): the refined level, the
/// curve network of the step, and what of them the next part keeps.
#[derive(Debug)]
struct PartStep {
    fine: Level,
    network: CurveNetwork,
    /// The vertices and faces of `fine` that the next part keeps.
    vertices: Vec<u32>,
    faces: Vec<u32>,
    /// The step's curve vertices (odd degrees) or curve edges (even) that it keeps.
    keep_curve: Vec<u32>,
    /// Whether the next part is the whole fine level (`vertices`, `faces` and `keep_curve` are
    /// then empty).
    whole: bool,
    /// The averaging rules: the step's regular windows, built with its topology so that the
    /// local levels of a limit, evaluated on every call, do not build them again (a cached
    /// limit on the 4k ico cage at level 3: degree 9 1448M -> 1030M instructions, degree 4
    /// 247M -> 231M).
    windows: Option<Windows>,
}

impl PartStep {
    /// The items of the fine level whose data the next part keeps: vertices (odd degrees) or
    /// faces (even).
    fn keep(&self, odd: bool) -> &[u32] {
        debug_assert!(!self.whole, "a whole level keeps every item");
        match odd {
            true => &self.vertices,
            false => &self.faces,
        }
    }

    /// The step primitive on `coarse`, the part the step refines, with its 2-D and 1-D `data`
    /// (`None` on the cage's level, whose data are the `cage` points): the fine level's data,
    /// whole, its buffers from `scratch`.
    fn advance<'a, T: Scalar>(
        &self,
        scheme: Scheme,
        odd: bool,
        coarse: &Level,
        cage: &'a [P<T>],
        data: Option<LevelParts<'a, T>>,
        scratch: &'a Scratch,
    ) -> Result<LevelData<'a, T, 3>> {
        let step = self.step(scheme, coarse);
        let mut run = match data {
            None => LevelData::new(cage),
            Some((data, curve)) => LevelData::on_level(cage, odd, data, curve),
        }
        .with_scratch_for(scratch, &step)?;
        run.step(&step)?;
        Ok(run)
    }

    fn step<'a>(&'a self, scheme: Scheme, coarse: &'a Level) -> Step<'a> {
        Step {
            scheme,
            coarse,
            fine: &self.fine,
            curves: &self.network,
            sharpness: None,
            windows: self.windows.as_ref(),
            smooth_points: None,
        }
    }
}

/// One step `P_t -> P_{t+1}`: refine, evaluate, keep the faces `keep` names.
fn refine_part<T: Scalar>(
    ctx: &Context<T>,
    t: usize,
    coarse: &Part<T>,
    keep: Keep,
) -> Result<Part<T>> {
    let odd = ctx.degree % 2 == 1;
    // Even degrees draw every level: the windows hold the fused drawing points.
    let (step, mut next) = refine_topology(ctx, t, coarse, keep, !odd)?;
    let scratch = Scratch::default();
    let data = (t > 0).then(|| (&coarse.data[..], coarse.curve.clone()));
    let run = step.advance(ctx.scheme, odd, &coarse.level, &ctx.cage, data, &scratch)?;
    // The drawing points: the primal data, or one more dual -> primal average (fused from the
    // coarse data where the uniform plan's drawn step fuses them).
    let drawing = match odd {
        true => None,
        false => {
            let step = step.step(ctx.scheme, &coarse.level);
            Some(run.drawing_points(&step, (t > 0).then_some(&coarse.data[..]))?)
        }
    };
    let (data, curve) = run.into_parts();
    if step.whole {
        next.points = match drawing {
            Some(points) => points,
            None => memory::collect(data.iter().copied())?,
        };
        next.data = data;
        next.curve = curve;
        next.level = step.fine;
        return Ok(next);
    }
    let points = drawing.as_deref().unwrap_or(&data);
    let pick =
        |values: &[P<T>], keep: &[u32]| gather_hinted(keep.len(), |i| values[keep[i] as usize]);
    next.points = pick(points, &step.vertices)?;
    next.data = pick(&data, step.keep(odd))?;
    next.curve = pick(&curve, &step.keep_curve)?;
    Ok(next)
}

/// The topology of one step `P_t -> P_{t+1}`: refine, keep the faces `keep` names. Returns the
/// step and the next part, without data (and, when it keeps every face, without its level,
/// which is the step's fine level).
fn refine_topology<T: Sync, U>(
    ctx: &Context<U>,
    t: usize,
    coarse: &Part<T>,
    keep: Keep,
    draw: bool,
) -> Result<(PartStep, Part<T>)> {
    let c = &coarse.level;
    let [nv, ne, nf, ncorners] = coarse.counts;
    let (cnv, cne) = (c.num_vertices, c.num_edges());
    let corner_uid = |k: usize| -> u64 {
        if t == 0 {
            k as u64
        } else {
            4 * coarse.face_uid[k >> 2] + (k & 3) as u64
        }
    };
    // Uniform ids of the fine level, asked for only where the next part keeps an item.
    let vert_uid = |w: usize| -> u64 {
        if w < cnv {
            coarse.vert_uid[w]
        } else if w < cnv + cne {
            nv + coarse.edge_uid[w - cnv]
        } else {
            nv + ne + coarse.face_uid[w - cnv - cne]
        }
    };
    let edge_uid = |i: usize| -> u64 {
        if i < 2 * cne {
            2 * coarse.edge_uid[i >> 1] + (i & 1) as u64
        } else {
            2 * ne + corner_uid(i - 2 * cne)
        }
    };
    let edge_faces = |i: usize| -> u32 {
        if i < 2 * cne {
            coarse.edge_faces[i >> 1]
        } else {
            2
        }
    };
    let vert_faces = |w: usize| -> u32 {
        if w < cnv {
            coarse.vert_faces[w]
        } else if w < cnv + cne {
            2 * coarse.edge_faces[w - cnv]
        } else {
            c.face_corners(w - cnv - cne).len() as u32
        }
    };

    // The curve network of this partial level, as the uniform plan makes it (its corners are
    // the cage's tagged vertices that it has; a corner keeps the point of its cage vertex).
    let nv0 = ctx.level0.num_vertices as u64;
    let corners: Vec<(u32, f32)> = (ctx.features.corners.iter())
        .filter_map(|&(v, s)| {
            let at = coarse.vert_uid.binary_search(&(v as u64)).ok()?;
            Some((at as u32, s))
        })
        .collect();
    let pin = |v: u32| {
        let uid = coarse.vert_uid[v as usize];
        if uid < nv0 {
            uid as u32
        } else {
            NONE
        }
    };
    let odd = ctx.degree % 2 == 1;
    // The refinement and the curve network read only the coarse level: side by side.
    let (fine, network) = rayon::join(
        || c.refine(),
        || {
            CurveNetwork::build(
                c,
                &coarse.curves,
                &corners,
                t as u32,
                coarse.network.as_ref(),
                odd,
                pin,
            )
        },
    );
    let (fine, network) = (fine?, network?);

    // Built even where they cost more than the passes they spare (the adaptive partial levels:
    // 14M of `adaptive-flat-4-6`'s 400M, 2026-12-04): the kernel's sums are not the passes' bit
    // for bit, and a partial level's points must be the uniform plan's, which uses them. The
    // uniform ids of a whole level (serial section copies) are made beside them.
    let scheme = ctx.scheme;
    let (windows, ids) = rayon::join(
        || match scheme {
            Scheme::Averaging { degree } => {
                let draw = if draw { Drawing::Now } else { Drawing::Skip };
                Windows::of_step(c, &fine, &network, degree, t, draw)
            }
            _ => Ok(None),
        },
        || match keep {
            Keep::All => whole_ids(coarse, t, &fine).map(Some),
            _ => Ok(None),
        },
    );
    let (windows, ids) = (windows?, ids?);
    let counts = [nv + ne + nf, 2 * ne + ncorners, ncorners, 4 * ncorners];
    // The seeds and the margin rings around them, or the faces named.
    let (seeds, margin) = match (keep, ids) {
        (Keep::Around(seeds), _) => (seeds, ctx.margin),
        (Keep::Faces(faces), _) => (faces, 0),
        (Keep::All, None) => {
            return Err(Error::Internal(
                "adaptive: a whole level without its ids".into(),
            ))
        }
        (Keep::All, Some(ids)) => {
            let next = Part {
                face_uid: ids.face_uid,
                vert_uid: ids.vert_uid,
                edge_uid: ids.edge_uid,
                edge_faces: ids.edge_faces,
                vert_faces: ids.vert_faces,
                curves: network.next_curves(),
                network: Some(network.clone()),
                data: Vec::new(),
                curve: Vec::new(),
                points: Vec::new(),
                counts,
                level: Level::default(),
            };
            let step = PartStep {
                fine,
                network,
                vertices: Vec::new(),
                faces: Vec::new(),
                keep_curve: Vec::new(),
                whole: true,
                windows,
            };
            return Ok((step, next));
        }
    };
    let mut keep = memory::filled(fine.num_faces(), false)?;
    // Both lists are sorted: one merge walk finds every seed.
    let mut f = 0;
    let nfine = fine.num_faces();
    for &s in seeds {
        while f < nfine && corner_uid(f) < s {
            f += 1;
        }
        if f == nfine || corner_uid(f) != s {
            return Err(Error::Internal(format!(
                "adaptive: seed face {s} of level {} missing",
                t + 1
            )));
        }
        keep[f] = true;
    }
    let keep = grow_rings(&fine, keep, margin)?;

    let sub = restrict(&fine, &keep)?;
    let (kept_network, kept_vertices, kept_edges) =
        network.restrict(&sub.vertex_map, &sub.edge_map);
    fn pick<V: Send>(map: &[u32], of: impl Fn(usize) -> V + Sync + Send) -> Result<Vec<V>> {
        gather_hinted(map.len(), |i| of(map[i] as usize))
    }
    let next = Part {
        face_uid: pick(&sub.faces, corner_uid)?,
        vert_uid: pick(&sub.vertices, vert_uid)?,
        edge_uid: pick(&sub.edges, edge_uid)?,
        edge_faces: pick(&sub.edges, edge_faces)?,
        vert_faces: pick(&sub.vertices, vert_faces)?,
        curves: kept_network.next_curves(),
        network: Some(kept_network),
        data: Vec::new(),
        curve: Vec::new(),
        points: Vec::new(),
        counts,
        level: sub.level,
    };
    let step = PartStep {
        fine,
        network,
        vertices: sub.vertices,
        faces: sub.faces,
        keep_curve: if odd { kept_vertices } else { kept_edges },
        whole: false,
        windows,
    };
    Ok((step, next))
}

/// The uniform ids and counts of a whole refined level ([`Keep::All`]).
struct WholeIds {
    face_uid: Vec<u64>,
    vert_uid: Vec<u64>,
    edge_uid: Vec<u64>,
    edge_faces: Vec<u32>,
    vert_faces: Vec<u32>,
}

/// [`WholeIds`] of `fine`, the whole refinement of `coarse` (level `t`), section by section of
/// the refined numbering (old vertices, edge points, face points; edge halves, then the edges
/// inside the faces, one per corner): copies and offsets of the coarse tables in plain loops,
/// where a gather per item took a three-way branch (module notes: `adaptive-flat-4-6` 387.2M
/// -> 366.7M instructions).
fn whole_ids<T>(coarse: &Part<T>, t: usize, fine: &Level) -> Result<WholeIds> {
    let c = &coarse.level;
    let [nv, ne, _, _] = coarse.counts;
    // Past the cage every level is quads: corner k is corner k & 3 of face k >> 2, and fine
    // face k is that corner's child.
    let face_uid: Vec<u64> = if t == 0 {
        memory::collect(0..c.num_corners() as u64)?
    } else {
        memory::collect(
            (coarse.face_uid.iter()).map(|&f| [4 * f, 4 * f + 1, 4 * f + 2, 4 * f + 3]),
        )?
        .into_flattened()
    };
    let mut vert_uid = with_capacity_hinted::<u64>(fine.num_vertices)?;
    vert_uid.extend_from_slice(&coarse.vert_uid);
    vert_uid.extend(coarse.edge_uid.iter().map(|&e| nv + e));
    vert_uid.extend(coarse.face_uid.iter().map(|&f| nv + ne + f));
    let mut edge_uid = with_capacity_hinted::<u64>(fine.num_edges())?;
    edge_uid.extend((coarse.edge_uid.iter()).flat_map(|&e| [2 * e, 2 * e + 1]));
    edge_uid.extend(face_uid.iter().map(|&k| 2 * ne + k));
    let mut edge_faces = with_capacity_hinted::<u32>(fine.num_edges())?;
    edge_faces.extend((coarse.edge_faces.iter()).flat_map(|&n| [n, n]));
    edge_faces.resize(fine.num_edges(), 2);
    let mut vert_faces = with_capacity_hinted::<u32>(fine.num_vertices)?;
    vert_faces.extend_from_slice(&coarse.vert_faces);
    vert_faces.extend(coarse.edge_faces.iter().map(|&n| 2 * n));
    vert_faces.extend((0..c.num_faces()).map(|f| c.face_corners(f).len() as u32));
    if face_uid.len() != fine.num_faces()
        || vert_uid.len() != fine.num_vertices
        || edge_uid.len() != fine.num_edges()
        || edge_faces.len() != fine.num_edges()
        || vert_faces.len() != fine.num_vertices
    {
        return Err(Error::Internal(format!(
            "adaptive: level {} does not refine its part's tables",
            t + 1
        )));
    }
    Ok(WholeIds {
        face_uid,
        vert_uid,
        edge_uid,
        edge_faces,
        vert_faces,
    })
}

/// The faces of the quad level `level` within `rings` vertex rings of the faces `marked`: each
/// ring adds the faces sharing a vertex with the last (as [`Level::grow_face_rings`]), as two
/// gathers in fixed chunks (the vertices of marked faces, the faces at marked vertices) rather
/// than a walk from a frontier, so that it runs in parallel with a result independent of the
/// threads.
fn grow_rings(level: &Level, marked: Vec<bool>, rings: usize) -> Result<Vec<bool>> {
    let (offsets, corners) = level.vertex_corner_table();
    let mut faces = marked;
    for _ in 0..rings {
        let at_vertex = gather_hinted(level.num_vertices, |v| {
            (corners[offsets[v] as usize..offsets[v + 1] as usize].iter())
                .any(|&c| faces[c as usize >> 2])
        })?;
        faces = gather_hinted(level.num_faces(), |f| {
            (level.corner_verts[4 * f..4 * f + 4].iter()).any(|&v| at_vertex[v as usize])
        })?;
    }
    Ok(faces)
}

/// A level restricted to some of its faces, with the old ids of what it kept and the new id of
/// every old vertex and edge (`NONE` if dropped).
struct Sub {
    level: Level,
    faces: Vec<u32>,
    vertices: Vec<u32>,
    edges: Vec<u32>,
    vertex_map: Vec<u32>,
    edge_map: Vec<u32>,
}

/// The quad level `fine` restricted to the faces marked in `keep`, numbered in the order of the
/// old ids; each vertex keeps its corners in the old order, each edge its faces in the old slot
/// order (a lone remaining face moves to the first slot). The new ids are numbered in one
/// sequential scan of each map, and every table is a gather or a prefix sum in fixed chunks
/// ([`crate::parallel`]), so the result does not depend on the threads.
fn restrict(fine: &Level, keep: &[bool]) -> Result<Sub> {
    let kept_face = |c: u32| c != NONE && keep[c as usize >> 2];
    let (offsets, corners) = fine.vertex_corner_table();
    let corners_of = |v: usize| &corners[offsets[v] as usize..offsets[v + 1] as usize];
    let manifold = fine.edges().more.is_empty();
    // New ids in the order of the old ones. The kept faces mark their vertices and edges (a
    // vertex or an edge is kept with a kept face that has it), then one scan of each map numbers
    // what is marked: a few instructions per item of the level and the rest in proportion to
    // what is kept. The limit restricts a plan's whole last level to a few per cent of its
    // faces (5,880 of 245,760 on the 4k sphere at level 3), where prefix sums over every face,
    // vertex and edge with a test of each one's corners cost 77M instructions, now 16M. (Maps
    // of bits with ranks instead of these tables touch less memory, but without a population
    // count in the processor's baseline their lookups cost more than the tables' page faults
    // save: measured, a first limit at degree 9, whose partial levels keep half, took 2.5 %
    // more instructions.)
    // The faces are numbered as they are read (the same as marking them and numbering the
    // marks, one scan of the level's faces less).
    let mut faces: Vec<u32> = memory::with_capacity(keep.iter().filter(|&&k| k).count())?;
    let mut face_at = memory::filled(keep.len(), NONE)?;
    for (f, _) in keep.iter().enumerate().filter(|&(_, &k)| k) {
        face_at[f] = faces.len() as u32;
        faces.push(f as u32);
    }
    let mut vert_map = memory::filled(fine.num_vertices, NONE)?;
    let mut edge_map = memory::filled(fine.num_edges(), NONE)?;
    for &f in &faces {
        let corners = 4 * f as usize..4 * f as usize + 4;
        for (&v, &e) in fine.corner_verts[corners.clone()]
            .iter()
            .zip(&fine.corner_edges()[corners])
        {
            vert_map[v as usize] = 0;
            edge_map[e as usize] = 0;
        }
    }
    let vertices = number_marked(&mut vert_map)?;
    let edges = number_marked(&mut edge_map)?;
    let corner_map = |c: u32| -> u32 {
        match face_at[c as usize >> 2] {
            NONE => NONE,
            at => 4 * at + (c & 3),
        }
    };
    // A face's four corners at once (one lookup of the face).
    let quad_of = |table: &[u32], map: &[u32], i: usize| -> [u32; 4] {
        let first = 4 * faces[i] as usize;
        std::array::from_fn(|k| map[table[first + k] as usize])
    };
    let face_tables = || -> Result<_> {
        let corner_verts =
            gather_hinted(faces.len(), |i| quad_of(&fine.corner_verts, &vert_map, i))?;
        let corner_edges =
            gather_hinted(faces.len(), |i| quad_of(fine.corner_edges(), &edge_map, i))?;
        Ok((corner_verts.into_flattened(), corner_edges.into_flattened()))
    };
    let edge_tables = || -> Result<_> {
        let edge_verts = gather_hinted(edges.len(), |i| {
            fine.edge_verts()[edges[i] as usize].map(|v| vert_map[v as usize])
        })?;
        let mut more = Vec::new();
        let edge_corners: Vec<[u32; 2]> = if manifold {
            // Two slots at most: the common case, without the slot iterator.
            gather_hinted(edges.len(), |i| {
                let [a, b] = fine.edge_corners()[edges[i] as usize].map(|c| {
                    if c == NONE {
                        NONE
                    } else {
                        corner_map(c)
                    }
                });
                if a == NONE {
                    [b, NONE]
                } else {
                    [a, b]
                }
            })?
        } else {
            let mut edge_corners = memory::with_capacity(edges.len())?;
            for (i, &e) in edges.iter().enumerate() {
                let mut slots = (fine.edge_slots(e as usize))
                    .map(corner_map)
                    .filter(|&c| c != NONE);
                edge_corners.push([slots.next().unwrap_or(NONE), slots.next().unwrap_or(NONE)]);
                more.extend(slots.map(|c| (i as u32, c)));
            }
            edge_corners
        };
        Ok((edge_verts, edge_corners, more))
    };
    // Per vertex kept, its corners kept.
    let vertex_tables = || -> Result<_> {
        let vert_corner_offsets = prefix_offsets(vertices.len(), |i| {
            (corners_of(vertices[i] as usize).iter())
                .filter(|&&c| kept_face(c))
                .count() as u32
        })?;
        let mut vert_corners = zeroed_hinted::<u32>(4 * faces.len())?;
        fill_csr(&vert_corner_offsets, &mut vert_corners, |i, out| {
            let kept = (corners_of(vertices[i] as usize).iter())
                .map(|&c| corner_map(c))
                .filter(|&c| c != NONE);
            for (o, c) in out.iter_mut().zip(kept) {
                *o = c;
            }
        });
        Ok((vert_corner_offsets, vert_corners))
    };
    let ((face_tables, edge_tables), vertex_tables) =
        rayon::join(|| rayon::join(face_tables, edge_tables), vertex_tables);
    let ((corner_verts, corner_edges), (edge_verts, edge_corners, more)) =
        (face_tables?, edge_tables?);
    let (vert_corner_offsets, vert_corners) = vertex_tables?;
    let mut level = Level::from_quad_tables(
        vertices.len(),
        corner_verts,
        Edges {
            corner_edges,
            verts: edge_verts,
            corners: edge_corners,
            more,
        },
        vert_corner_offsets,
        vert_corners,
    );
    // The non-manifold tags of what is kept (the maps keep the order: still sorted).
    let kept = |tags: &[u32], map: &[u32]| -> Vec<u32> {
        (tags.iter())
            .map(|&x| map[x as usize])
            .filter(|&x| x != NONE)
            .collect()
    };
    level.nm_edges = kept(&fine.nm_edges, &edge_map);
    level.nm_vertices = kept(&fine.nm_vertices, &vert_map);
    Ok(Sub {
        level,
        faces,
        vertices,
        edges,
        vertex_map: vert_map,
        edge_map,
    })
}

/// Numbers the items marked in `map` (any value but `NONE`) in the order of their ids, writing
/// each one's new id in its place, and returns the marked items in order.
fn number_marked(map: &mut [u32]) -> Result<Vec<u32>> {
    let count = map.iter().filter(|&&m| m != NONE).count();
    let mut items: Vec<u32> = memory::with_capacity(count)?;
    for (i, m) in map.iter_mut().enumerate() {
        if *m != NONE {
            *m = items.len() as u32;
            items.push(i as u32);
        }
    }
    Ok(items)
}

/// Flatness of nodes at level `t` (see the module documentation), from their children's
/// drawing points at level `t + 1`.
fn measure<T: Scalar>(
    ctx: &Context<T>,
    parts: &[Part<T>],
    t: usize,
    nodes: &[u64],
) -> Result<Vec<f64>> {
    let fine = &parts[t + 1];
    let scale_by = if ctx.diagonal > 0.0 {
        1.0 / ctx.diagonal
    } else {
        1.0
    };
    let p = |v: u32| -> [f64; 3] { fine.points[v as usize].map(|x| x.to_f64()) };
    let errors = gather_hinted(nodes.len(), |i| -> Result<f64> {
        let u = nodes[i];
        let mut corner = [[0.0; 3]; 4];
        let mut mid = [[0.0; 3]; 4];
        let mut centre = [0.0; 3];
        // The four children have consecutive uniform ids, so consecutive places.
        let first = fine
            .face_of_uid(4 * u)
            .filter(|&f| fine.face_uid.get(f + 3) == Some(&(4 * u + 3)))
            .ok_or_else(|| {
                Error::Internal(format!("adaptive: child of node {u} (level {t}) missing"))
            })?;
        for k in 0..4 {
            let f = first + k;
            let q = &fine.level.corner_verts[4 * f..4 * f + 4];
            corner[k] = p(q[0]);
            mid[k] = p(q[1]);
            centre = p(q[2]);
        }
        Ok(flatness(&corner, &mid, centre) * scale_by)
    })?;
    errors.into_iter().collect()
}

/// The flatness of a node (module documentation) from its children's points: its `corner`s,
/// the `mid`points of its edges (edge k from corner k to k + 1) and its `centre`; absolute.
fn flatness(corner: &[[f64; 3]; 4], mid: &[[f64; 3]; 4], centre: [f64; 3]) -> f64 {
    let dist = |a: [f64; 3], b: [f64; 3]| -> f64 {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    };
    let mut error = 0.0f64;
    let mut mean = [0.0; 3];
    for k in 0..4 {
        let (a, b) = (corner[k], corner[(k + 1) & 3]);
        let m = [0, 1, 2].map(|i| 0.5 * (a[i] + b[i]));
        error = error.max(dist(mid[k], m));
        for i in 0..3 {
            mean[i] += 0.25 * a[i];
        }
    }
    error.max(dist(centre, mean))
}

/// The children's points of a node on a grid in closed form, to decide its refinement without
/// making its children. Where the faces around a node form a grid (every vertex inside its
/// window interior, manifold, complete, of valence 4, on no curve of the step and no tagged
/// corner), a step of the averaging rules and the drawing average are the tensor-product
/// B-spline (`step::regular`): each of the nine points is `sum W_p(x) W_q(y) d(x, y)` over the
/// level's data in the node's frame, with the 1-D weights of replication and the averages
/// below. These sums are not the step's, so they differ from its points by rounding: a node is
/// decided only when its error is farther from the tolerance than `slack` times the magnitude
/// of its data (an upper bound of both roundings); the others are measured on their children.
#[derive(Debug)]
struct Grid {
    /// Whether the data are per vertex (odd degrees) or per face.
    odd: bool,
    /// Lowest data position (cell or vertex) in the node's frame; the node is cell `(0, 0)`,
    /// its corner 0 vertex `(0, 0)`.
    lo: i32,
    /// Cells placed around the node in each direction.
    reach: i32,
    /// Vertices at positions `-inner..=inner + 1` must be regular.
    inner: i32,
    /// Per child position p (0, 1/2, 1, 3/2, 2 of the node's side: p = 0..=4), the weight of
    /// each data position from `lo` on (one more than a node reads, for a sibling block).
    weights: [Vec<f64>; 5],
    /// Per child position, the data positions of its nonzero weights (one run: replication and
    /// averages spread each child over consecutive positions), so the sums skip the zeros.
    taps: [std::ops::Range<usize>; 5],
    /// Bound of the rounding of both computations of the error, per unit of data magnitude
    /// (relative to the cage diagonal).
    slack: f64,
}

impl Grid {
    /// The closed form of `ctx`'s step, `None` for rules it does not cover (classic ones).
    fn new<T: Scalar>(ctx: &Context<T>) -> Option<Grid> {
        let Scheme::Averaging { degree } = ctx.scheme else {
            return None;
        };
        let n = degree as i64;
        let odd = n % 2 == 1;
        // The drawing points are n + 1 averages of dual data (even degrees: the step's n and
        // the drawing one) or n averages of primal data (odd) after replication, whose fine
        // face m (position m / 2 .. (m + 1) / 2) holds coarse face floor(m / 2) or coarse
        // vertex ceil(m / 2); fine vertex p averages fine faces p - (a + 1) / 2 .. p + a / 2
        // with the binomial weights of a averages.
        let a = if odd { n } else { n + 1 };
        let first = |p: i64| p - (a + 1) / 2;
        let source = |m: i64| {
            if odd {
                m.div_euclid(2) + m.rem_euclid(2)
            } else {
                m.div_euclid(2)
            }
        };
        let lo = source(first(0));
        let hi = source(first(2) + a);
        // Row a of Pascal's triangle.
        let binomial: Vec<f64> = (0..a).fold(vec![1.0f64], |row, _| {
            let mut next = vec![1.0; row.len() + 1];
            for i in 1..row.len() {
                next[i] = row[i - 1] + row[i];
            }
            next
        });
        let half_a = 0.5f64.powi(a as i32);
        // Positions p = 0..=4: the children of a sibling block (two cells) too.
        let weights = [0, 1, 2, 3, 4].map(|p| {
            let mut w = vec![0.0; (hi - lo + 2) as usize];
            for i in 0..=a {
                w[(source(first(p) + i) - lo) as usize] += binomial[i as usize] * half_a;
            }
            w
        });
        // Vertices where the averages run: old vertices within (n - 1) / 4 (odd) or n / 4
        // (even) of the node.
        let inner = if odd { (n - 1) / 4 } else { n / 4 } as i32;
        let reach = if odd {
            (-lo).max(hi - 1)
        } else {
            (-lo).max(hi)
        } as i32;
        // The window must lie in the margin kept around every node, and in the arrays of
        // [`decide`].
        let margin = ctx.margin as i32;
        let side = 2 * reach as usize + 1;
        if reach > margin || inner + 1 > margin || inner > reach || side > GRID_SIDE {
            return None;
        }
        let scale_by = if ctx.diagonal > 0.0 {
            1.0 / ctx.diagonal
        } else {
            1.0
        };
        let taps = weights.each_ref().map(|w| {
            let first = w.iter().position(|&x| x != 0.0).unwrap_or(0);
            let end = w.iter().rposition(|&x| x != 0.0).map_or(first, |l| l + 1);
            first..end
        });
        Some(Grid {
            odd,
            lo: lo as i32,
            reach,
            inner: inner.max(reach - 1),
            weights,
            taps,
            slack: 256.0 * (n as f64 + 2.0) * T::UNIT_ROUNDOFF * scale_by,
        })
    }
}

/// Largest side, in cells, of a [`Grid`] window (its data positions are at most one more);
/// higher degrees measure every node on its children.
const GRID_SIDE: usize = 15;

/// Per node of level `t` (sorted uniform ids of faces of `part`): whether its error is above
/// the tolerance (`Some`), decided by `grid`'s closed form, or `None` where its children must
/// be measured (no grid around it, or its error too near the tolerance). From level 2 on the
/// nodes come in sibling blocks (the four children of a refined node, a 2 x 2 block of cells),
/// evaluated together: one walk and one set of sums serve the four.
fn decide<T: Scalar>(
    ctx: &Context<T>,
    grid: &Option<Grid>,
    t: usize,
    part: &Part<T>,
    nodes: &[u64],
    tolerance: f64,
) -> Result<Vec<Option<bool>>> {
    let Some(grid) = grid else {
        return memory::filled(nodes.len(), None);
    };
    // Two independent tables, side by side (each a few short passes).
    let (regular, twins) = rayon::join(|| regular_faces(ctx, part), || grid_twins(part));
    let (regular, twins) = (regular?, twins?);
    // Blocks of nodes: the four siblings from level 2 on (always all four: nodes are the
    // children of refined nodes, and holes are whole cage faces), single nodes at level 1.
    let span = if t >= 2 && nodes.len().is_multiple_of(4) {
        2
    } else {
        1
    };
    let scale_by = scale_of(ctx);
    let blocks = gather_grain(
        nodes.len() / span / span,
        BLOCK_GRAIN,
        |i| -> [Option<bool>; 4] {
            let block = &nodes[span * span * i..span * span * (i + 1)];
            let mut out = [None; 4];
            if let Some(errors) = block_errors(grid, part, &regular, &twins, span, block) {
                for (o, (error, slack)) in out.iter_mut().zip(errors) {
                    let error = error * scale_by;
                    let slack = slack * scale_by;
                    *o = if error + slack < tolerance {
                        Some(false)
                    } else if error - slack > tolerance {
                        Some(true)
                    } else {
                        None
                    };
                }
            }
            out
        },
    )?;
    memory::collect(
        (blocks.iter())
            .flat_map(|b| b[..span * span].iter().copied())
            .take(nodes.len()),
    )
}

/// Sibling blocks per parallel task of [`decide`]: about 8k instructions each, so that a level
/// of a few thousand blocks is shared out over many threads (in [`crate::parallel::CHUNK`]s of
/// blocks, the decisions of level 4 of `adaptive-flat-4-6` were one task).
const BLOCK_GRAIN: usize = 32;

/// Per face of `part`: whether its four vertices can all be inside a grid (complete, interior,
/// manifold, of valence 4, on no curve edge of the step and no tagged corner). A grid's
/// vertices are the corners of a square of cells, so [`block_errors`] checks the cells, one
/// lookup each, rather than every vertex.
fn regular_faces<T: Scalar>(ctx: &Context<T>, part: &Part<T>) -> Result<Vec<bool>> {
    let level = &part.level;
    let mut on_curve = memory::filled(level.num_vertices, false)?;
    let mut curve_edge = memory::filled(level.num_edges(), false)?;
    for c in &part.curves {
        curve_edge[c.edge as usize] = true;
        for v in level.edge_verts()[c.edge as usize] {
            on_curve[v as usize] = true;
        }
    }
    let nv0 = ctx.level0.num_vertices as u64;
    let corners = &ctx.features.corners;
    let (offsets, vertex_corners) = level.vertex_corner_table();
    let corner_edges = level.corner_edges();
    let regular = gather_hinted(level.num_vertices, |v| {
        let at = &vertex_corners[offsets[v] as usize..offsets[v + 1] as usize];
        let uid = part.vert_uid[v];
        at.len() == 4
            && part.vert_faces[v] == 4
            && !on_curve[v]
            && !(uid < nv0 && corners.binary_search_by_key(&(uid as u32), |c| c.0).is_ok())
            && level.nm_vertices.binary_search(&(v as u32)).is_err()
            && at.iter().all(|&c| {
                let c = c as usize;
                let (e, d) = (corner_edges[c], corner_edges[(c & !3) | ((c + 3) & 3)]);
                part.edge_faces[e as usize] == 2
                    && part.edge_faces[d as usize] == 2
                    && !curve_edge[e as usize]
                    && !curve_edge[d as usize]
            })
    })?;
    gather_hinted(level.num_faces(), |f| {
        (level.corner_verts[4 * f..4 * f + 4].iter()).all(|&v| regular[v as usize])
    })
}

/// Per corner `c` of `part`: the corner of the face across its outgoing edge that leaves the
/// vertex `c`'s edge arrives at, where that edge has two faces in the uniform level, both here,
/// running opposite ways (as on a grid); `NONE` elsewhere. One table for the level, so that the
/// walks of [`block_errors`] cross a side in one lookup.
fn grid_twins<T: Sync>(part: &Part<T>) -> Result<Vec<u32>> {
    let level = &part.level;
    let corner_edges = level.corner_edges();
    let edge_corners = level.edge_corners();
    gather_hinted(level.num_corners(), |c| {
        let e = corner_edges[c] as usize;
        if part.edge_faces[e] != 2 {
            return NONE;
        }
        let [c0, c1] = edge_corners[e];
        let d = if c0 as usize == c { c1 } else { c0 };
        let ahead = (c & !3) | ((c + 1) & 3);
        if d == NONE || level.corner_verts[d as usize] != level.corner_verts[ahead] {
            NONE
        } else {
            d
        }
    })
}

/// The closed-form errors (absolute) and their rounding bounds of the nodes of `block` (one
/// node, or four siblings in their order), `None` unless a grid holds them all; `regular` is
/// [`regular_faces`] and `twins` [`grid_twins`] of `part`.
fn block_errors<T: Scalar>(
    grid: &Grid,
    part: &Part<T>,
    regular: &[bool],
    twins: &[u32],
    span: usize,
    block: &[u64],
) -> Option<[(f64, f64); 4]> {
    // The block's side as a constant, so that the loops over its 2 x span + 1 points unroll
    // (module notes: `block_errors` 86.9M -> 80.9M instructions in `adaptive-flat-4-6`).
    debug_assert!(span == 1 || span == 2, "sibling blocks of 1 or 2 x 2 nodes");
    match span {
        2 => block_errors_of::<T, 2>(grid, part, regular, twins, block),
        _ => block_errors_of::<T, 1>(grid, part, regular, twins, block),
    }
}

/// [`block_errors`] for blocks of `SPAN x SPAN` nodes.
fn block_errors_of<T: Scalar, const SPAN: usize>(
    grid: &Grid,
    part: &Part<T>,
    regular: &[bool],
    twins: &[u32],
    block: &[u64],
) -> Option<[(f64, f64); 4]> {
    let level = &part.level;
    let f = part.face_of_uid(block[0])?;
    if SPAN == 2
        && block
            .iter()
            .enumerate()
            .any(|(k, &u)| u != block[0] + k as u64)
    {
        return None;
    }
    // The frame corner (at the cell's (0, 0), its next along x) of the cell across side k
    // (0: -y, 1: +x, 2: +y, 3: -x) of the cell of frame corner `fc`, on a grid.
    let step = |fc: u32, k: u32| -> Option<u32> {
        let d = twins[((fc & !3) | ((fc + k) & 3)) as usize];
        (d != NONE).then_some((d & !3) | ((d + 6 - k) & 3))
    };
    // Cells -r..=r + SPAN - 1 in both directions, the first node's cell at (0, 0): along
    // its column, then along each row.
    let r = grid.reach;
    let top = r + SPAN as i32 - 1;
    const STRIDE: usize = GRID_SIDE + 1;
    let mut cells = [0u32; STRIDE * STRIDE];
    let at = |a: i32, b: i32| ((b + r) as usize) * STRIDE + (a + r) as usize;
    cells[at(0, 0)] = 4 * f as u32;
    for b in 1..=r.max(top) {
        if b <= top {
            cells[at(0, b)] = step(cells[at(0, b - 1)], 2)?;
        }
        if b <= r {
            cells[at(0, -b)] = step(cells[at(0, 1 - b)], 0)?;
        }
    }
    for b in -r..=top {
        for a in 1..=r.max(top) {
            if a <= top {
                cells[at(a, b)] = step(cells[at(a - 1, b)], 1)?;
            }
            if a <= r {
                cells[at(-a, b)] = step(cells[at(1 - a, b)], 3)?;
            }
        }
    }
    // The siblings lie counterclockwise from the first: cells (1, 0), (1, 1), (0, 1).
    const PLACE: [(i32, i32); 4] = [(0, 0), (1, 0), (1, 1), (0, 1)];
    if SPAN == 2 {
        for (k, &(a, b)) in PLACE.iter().enumerate().skip(1) {
            if part.face_uid.get((cells[at(a, b)] >> 2) as usize) != Some(&block[k]) {
                return None;
            }
        }
    }
    // Vertex at (x, y), -r <= x, y <= top + 1: a corner of the cell at or below it.
    let vertex = |x: i32, y: i32| -> usize {
        let (a, b) = (x.min(top), y.min(top));
        let k = match (x - a, y - b) {
            (0, 0) => 0,
            (1, 0) => 1,
            (1, 1) => 2,
            _ => 3,
        };
        let fc = cells[at(a, b)];
        level.corner_verts[((fc & !3) | ((fc + k) & 3)) as usize] as usize
    };
    // Vertices -inner..=inner + SPAN: the corners of cells -inner..inner + SPAN.
    let inner = grid.inner;
    for b in -inner..inner + SPAN as i32 {
        for a in -inner..inner + SPAN as i32 {
            if !regular[(cells[at(a, b)] >> 2) as usize] {
                return None;
            }
        }
    }
    // Rows, then columns: row(y)[p] = sum_x W_p(x) d(x, y), point(p, q) = sum_y W_q(y)
    // row(y)[p], over the data positions lo..lo + n (+ 1 for a block). Each sum runs over the
    // nonzero weights only, in increasing position; a row is added to the points as soon as
    // it is made, its data read once.
    let n = grid.weights[0].len() - 2 + SPAN;
    let points = 2 * SPAN + 1;
    let taps = grid.taps.each_ref().map(|t| (t.start, t.end.min(n)));
    let mut magnitude = 0.0f64;
    let mut data = [[0.0f64; 3]; GRID_SIDE + 2];
    let mut grid_points = [[[0.0f64; 3]; 5]; 5];
    for y in 0..n {
        let py = grid.lo + y as i32;
        for (x, d) in data[..n].iter_mut().enumerate() {
            let px = grid.lo + x as i32;
            let item = if grid.odd {
                vertex(px, py)
            } else {
                (cells[at(px, py)] >> 2) as usize
            };
            let [a, b, c] = part.data[item].map(|v| v.to_f64());
            // As `f64::max`, without its NaN handling (the data are finite).
            let m = a.abs();
            let m = if b.abs() > m { b.abs() } else { m };
            let m = if c.abs() > m { c.abs() } else { m };
            if m > magnitude {
                magnitude = m;
            }
            *d = [a, b, c];
        }
        // Plain index loops over the taps, each sum from 0 in increasing position (the order
        // of the iterator version they replace: the same bits).
        let mut row = [[0.0f64; 3]; 5];
        for p in 0..points {
            let (first, end) = taps[p];
            let w = &grid.weights[p][first..end];
            let d = &data[first..end];
            let mut sum = [0.0f64; 3];
            for i in 0..w.len().min(d.len()) {
                sum[0] += w[i] * d[i][0];
                sum[1] += w[i] * d[i][1];
                sum[2] += w[i] * d[i][2];
            }
            row[p] = sum;
        }
        for q in 0..points {
            let (first, end) = taps[q];
            if y < first || y >= end {
                continue;
            }
            let w = grid.weights[q][y];
            let column = &mut grid_points[q];
            for p in 0..points {
                column[p][0] += w * row[p][0];
                column[p][1] += w * row[p][1];
                column[p][2] += w * row[p][2];
            }
        }
    }
    let slack = grid.slack * magnitude;
    let mut out = [(0.0, 0.0); 4];
    for (o, &(a, b)) in out.iter_mut().zip(&PLACE).take(SPAN * SPAN) {
        let (a, b) = (2 * a as usize, 2 * b as usize);
        // Point (p, q) of the node is grid_points[b + q][a + p].
        let [r0, r1, r2] = [&grid_points[b], &grid_points[b + 1], &grid_points[b + 2]];
        let corner = [r0[a], r0[a + 2], r2[a + 2], r2[a]];
        let mid = [r0[a + 1], r1[a + 2], r2[a + 1], r1[a]];
        *o = (flatness(&corner, &mid, r1[a + 1]), slack);
    }
    Some(out)
}

/// The factor that makes an error relative to the cage diagonal.
fn scale_of<T>(ctx: &Context<T>) -> f64 {
    if ctx.diagonal > 0.0 {
        1.0 / ctx.diagonal
    } else {
        1.0
    }
}

/// Refines the nodes `nodes` of level `t` and, by the vertex restriction criterion, every leaf
/// parent of a face sharing a vertex with a refined node, down to the roots. Returns the lowest
/// level at which a node was refined (`t` if none).
///
/// The criterion only reaches down a level, so the sets are completed level by level from `t`:
/// the parents a level's new nodes ask for are found in parallel chunks (the sets of the level
/// below are only read meanwhile), sorted and added. The sets are the same as by any order of
/// insertion (the smallest ones closed under the criterion).
fn restrict_refine<T: Sync>(
    parts: &[Part<T>],
    refined: &mut [IdSet],
    t: usize,
    nodes: impl Iterator<Item = u64>,
) -> Result<usize> {
    let mut lowest = t;
    let nodes: Vec<u64> = nodes.collect();
    reserve_set(&mut refined[t], nodes.len())?;
    let mut new: Vec<u64> = nodes
        .into_iter()
        .filter(|&x| refined[t].insert(x))
        .collect();
    let mut s = t;
    while !new.is_empty() && s > 1 {
        let part = &parts[s];
        let below = &refined[s - 1];
        // The leaf parents asked for by the nodes of one chunk, in the nodes' order.
        let asked = |chunk: &[u64]| -> Result<Vec<u64>> {
            let mut out = Vec::new();
            for &x in chunk {
                let f = part.face_of_uid(x).ok_or_else(|| {
                    Error::Internal(format!("adaptive: node {x} of level {s} outside its level"))
                })?;
                // The faces around the node's corners have few parents, met in runs, and one
                // of them is the node's own (refined): each other one is looked up once per run.
                let mut last = x >> 2;
                for k in 4 * f..4 * f + 4 {
                    let v = part.level.corner_verts[k] as usize;
                    if !part.is_complete(v) {
                        return Err(Error::Internal(format!(
                            "adaptive: vertex {} of level {s} is cut off",
                            part.vert_uid[v]
                        )));
                    }
                    for &d in part.level.corners_of_vertex(v) {
                        let parent = part.face_uid[(d >> 2) as usize] >> 2;
                        if parent != last && parent != x >> 2 && !below.contains(&parent) {
                            out.push(parent);
                        }
                        last = parent;
                    }
                }
            }
            Ok(out)
        };
        let chunks: Vec<Result<Vec<u64>>> = new.par_chunks(RESTRICT_CHUNK).map(asked).collect();
        let mut parents = Vec::new();
        for chunk in chunks {
            parents.extend(chunk?);
        }
        parents.sort_unstable();
        parents.dedup();
        s -= 1;
        reserve_set(&mut refined[s], parents.len())?;
        refined[s].extend(parents.iter().copied());
        if !parents.is_empty() {
            lowest = s;
        }
        new = parents;
    }
    Ok(lowest)
}

/// Nodes per parallel task of [`restrict_refine`] (each looks at the 16 faces or so around its
/// node's corners).
const RESTRICT_CHUNK: usize = 1 << 9;

/// Triangle templates of a leaf quad for the 16 cases of refined edge neighbours (bit k: the
/// neighbour across edge k, from corner k to corner k + 1, is refined once more). Positions:
/// corner k is `2k`, the midpoint of edge k is `2k + 1`.
pub fn triangle_template(mask: u8) -> Vec<[u8; 3]> {
    let mask = mask & 15;
    if mask == 0 {
        return vec![[0, 2, 4], [0, 4, 6]];
    }
    let first = mask.trailing_zeros() as u8;
    let ring: Vec<u8> = (0..8u8)
        .map(|i| (2 * first + 1 + i) % 8)
        .filter(|&p| p % 2 == 0 || mask & (1 << (p / 2)) != 0)
        .collect();
    (1..ring.len() - 1)
        .map(|i| [ring[0], ring[i], ring[i + 1]])
        .collect()
}

/// The cage edge that edge `uid` of the uniform level `t` lies on, or `NONE`. Edge `e` of
/// `M_j` has the halves `2e`, `2e + 1` in `M_{j+1}` and the edges after them are inside
/// faces, and `M_j` has at least `2^j` times the cage's edges: the first `E_0 2^t` edges of
/// `M_t` are the halves down to the cage's `E_0` edges, edge `uid` on cage edge `uid >> t`.
fn cage_edge_of<T>(parts: &[Part<T>], t: usize, uid: u64) -> u32 {
    let cage = uid >> t;
    if cage < parts[0].counts[1] {
        cage as u32
    } else {
        NONE
    }
}

/// Where a triangle corner is: the level of its leaf, the leaf (a face of that partial level)
/// and its template slot (corner `k` is `2k`, the midpoint of edge `k` is `2k + 1`).
type CornerAt = (u32, u32, u8);

/// The output mesh and where its vertices and triangle corners are in the partial levels.
struct Drawn<T> {
    mesh: AdaptiveMesh<T>,
    /// Per output vertex: its level and its vertex there.
    vertex_at: Vec<(u32, u32)>,
    /// Per triangle corner: the level of its leaf, the leaf (a face of that partial level) and
    /// its template slot (corner `k` is `2k`, the midpoint of edge `k` is `2k + 1`).
    corner_at: Vec<CornerAt>,
}

/// Leaves per chunk of the parallel triangle output.
const LEAF_CHUNK: usize = 1 << 10;

/// A run of leaves (indices into the output order) and the runs of the triangle outputs that
/// their triangles fill.
/// The runs start uninitialised: each chunk writes all of them (checked before the outputs'
/// lengths are set), so they are not filled with zeros first.
struct LeafChunk<'a> {
    leaves: std::ops::Range<usize>,
    triangles: &'a mut [MaybeUninit<[u32; 3]>],
    face_origin: &'a mut [MaybeUninit<u32>],
    triangle_level: &'a mut [MaybeUninit<u32>],
    corner_at: &'a mut [MaybeUninit<CornerAt>],
    edge_origin: &'a mut [MaybeUninit<u32>],
    edge_level: &'a mut [MaybeUninit<u32>],
    edge_sharpness: &'a mut [MaybeUninit<f32>],
}

impl<'a> LeafChunk<'a> {
    /// The first `n` triangles of these runs, for the leaves `leaves`, and the rest.
    fn split(self, leaves: std::ops::Range<usize>, n: usize) -> (LeafChunk<'a>, LeafChunk<'a>) {
        let (triangles, t) = self.triangles.split_at_mut(n);
        let (face_origin, o) = self.face_origin.split_at_mut(n);
        let (triangle_level, l) = self.triangle_level.split_at_mut(n);
        let (corner_at, ca) = self.corner_at.split_at_mut(3 * n);
        let (edge_origin, eo) = self.edge_origin.split_at_mut(3 * n);
        let (edge_level, el) = self.edge_level.split_at_mut(3 * n);
        let (edge_sharpness, es) = self.edge_sharpness.split_at_mut(3 * n);
        let rest = LeafChunk {
            leaves: leaves.end..leaves.end,
            triangles: t,
            face_origin: o,
            triangle_level: l,
            corner_at: ca,
            edge_origin: eo,
            edge_level: el,
            edge_sharpness: es,
        };
        let chunk = LeafChunk {
            leaves,
            triangles,
            face_origin,
            triangle_level,
            corner_at,
            edge_origin,
            edge_level,
            edge_sharpness,
        };
        (chunk, rest)
    }
}

/// The output mesh: leaves (hole leaves are none) triangulated by the templates, shared
/// vertices drawn at the finest level around them; `refined` and `leaves` are the refined
/// nodes and the leaves of every level (sorted uniform ids).
fn triangulate<T: Scalar>(
    ctx: &Context<T>,
    parts: &[Part<T>],
    refined: &[Vec<u64>],
    leaves: &[Vec<u64>],
) -> Result<Drawn<T>> {
    let max_level = parts.len() - 1;
    // The leaves' faces in their partial levels: both lists are sorted, one merge walk each.
    let mut leaf_faces: Vec<Vec<usize>> = vec![Vec::new(); max_level + 1];
    for (t, faces) in leaf_faces.iter_mut().enumerate().skip(1) {
        let face_uid = &parts[t].face_uid;
        *faces = memory::with_capacity(leaves[t].len())?;
        let mut f = 0;
        for &u in &leaves[t] {
            while f < face_uid.len() && face_uid[f] < u {
                f += 1;
            }
            if face_uid.get(f) != Some(&u) {
                return Err(Error::Internal(format!(
                    "adaptive: leaf {u} of level {t} missing"
                )));
            }
            faces.push(f);
        }
    }
    // Per level, the output vertex of each vertex of its partial level (`NONE` if not drawn at
    // this level or finer): flat tables in place of a map by uniform id. Levels are numbered
    // from the finest down, each leaf's corners in order, so a vertex is numbered where it is
    // first met in that order, at the finest level of the leaves around it.
    let mut drawn_as: Vec<Vec<u32>> = vec![Vec::new(); max_level + 1];
    let mut points = Vec::new();
    let mut vertex_level = Vec::new();
    let mut vertex_id = Vec::new();
    let mut vertex_at = Vec::new();
    for t in (1..=max_level).rev() {
        let part = &parts[t];
        let mut here = memory::filled(part.vert_uid.len(), NONE)?;
        if t < max_level {
            // An old vertex keeps its uniform id: the vertices of level t + 1 below level t's
            // vertex count are level t's, drawn there (or finer) already.
            let (finer, finer_drawn) = (&parts[t + 1], &drawn_as[t + 1]);
            let mut v = 0;
            for (w, &uid) in finer.vert_uid.iter().enumerate() {
                if uid >= part.counts[0] {
                    break;
                }
                if finer_drawn[w] == NONE {
                    continue;
                }
                while v < part.vert_uid.len() && part.vert_uid[v] < uid {
                    v += 1;
                }
                if part.vert_uid.get(v) == Some(&uid) {
                    here[v] = finer_drawn[w];
                }
            }
        }
        for &f in &leaf_faces[t] {
            for &v in &part.level.corner_verts[4 * f..4 * f + 4] {
                let v = v as usize;
                if here[v] == NONE {
                    here[v] = vertex_id.len() as u32;
                    points.extend_from_slice(&part.points[v]);
                    vertex_at.push((t as u32, v as u32));
                    vertex_level.push(t as u32);
                    vertex_id.push(part.vert_uid[v]);
                }
            }
        }
        drawn_as[t] = here;
    }
    // Per level below the last, the faces of its partial level that are refined (`refined`:
    // sorted uniform ids per level, a merge walk).
    let mut is_refined: Vec<Vec<bool>> = vec![Vec::new(); max_level + 1];
    for t in 1..max_level {
        let face_uid = &parts[t].face_uid;
        let mut flags = memory::filled(face_uid.len(), false)?;
        let mut f = 0;
        for &u in &refined[t] {
            while f < face_uid.len() && face_uid[f] < u {
                f += 1;
            }
            if face_uid.get(f) == Some(&u) {
                flags[f] = true;
            }
        }
        is_refined[t] = flags;
    }
    let templates: Vec<Vec<[u8; 3]>> = (0..16).map(triangle_template).collect();
    // The side `k` of the leaf a template edge between slots `p` and `q` lies on (both among
    // its corners `2k`, `2k + 2` and midpoint `2k + 1`), 4 for an edge inside the leaf.
    let side_of: [[u8; 8]; 8] = std::array::from_fn(|p| {
        std::array::from_fn(|q| {
            let on = |x: usize, k: usize| (x + 8 - 2 * k) % 8 <= 2;
            (0..4).find(|&k| on(p, k) && on(q, k)).unwrap_or(4) as u8
        })
    });
    // The leaves in output order, then each one's template slots and case: the outputs are
    // then allocated once, and every leaf's triangles written apart (in parallel chunks, the
    // same output whatever the threads).
    let leaf_at: Vec<(u32, u32)> = memory::collect(
        (1..=max_level).flat_map(|t| leaf_faces[t].iter().map(move |&f| (t as u32, f as u32))),
    )?;
    let cases = gather_grain(leaf_at.len(), LEAF_CHUNK, |i| -> Result<([u32; 8], u8)> {
        let (t, f) = (leaf_at[i].0 as usize, leaf_at[i].1 as usize);
        let part = &parts[t];
        let level = &part.level;
        let manifold = level.edges().more.is_empty();
        let mut slots = [NONE; 8];
        let mut mask = 0u8;
        for k in 0..4 {
            let corner = 4 * f + k;
            slots[2 * k] = drawn_as[t][level.corner_verts[corner] as usize];
            if t == max_level {
                continue;
            }
            let e = level.corner_edges()[corner] as usize;
            // Any drawn face across the edge (one, or several on a non-manifold edge) that
            // is refined once more has the edge's midpoint; a hole has nothing drawn.
            let finer_across = |other: u32| {
                if other == NONE || other as usize == corner {
                    return false;
                }
                let g = (other >> 2) as usize;
                is_refined[t][g] && !ctx.is_hole(t, part.face_uid[g])
            };
            let finer = if manifold {
                // Two slots at most, without the slot iterator.
                level.edge_corners()[e].into_iter().any(finer_across)
            } else {
                level.edge_slots(e).any(finer_across)
            };
            if finer {
                let uid = part.counts[0] + part.edge_uid[e];
                let finer = &parts[t + 1];
                let at = finer.vert_uid.binary_search(&uid).ok();
                slots[2 * k + 1] = at.map_or(NONE, |w| drawn_as[t + 1][w]);
                if slots[2 * k + 1] == NONE {
                    return Err(Error::Internal(format!(
                        "adaptive: edge point {uid} of level {} missing",
                        t + 1
                    )));
                }
                mask |= 1 << k;
            }
        }
        Ok((slots, mask))
    })?;
    let mut ok: Vec<([u32; 8], u8)> = memory::with_capacity(cases.len())?;
    for case in cases {
        ok.push(case?);
    }
    let cases = ok;
    let first_triangle =
        prefix_offsets(cases.len(), |i| templates[cases[i].1 as usize].len() as u32)?;
    let num_triangles = first_triangle[cases.len()] as usize;
    let (n, n3) = (num_triangles, 3 * num_triangles);
    let mut triangles = with_capacity_hinted::<[u32; 3]>(n)?;
    let mut face_origin = with_capacity_hinted::<u32>(n)?;
    let mut triangle_level = with_capacity_hinted::<u32>(n)?;
    let mut corner_at = with_capacity_hinted::<CornerAt>(n3)?;
    let mut edge_origin = with_capacity_hinted::<u32>(n3)?;
    let mut edge_level = with_capacity_hinted::<u32>(n3)?;
    let mut edge_sharpness = with_capacity_hinted::<f32>(n3)?;
    // Chunks of leaves and the runs of the outputs they write.
    let mut chunks: Vec<LeafChunk> = Vec::new();
    {
        let mut rest = LeafChunk {
            leaves: 0..0,
            triangles: &mut triangles.spare_capacity_mut()[..n],
            face_origin: &mut face_origin.spare_capacity_mut()[..n],
            triangle_level: &mut triangle_level.spare_capacity_mut()[..n],
            corner_at: &mut corner_at.spare_capacity_mut()[..n3],
            edge_origin: &mut edge_origin.spare_capacity_mut()[..n3],
            edge_level: &mut edge_level.spare_capacity_mut()[..n3],
            edge_sharpness: &mut edge_sharpness.spare_capacity_mut()[..n3],
        };
        for first in (0..cases.len()).step_by(LEAF_CHUNK) {
            let end = (first + LEAF_CHUNK).min(cases.len());
            let n = (first_triangle[end] - first_triangle[first]) as usize;
            let (chunk, more) = rest.split(first..end, n);
            chunks.push(chunk);
            rest = more;
        }
    }
    chunks.par_iter_mut().for_each(|chunk| {
        let (mut x, mut y) = (0, 0);
        for i in chunk.leaves.clone() {
            let (t, f) = (leaf_at[i].0 as usize, leaf_at[i].1 as usize);
            let (slots, mask) = cases[i];
            let part = &parts[t];
            let level = &part.level;
            let origin = ctx.level0.corner_faces[(part.face_uid[f] >> (2 * (t - 1))) as usize];
            // The cage edge under each side of the leaf.
            let sides: [u32; 4] = std::array::from_fn(|k| {
                cage_edge_of(
                    parts,
                    t,
                    part.edge_uid[level.corner_edges()[4 * f + k] as usize],
                )
            });
            for tri in &templates[mask as usize] {
                chunk.triangles[x].write(tri.map(|p| slots[p as usize]));
                chunk.face_origin[x].write(origin);
                chunk.triangle_level[x].write(t as u32);
                x += 1;
                for i in 0..3 {
                    let (p, q) = (tri[i], tri[(i + 1) % 3]);
                    let side = side_of[p as usize][q as usize];
                    let origin = sides.get(side as usize).copied().unwrap_or(NONE);
                    let depth = t as u32 + (p % 2 == 1 || q % 2 == 1) as u32;
                    let cage = if origin == NONE {
                        0.0
                    } else {
                        ctx.features.edge_sharpness[origin as usize]
                    };
                    chunk.corner_at[y].write((t as u32, f as u32, p));
                    chunk.edge_origin[y].write(origin);
                    chunk.edge_level[y].write(depth);
                    // Decrementing keeps 0 (and makes anything not positive 0): skip it there.
                    chunk.edge_sharpness[y].write(if cage <= 0.0 {
                        0.0
                    } else {
                        (0..depth).fold(cage, |s, _| decrement(s))
                    });
                    y += 1;
                }
            }
        }
        // Items 0..x and 0..y of the runs were written, one after the other: all of them (the
        // runs' lengths are the leaves' template sizes, as `first_triangle` counted them).
        assert!(
            x == chunk.triangles.len() && y == chunk.corner_at.len(),
            "adaptive: a chunk of leaves wrote {x} of {} triangles",
            chunk.triangles.len()
        );
    });
    // SAFETY: the chunks' runs tile the first `n` (`n3`) items of each output, in order
    // (`LeafChunk::split` of the spare capacities, `n` triangles in all as `first_triangle`
    // counts them), and every chunk wrote every item of its runs (the assertion above, which
    // would have unwound past here); `n` and `n3` are within the capacities allocated.
    unsafe {
        triangles.set_len(n);
        face_origin.set_len(n);
        triangle_level.set_len(n);
        corner_at.set_len(n3);
        edge_origin.set_len(n3);
        edge_level.set_len(n3);
        edge_sharpness.set_len(n3);
    }
    let mut leaves_per_level = vec![0u64; max_level + 1];
    for (t, l) in leaves.iter().enumerate() {
        if t <= max_level {
            leaves_per_level[t] = l.len() as u64;
        }
    }
    let mesh = AdaptiveMesh {
        points,
        triangles,
        face_origin,
        triangle_level,
        vertex_level,
        vertex_id,
        cage_vertex: Vec::new(),
        vertex_sharpness: Vec::new(),
        leaves_per_level,
        max_error: None,
        edge_origin,
        edge_level,
        edge_sharpness,
        cage_edges: Vec::new(),
        vertex_values: Vec::new(),
        face_varying: Vec::new(),
    };
    Ok(Drawn {
        mesh,
        vertex_at,
        corner_at,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic generator in [0, 1).
    struct Random(u64);

    impl Random {
        fn next(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// An n x n grid of quads with pseudo-random heights, a crease along one line of interior
    /// edges (semi-sharp) and a tagged corner inside.
    fn rough_grid(n: usize) -> (Cage, Vec<f64>) {
        let id = |a: usize, b: usize| (a * (n + 1) + b) as i64;
        let (mut sizes, mut verts) = (Vec::new(), Vec::new());
        for a in 0..n {
            for b in 0..n {
                sizes.push(4);
                verts.extend([id(a, b), id(a + 1, b), id(a + 1, b + 1), id(a, b + 1)]);
            }
        }
        let mut rng = Random(11);
        let mut points = Vec::new();
        for a in 0..=n {
            for b in 0..=n {
                points.extend([a as f64, b as f64, 0.3 * rng.next()]);
            }
        }
        let creases: Vec<(i64, i64, f32)> =
            (1..n - 1).map(|b| (id(2, b), id(2, b + 1), 1.5)).collect();
        let cage = Cage::from_indices((n + 1) * (n + 1), &sizes, &verts)
            .unwrap()
            .with_creases(&creases)
            .unwrap()
            .with_corners(&[(id(n - 3, n - 3), 2.0)])
            .unwrap();
        (cage, points)
    }

    /// A cube with one corner pulled out (valence-3 vertices).
    fn cube() -> (Cage, Vec<f64>) {
        let mut points: Vec<f64> = (0..8)
            .flat_map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64])
            .collect();
        points[21] += 0.8;
        let faces: [[i64; 4]; 6] = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let cage = Cage::from_indices(8, &[4; 6], faces.as_flattened()).unwrap();
        (cage, points)
    }

    /// The closed form agrees with the error measured on the children within its rounding
    /// bound for every node it evaluates (all faces of levels 1-3, so the full uniform levels,
    /// every degree it covers), and it evaluates most nodes of a grid: a wrong mask, frame or
    /// grid test shows here as an error far off the measured one.
    #[test]
    fn closed_form_errors_match_the_children() {
        for (name, (cage, points)) in [("grid", rough_grid(8)), ("cube", cube())] {
            for degree in 1..=9 {
                let options = AdaptiveOptions {
                    degree,
                    ..AdaptiveOptions::default()
                };
                let (_, ctx) = context(&cage, &points, &options, margin_rings(degree)).unwrap();
                let Some(grid) = Grid::new(&ctx) else {
                    panic!("degree {degree}: no closed form");
                };
                let roots = ctx.level0.num_corners() as u64;
                let seeds: Vec<Vec<u64>> = (0..=4)
                    .map(|t| match t {
                        0 => Vec::new(),
                        _ => (0..roots << (2 * (t - 1))).collect(),
                    })
                    .collect();
                let parts = run_pass(&ctx, &seeds, 0).unwrap();
                let (mut evaluated, mut total) = (0, 0);
                for t in 1..=3 {
                    let part = &parts[t];
                    let nodes = &seeds[t];
                    let exact = measure(&ctx, &parts, t, nodes).unwrap();
                    let span = if t >= 2 { 2 } else { 1 };
                    let regular = regular_faces(&ctx, part).unwrap();
                    let twins = grid_twins(part).unwrap();
                    for (i, block) in nodes.chunks(span * span).enumerate() {
                        total += block.len();
                        let Some(errors) = block_errors(&grid, part, &regular, &twins, span, block)
                        else {
                            continue;
                        };
                        for (k, &(error, slack)) in errors[..block.len()].iter().enumerate() {
                            evaluated += 1;
                            let measured = exact[span * span * i + k] * ctx.diagonal;
                            assert!(
                                (error - measured).abs() <= slack && slack < 1e-9,
                                "{name}, degree {degree}, level {t}, node {}: closed form {error}, children {measured}, bound {slack}",
                                block[k]
                            );
                        }
                    }
                }
                if name == "grid" {
                    assert!(
                        evaluated * 2 > total,
                        "degree {degree}: {evaluated} of {total} nodes evaluated"
                    );
                }
            }
        }
    }
}
