//! Limit positions and limit normals at the output vertices, for every degree: the paper's §4
//! eigen-structure put to work.
//!
//! The limit of the surface at a vertex `v` of the last level is a fixed linear combination of
//! the scheme's data (per vertex for odd degrees, per face for even ones) on `v`'s minimal
//! invariant neighbourhood (`N` rings, `N` as in [`crate::analysis::neighbourhood_size`]),
//! *provided* that the subdivision matrix of that neighbourhood is the polar one of
//! [`crate::analysis::subdivision_matrix`] for `v`'s valence: every other vertex within `N`
//! rings is interior, of valence 4 and on no crease. (Working back through the `n` averages of
//! a step, the valences that enter the new values on the neighbourhood are those of the old
//! vertices within `N - 1/2` rings, and the 1-D rules those of curve vertices within `N`; the
//! walk that labels the neighbourhood is sound under the same condition.) Then
//! - the limit position is the dominant left eigenvector (eigenvalue 1, summing to 1), and
//! - two tangents are the real and imaginary parts of the subdominant left eigenvector of the
//!   Fourier mode 1 (eigenvalue `lambda1`); their cross product is the limit normal.
//!
//! At valence 4 these are exactly the tensor-product B-spline masks (tested). Vertices that are
//! not in such a clean neighbourhood (near another irregular vertex, a crease or a boundary) are
//! handled by refining further, `m` levels, which doubles their distances `m` times while the old
//! vertices keep their ids, until every one of them is clean. With the averaging rules, when
//! the partial levels around those vertices have at most 1 / [`LOCAL_SHARE`] of the faces of
//! the whole plan extended, this is local: only partial levels around them are made (the
//! adaptive module's [`LocalLevels`], exact where their stencils reach), and every other vertex
//! keeps the masks of the plan's own last level; the curve vertices, corners and valence-2
//! vertices then take the extension too (their normals come from fans at the extended level).
//! Otherwise the whole plan is extended.
//!
//! Semi-sharp creases and corners (sharpness `s`) must have left the last step's network: the
//! vertices they make are never clean (their rules change later), so the extension reaches
//! level `ceil(s) + 1`. That is local too when its partial levels make at most 1 /
//! [`LOCAL_SHARE`] of the faces of the whole plan extended (which has 4^m times the plan's per
//! level), in two stages: the vertices that are clean `clean` levels down (the smallest
//! extension for the degree) get their stencils there, and only those the features still reach
//! go on, on partial levels past those around them alone: along a crease these grow about 2x
//! per level, not 4x. The curve vertices, corners and valence-2 vertices that are clean at the
//! first stage keep their fans there, as on a mesh without semi-sharp features: a fan's level
//! does not depend on features elsewhere on the mesh, and a grid with a boundary and one
//! semi-sharp crease takes the second stage around the crease alone (it went around the
//! boundary too: a cached limit of the callgrind driver's `limit-semisharp-4` cost 80.6M
//! instructions, now 32.1M, against 10.4M with the crease infinitely sharp). Classic
//! Catmull-Clark limits are not extended at all (below).
//!
//! Curve vertices (boundaries, infinitely sharp creases) lie on the curve's uniform B-spline of
//! degree n (DESIGN.md §2): their limit position is the 1-D B-spline mask along the curve, exact;
//! corners keep their cage point. Normals there are one-sided: one per side of the curve (a
//! crease vertex has two), from the fan of refined control points on that side at the extended
//! level (first-order accurate in the level's spacing, not exact: the exact one would need the
//! eigenvectors of the boundary subdivision matrices). An interior vertex of valence 2 (on two
//! faces) has its exact limit position from the dominant eigenvector of its valence, but no
//! tangent masks: there the eigenvalue after 1 is 1/4 three times over, so the limit surface
//! has in general a conical point and no tangent plane ([`crate::analysis::vertex_masks`]);
//! its normal is the fan normal of its two faces, as at a curve vertex (a closed fan: one
//! normal for both corners). Degree 1 is bilinear: positions are the
//! refined points, normals those of each face's bilinear patch at its corner.
//!
//! Around an isolated irregular vertex (no other irregular vertex, curve or semi-sharp feature
//! within the rings its neighbours' limits read) no level is made at all: the limit of each of
//! its neighbours within `N` rings is a fixed function of the last level's data, the same around
//! every such vertex of that valence, composed once per process ([`polar`]) and read off the
//! table by the sector frames around the vertex. Only the vertices that are not clean for
//! another reason take the local extension (`limit-ico-9` of the callgrind driver at level 2,
//! one thread: cached 105.7M -> 54.3M instructions, the first call 866.8M -> 209.8M; level 3
//! 206.0M -> 154.1M and 1,162.0M -> 498.3M; the tables, made once per process, 691M for
//! degree 9 at valences 3 and 5).
//!
//! On a smooth mesh, from `N` = 3 (degree 6) the local extension is made one level at a time
//! ([`stepwise_local_stencils`]): a vertex `d` rings from an irregular vertex or a curve is clean
//! once `2^k d > N`, so most of them are clean one or two levels down, and each further level is
//! made around the rest alone (`limit-ico-9` of the callgrind driver, cached: 521.4M -> 449.3M
//! instructions; its first call 2.33G -> 1.90G).
//!
//! Most vertices of a mesh are regular, and at the plan's own last level those whose whole
//! neighbourhood is a grid are computed by limit tiles ([`tiles`]): the same valence-4 masks as
//! separable 1-D filters over blocks of vertices (rows filtered once for a block's columns), and
//! no stencil is walked or stored for them (a cached limit of the callgrind driver's
//! `limit-ico-4` cost 198.5M instructions with stencils alone, 167.1M with tiles; `limit-ico-9`
//! 840.9M, 552.3M; the first call of `limit-first-ico-4` 952.7M, 778.0M). Where the processor
//! has AVX2 the tiles run in four-lane vectors, bitwise the same values (`limit-ico-4` 154.8M ->
//! 131.7M, `limit-ico-9` 449.3M -> 398.2M). Their normals are made a whole output row at a
//! time, lane by lane (`limit-ico-2` 105.1M -> 93.9M, `-3` 115.0M -> 103.3M, `-4` 135.6M ->
//! 125.0M), and each vertex's values are written in place in the output arrays (no array per
//! tile slot, no gather after them: 1-2 % fewer instructions, one array of the level's size less).
//! The window's gather and the row filters are written in AVX2 intrinsics (the same values:
//! `limit-ico-9` at level 3 154.1M -> 131.6M, `-2` 58.1M -> 52.6M; see [`tiles`]).
//!
//! The stencils and fans are built on first use and kept in the plan ([`LimitCache`]), so
//! re-evaluating a deformed cage costs one evaluation of the plan (or of the whole extended
//! refinement), the steps of the local partial levels, and one small gather per vertex.
//!
//! Classic Catmull-Clark limit positions use OpenSubdiv's limit masks (`catmark_limit`) at the
//! plan's last level, with no extension: where a semi-sharp feature is still sharp there, its
//! current rule is used, as OpenSubdiv's `PrimvarRefiner::Limit` (and so Blender) does. Taking
//! them past semi-sharp features on partial levels would need the classic sharpness and vertex
//! rules ([`LevelSharpness`], Chaikin creasing) on partial levels, which only run the averaging
//! rules, and would part from OpenSubdiv.
//!
//! Everything here is at the vertices and corners of the whole last level: holes change no rule
//! (their points shape their neighbours), so the plan selects the drawing mesh's vertices and
//! corners from these values ([`crate::output::OutputMesh::vertex_values`]).

use std::borrow::Cow;
use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

use glam::DVec3;

use crate::adaptive::LocalLevels;
use crate::analysis::{
    cached_vertex_masks, frame_items, neighbourhood_size, sector_frames, Labelled, VertexMasks,
};
use crate::curves::CurveNetwork;
use crate::curves::LevelSharpness;
use crate::error::{Error, Result};
use crate::evaluate::{in_groups_of_four, run, run_parts};
use crate::memory;
use crate::options::{NormalDomain, Options, OutputKind};
use crate::parallel::{gather_hinted, gather_indexed, with_capacity_hinted, Disjoint, CHUNK};
use crate::refinement::Refinement;
use crate::scalar::{add, mad, scale, zero, Scalar, Value};
use crate::scheme::catmark::{
    dart_limit_mask, smooth_limit_weights, VertexRule, CREASE_LIMIT_WEIGHTS,
};
use crate::scheme::Scheme;
use crate::scheme::{cardinal_bspline, is_infinitely_sharp, is_semi_sharp, is_sharp, LimitMethod};
use crate::step::{Final, Parts, Scratch};
use crate::topology::{quad_next, quad_prev, Level, NONE};
use rayon::prelude::*;

mod polar;
mod tiles;
use tiles::Tiles;

/// Extra levels tried at most beyond the first guess before giving up.
const MAX_EXTRA_LEVELS: u32 = 8;

/// The local extension is made when its partial levels have at most this share (1 /
/// LOCAL_SHARE) of the faces of the whole plan extended, and its seeds at most this share of the
/// plan's last level (else the partial levels are not even built). A partial face costs more
/// than a face of the whole extension (measured with every face a seed, the valence-400 fan at
/// degree 9: 1.3x per cached call, 2.7x in the first), so at half the faces the cached call
/// costs about two thirds and the first call at most about a third more.
const LOCAL_SHARE: usize = 2;

/// The neighbourhood size `N` from which the local extension is made one level at a time
/// ([`stepwise_local_stencils`]): with `N` of 2 (degrees 4 and 5) the vertices clean one level
/// down are only the ring 2 away, and the two stages cost 1 % more than one in a cached limit of
/// the callgrind driver's `limit-ico-4` (4 % more in the first call); from 3 on they cost less
/// (degree 6 3.5 %, 9 14 %; the first call 4 %, 18 %).
const STEPWISE_RINGS: usize = 3;

/// Which mask gives the limit at one output vertex.
#[derive(Debug, Clone, Copy, PartialEq)]
enum LimitMask {
    /// An interior vertex: masks of its valence (index into `Stencils::masks`).
    Interior(u32),
    /// An interior vertex of valence 2: the position mask of its valence (index into
    /// `Stencils::masks`); its normal comes from its fan, as at a curve vertex (there is no
    /// tangent plane to take it from, see [`crate::analysis::vertex_masks`]).
    Valence2(u32),
    /// A curve vertex: the 1-D B-spline mask along the curve.
    Curve,
    /// A corner: its cage point.
    Corner,
    /// Not clean at this level: the stencil of the local extension.
    Local,
    /// An interior vertex of valence 4 that a limit tile computes (and writes in place).
    Tiled,
    /// Near an isolated irregular vertex: a composed stencil ([`polar`]; index into
    /// `Stencils::composed`).
    Composed(u32),
}

/// Everything topological the limit needs, built once per plan (see the module documentation).
#[derive(Debug)]
pub(crate) struct Stencils {
    /// The refinement extended by `extra_levels` levels and its evaluation buffers (`None` when
    /// the plan's own refinement is enough).
    extended: Option<(Refinement, Scratch)>,
    /// Levels added to the plan (the whole plan when `extended`, else around the vertices of
    /// `local`).
    extra_levels: u32,
    /// The stencils of the vertices that are not clean at the plan's last level, on partial
    /// levels past it around those vertices (their topology made once, here); past semi-sharp
    /// features, these have their own `local` for the vertices that are not clean there.
    local: Option<(Box<Stencils>, LocalLevels)>,
    /// The stencils (indices into `masks_of`) that `local` gives, in order.
    local_vertices: Vec<u32>,
    /// Mask of each output vertex.
    masks_of: Vec<LimitMask>,
    /// The stencils composed around isolated irregular vertices ([`LimitMask::Composed`]).
    composed: polar::Composed,
    /// The tiles that compute most regular vertices at the plan's own last level (their
    /// [`LimitMask::Tiled`] stencils have no items).
    tiles: Option<Tiles>,
    /// The stencils that no tile computes (increasing): what [`stencil_values`] walks after
    /// the tiles (a list, not a test per vertex: most vertices are tiled).
    untiled: Vec<u32>,
    /// Offsets into `items` per output vertex.
    offsets: Vec<u32>,
    /// Indices into the data the stencils read (see `Limit::limit_data`).
    items: Vec<u32>,
    /// Interior masks by valence.
    masks: Vec<Arc<VertexMasks>>,
    /// The same masks with tangents, per item its position and two tangent weights and a zero
    /// (empty where there are no tangents): one walk over a stencil's data gives all three,
    /// in two-lane vector operations.
    joint: Vec<Vec<[f64; 4]>>,
    /// The masks of valence 4 folded over the sectors (`None` at other valences).
    folded: Vec<Option<Folded>>,
    /// The 1-D position mask along curves (symmetric, centred).
    curve_mask: Vec<f64>,
    /// Fan of each output face corner at a curve vertex or corner (index into `fan_offsets`),
    /// `NONE` elsewhere.
    corner_fan: Vec<u32>,
    /// Offsets into `fan_items` per fan, and whether the fan closes on itself.
    fan_offsets: Vec<u32>,
    fan_closed: Vec<bool>,
    /// The stencil (the vertex) each fan turns around.
    fan_vertex: Vec<u32>,
    /// Data indices of each fan's points, counter-clockwise around its vertex.
    fan_items: Vec<u32>,
    /// [`normals_split`]'s answer, made on its first call (the stencils' alone: an update of
    /// the add-on asks it every frame).
    normals_split: OnceLock<bool>,
}

impl Stencils {
    /// The stages of the local extension, each past the one before, with their levels.
    fn locals(&self) -> impl Iterator<Item = &(Box<Stencils>, LocalLevels)> {
        std::iter::successors(self.local.as_ref(), |(local, _)| local.local.as_ref())
    }
}

/// Which vertices and corners of a level [`build_stencils`] makes stencils for: stencil `i` is
/// at level vertex `vertex(i)` and output vertex `output_vertex(i)`; output corner `c` (of
/// `output`, the plan's last level) is level corner `corner(c)` (`None`: not one of the
/// target's); `index(w)` is the stencil of level vertex `w`, if any. (The plan's stencil `i`
/// is output vertex `i`; a local one is its parent's `local_vertices[i]`.)
struct Targets<'a> {
    count: usize,
    output: &'a Level,
    output_vertex: &'a (dyn Fn(usize) -> usize + Sync),
    vertex: &'a (dyn Fn(usize) -> usize + Sync),
    corner: &'a (dyn Fn(usize) -> Option<usize> + Sync),
    index: &'a (dyn Fn(usize) -> Option<usize> + Sync),
}

/// What [`build_stencils`] does with a target vertex that is not clean.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Unclean {
    /// The stencils are refused (`None`).
    Refuse,
    /// It gets a [`LimitMask::Local`] stencil, to be built on a local extension, and so do the
    /// curve vertices, corners and valence-2 vertices: their normals come from fans at the
    /// level where every vertex is clean, as with the whole plan extended (the plan's level,
    /// and the local extension's levels before its last).
    LocalWithFans,
    /// As `LocalWithFans`, but the vertices near isolated irregular vertices get composed
    /// stencils instead ([`polar`]; targets that are the level's vertices, as at a plan's
    /// last level), and only the others the local extension.
    Polar,
    /// It gets a [`LimitMask::Local`] stencil, alone: the fans stay at this level (the first
    /// stage past semi-sharp features, so that a fan's level does not depend on features
    /// elsewhere on the mesh, and the second stage is made around the features only).
    Local,
}

/// Builds the stencils on `last` (a plan's last level, an extended one's, or a partial level
/// past it) with `curves` (the network of the step that made it) for `targets`; `semi_corners`
/// are the cage vertices tagged semi-sharp (sorted). A target vertex that is not clean makes
/// the result `None`, or a [`LimitMask::Local`] stencil (listed in `local`) as `unclean` says.
/// With `tile_depth` (every vertex of `last` a target, its faces blocks of the descendants of
/// the faces of the level given, that many levels above), the regular vertices go to limit
/// tiles of that depth.
fn build_stencils(
    last: &Level,
    curves: &CurveNetwork,
    degree: u32,
    targets: &Targets,
    semi_corners: &[u32],
    unclean: Unclean,
    tile_depth: Option<(u32, &Level)>,
) -> Result<Option<Stencils>> {
    let primal = degree % 2 == 1;
    let n = neighbourhood_size(degree);
    let nf = last.num_faces();
    let nc = curves.edges().len();
    // Data layout (see `limit_data`): odd degrees, the vertices; even degrees, the faces,
    // then the last step's curve edges, then the cage points (for corners).
    let cage_item = |v: usize| if primal { v } else { nf + nc + v };
    // Curve vertex of each vertex id (index into the step's curve vertices).
    let curve_of = |v: usize| curves.vertex_index(v as u32).map(|i| i as usize);
    let transient = transient_curve_vertices(curves, semi_corners)?;
    let curve_index = |e: u32| curves.edge_index(e);
    let is_curve_edge = |e: u32| curve_index(e).is_some();

    let curve_mask = knot_mask(degree, cardinal_bspline);

    let mut valences: Vec<usize> = Vec::new();
    // Per vertex: rule and items, or None when not clean.
    let stencil_of = |v: usize| -> Option<(LimitMask, Vec<u32>)> {
        if let Some(i) = curve_of(v) {
            let cv = &curves.vertices()[i];
            if transient[i] {
                return None;
            }
            let Some([a, b]) = cv.edges else {
                // Odd degrees: the corner's own vertex, which holds its cage point at every
                // level (on a partial level its index is not the cage vertex's).
                let item = if primal {
                    v
                } else {
                    cage_item(cv.pin as usize)
                };
                return Some((LimitMask::Corner, vec![item as u32]));
            };
            // Walk the polyline both ways: curve vertices (odd) or edges (even).
            let walk = |first_edge: u32, from: usize, count: usize| -> Option<Vec<u32>> {
                let mut out = Vec::with_capacity(count);
                let (mut edge, mut at) = (first_edge as usize, from);
                for _ in 0..count {
                    let ends = curves.edges()[edge].ends;
                    let next = if ends[0] as usize == at {
                        ends[1]
                    } else {
                        ends[0]
                    } as usize;
                    if primal {
                        out.push(curves.vertices()[next].vertex);
                    } else {
                        out.push((nf + edge) as u32);
                    }
                    let [x, y] = curves.vertices()[next].edges?;
                    if transient[next] {
                        return None;
                    }
                    edge = if x as usize == edge { y } else { x } as usize;
                    at = next;
                }
                Some(out)
            };
            // Odd: N vertices each way (the N-th may be a corner: its value is still its 1-D
            // value); even: N edges each way. One more step each way must exist (no corner
            // within the mask's reach, else the 1-D scheme is not uniform there).
            let back = walk(a, i, n + 1)?;
            let ahead = walk(b, i, n + 1)?;
            let mut items: Vec<u32> = Vec::with_capacity(2 * n + 1);
            if primal {
                items.extend(back[..n].iter().rev());
                items.push(v as u32);
                items.extend(&ahead[..n]);
            } else {
                // back[0] is edge a itself.
                items.extend(back[..n].iter().rev());
                items.extend(&ahead[..n]);
            }
            let mut sorted = items.clone();
            sorted.sort_unstable();
            sorted.dedup();
            return (sorted.len() == items.len()).then_some((LimitMask::Curve, items));
        }
        // Interior: the vertices up to N rings away must be clean.
        let first = last.corners_of_vertex(v)[0] as usize;
        let frames = sector_frames(last, first, n)?;
        let ring = frame_items(last, &frames, n, n, false);
        if !polar_grid(last, &ring, &|w| curve_of(w).is_some()) {
            return None;
        }
        let items = if primal {
            ring
        } else {
            frame_items(last, &frames, n, n, true)
        };
        let valence = frames.len() / ((n + 1) * (n + 1));
        let mask = match valence {
            2 => LimitMask::Valence2(valence as u32),
            _ => LimitMask::Interior(valence as u32),
        };
        Some((mask, items.iter().map(|&(_, i)| i as u32).collect()))
    };
    // On a quad level (every level past the cage) the interior stencils are walked on a table
    // of twin corners and one of regular vertices (valence 4, on no curve), each chunk of
    // vertices writing into its own buffers: no allocation, sort or search per vertex.
    let quads = last.is_quads();
    let walk = match quads {
        true => Some(QuadWalk {
            level: last,
            twins: last.twin_corners()?,
            marks: regular_marks(last, curves)?,
            n,
            primal,
        }),
        false => None,
    };
    // Stamps per task, shared by the tiles' walks and the stencils' (see [`Pooled`]).
    let pool = Mutex::new(Vec::new());
    let tiles = match (&walk, tile_depth) {
        (Some(walk), Some((depth, above))) => {
            Tiles::build(last, above, &walk.twins, &walk.marks, degree, depth, &pool)?
        }
        _ => None,
    };
    let tiled = match &tiles {
        Some(tiles) => tiles.computed(last.num_vertices)?,
        None => Vec::new(),
    };
    let chunk_stencils = |stamps: &mut Stamps, range: std::ops::Range<usize>| -> Result<_> {
        let mut chunk = ChunkStencils::default();
        for t in range {
            let v = (targets.vertex)(t);
            let at = chunk.items.len();
            // The tiles write their values at their level vertex: a tiled stencil is its own
            // vertex (as every stencil of a plan's last level is).
            if v == t && tiled.get(v).copied().unwrap_or(false) {
                chunk.masks.push(Some(LimitMask::Tiled));
                chunk.ends.push(at as u32);
                continue;
            }
            let general = |items: &mut Vec<u32>| {
                items.truncate(at);
                stencil_of(v).map(|(mask, its)| {
                    items.extend(its);
                    mask
                })
            };
            let mask = match &walk {
                Some(walk) if curve_of(v).is_none() => {
                    match walk.interior(v, stamps, &mut chunk.items) {
                        Walked::Clean(mask) => Some(mask),
                        Walked::NotClean => None,
                        Walked::Other => general(&mut chunk.items),
                    }
                }
                _ => general(&mut chunk.items),
            };
            if mask.is_none() {
                chunk.items.truncate(at);
            }
            chunk.masks.push(mask);
            chunk.ends.push(chunk.items.len() as u32);
        }
        Ok(chunk)
    };
    // The tables are allocated fallibly; the per-vertex stencils are gathered a block of
    // vertices at a time (in fixed chunks), so that what is held besides the tables stays small.
    const BLOCK: usize = 1 << 16;
    let outputs = targets.count;
    let mut masks_of = memory::with_capacity(outputs)?;
    let mut offsets = memory::with_capacity(outputs + 1)?;
    let mut items: Vec<u32> = Vec::new();
    let mut local = Vec::new();
    offsets.push(0u32);
    let marks = walk.as_ref().map_or(&[][..], |w| &w.marks[..]);
    for start in (0..outputs).step_by(BLOCK) {
        let end = (start + BLOCK).min(outputs);
        let chunks: Vec<ChunkStencils> = (start..end)
            .step_by(CHUNK)
            .collect::<Vec<_>>()
            .into_par_iter()
            // Each task takes stamps (a table per level vertex) from the pool for all its
            // chunks and puts them back: as many tables as tasks run at once, not one per task.
            .map_init(
                || Pooled::take(&pool, marks),
                |stamps, from| {
                    let stamps = stamps.stamps.as_mut().map_err(|e| e.clone())?;
                    chunk_stencils(stamps, from..(from + CHUNK).min(end))
                },
            )
            .collect::<Result<_>>()?;
        if unclean == Unclean::Refuse && chunks.iter().any(|c| c.masks.contains(&None)) {
            return Ok(None);
        }
        let size: usize = chunks.iter().map(|c| c.items.len()).sum();
        memory::grow(&mut items, size)?;
        let mut t = start;
        for chunk in chunks {
            let base = items.len() as u32;
            for (&mask, &end) in chunk.masks.iter().zip(&chunk.ends) {
                let Some(mask) = mask else {
                    local.push(t as u32);
                    masks_of.push(LimitMask::Local);
                    offsets.push(base + end);
                    t += 1;
                    continue;
                };
                let mut index_of = |k: u32| {
                    let at = match valences.iter().position(|&x| x == k as usize) {
                        Some(at) => at,
                        None => {
                            valences.push(k as usize);
                            valences.len() - 1
                        }
                    };
                    at as u32
                };
                let mask = match mask {
                    LimitMask::Interior(k) => LimitMask::Interior(index_of(k)),
                    LimitMask::Valence2(k) => LimitMask::Valence2(index_of(k)),
                    m => m,
                };
                masks_of.push(mask);
                offsets.push(base + end);
                t += 1;
            }
            items.extend_from_slice(&chunk.items);
        }
    }
    let mut composed = polar::Composed::default();
    if !local.is_empty() && unclean == Unclean::Polar {
        let on_curve = |v: usize| curve_of(v).is_some();
        let is_local = |v: usize| masks_of[v] == LimitMask::Local;
        let (vertices, stencils) = polar::stencils_around(last, degree, &on_curve, &is_local)?;
        for (i, &v) in vertices.iter().enumerate() {
            masks_of[v as usize] = LimitMask::Composed(i as u32);
        }
        local.retain(|&v| masks_of[v as usize] == LimitMask::Local);
        composed = stencils;
    }
    if !local.is_empty() && matches!(unclean, Unclean::LocalWithFans | Unclean::Polar) {
        for (i, mask) in masks_of.iter_mut().enumerate() {
            if matches!(
                mask,
                LimitMask::Curve | LimitMask::Corner | LimitMask::Valence2(_)
            ) {
                *mask = LimitMask::Local;
                local.push(i as u32);
            }
        }
        local.sort_unstable();
    }
    let masks = valences
        .iter()
        .map(|&k| cached_vertex_masks(degree, k))
        .collect::<Result<Vec<_>>>()?;
    let joint = masks
        .iter()
        .map(|m| match &m.tangents {
            [a, b] if !a.is_empty() => (m.position.iter().zip(a).zip(b))
                .map(|((&p, &a), &b)| [p, a, b, 0.0])
                .collect(),
            _ => Vec::new(),
        })
        .collect();
    let folded = masks.iter().map(|m| Folded::of(m, primal)).collect();

    // Fans at curve vertices and corners, one per output corner there: (level corner, stencil).
    let output_corners = targets.output.num_corners();
    let on_curve = |c: usize| {
        let d = (targets.corner)(c)?;
        let i = (targets.index)(last.corner_verts[d] as usize)?;
        let fan = matches!(
            masks_of[i],
            LimitMask::Curve | LimitMask::Corner | LimitMask::Valence2(_)
        );
        fan.then_some((d, i))
    };
    // Only the output corners at the stencils' own vertices can have a fan there (in order).
    let mut fan_candidates: Vec<u32> = Vec::new();
    for (i, mask) in masks_of.iter().enumerate() {
        if matches!(
            mask,
            LimitMask::Curve | LimitMask::Corner | LimitMask::Valence2(_)
        ) {
            let at = (targets.output_vertex)(i);
            fan_candidates.extend_from_slice(targets.output.corners_of_vertex(at));
        }
    }
    fan_candidates.sort_unstable();
    // At most one fan per such corner, and at most three items per corner of a fan (its
    // outline, or its faces and two curve edges).
    let fan_corners = (fan_candidates.iter())
        .filter(|&&c| on_curve(c as usize).is_some())
        .count();
    let mut corner_fan = memory::filled(output_corners, NONE)?;
    let mut fan_offsets = memory::with_capacity(fan_corners + 1)?;
    fan_offsets.push(0u32);
    let mut fan_closed = memory::with_capacity(fan_corners)?;
    let mut fan_vertex = memory::with_capacity(fan_corners)?;
    let mut fan_items = memory::with_capacity(3 * fan_corners)?;
    let mut fan_of_start: HashMap<usize, u32> = HashMap::new();
    fan_of_start
        .try_reserve(fan_corners)
        .map_err(|_| memory::refused_bytes(16 * fan_corners as u64))?;
    for &c in &fan_candidates {
        let c = c as usize;
        let Some((d, i)) = on_curve(c) else {
            continue;
        };
        let fan = &mut corner_fan[c];
        // Clockwise to the fan's start: across outgoing edges until a curve edge. A fan that
        // closes on itself starts at its smallest corner, so that every corner of its vertex
        // takes the one fan, summed in one order (bitwise one normal).
        let mut start = d;
        let mut smallest = d;
        let mut closed = false;
        loop {
            let e = last.corner_edges()[start];
            if is_curve_edge(e) {
                break;
            }
            match last.opposite(e as usize, start) {
                Some(o) => start = last.next(o),
                None => break,
            }
            if start == d {
                closed = true;
                start = smallest;
                break;
            }
            smallest = smallest.min(start);
        }
        if let Some(&id) = fan_of_start.get(&start) {
            *fan = id;
            continue;
        }
        // Counter-clockwise from the start, collecting the fan's points.
        let mut corners = vec![start];
        loop {
            let x = *corners.last().expect("a corner");
            let p = last.prev(x);
            let e = last.corner_edges()[p];
            if is_curve_edge(e) && !closed {
                break;
            }
            match last.opposite(e as usize, p) {
                Some(o) if o != start => corners.push(o),
                _ => break,
            }
        }
        if primal {
            // The fan's outline: next(x1), then opposite and previous corner of each face
            // (previous of one face is next of the following one); a closed fan is cyclic.
            if !closed {
                fan_items.push(last.corner_verts[last.next(start)]);
            }
            for &x in &corners {
                fan_items.push(last.corner_verts[last.next(last.next(x))]);
                fan_items.push(last.corner_verts[last.prev(x)]);
            }
        } else if closed && corners.len() == 2 {
            // Valence 2 (dual data): the two face points alone would span no area; take the
            // four faces across the far edges of the two faces instead, counter-clockwise (the
            // neighbourhood is clean, so they are there).
            for &x in &corners {
                for y in [last.next(x), last.next(last.next(x))] {
                    let across =
                        (last.opposite(last.corner_edges()[y] as usize, y)).ok_or_else(|| {
                            Error::Internal("limit fans: a valence-2 vertex on a boundary".into())
                        })?;
                    fan_items.push(last.face_of(across) as u32);
                }
            }
        } else {
            let curve_item = |e: u32| -> Result<u32> {
                let i = curve_index(e).ok_or_else(|| {
                    Error::Internal("limit fans: a fan ends on an edge of no curve".into())
                })?;
                Ok(nf as u32 + i)
            };
            if !closed {
                fan_items.push(curve_item(last.corner_edges()[start])?);
            }
            fan_items.extend(corners.iter().map(|&x| last.face_of(x) as u32));
            if !closed {
                let x = *corners.last().expect("a corner");
                fan_items.push(curve_item(last.corner_edges()[last.prev(x)])?);
            }
        }
        let id = fan_closed.len() as u32;
        fan_closed.push(closed);
        fan_vertex.push(i as u32);
        fan_offsets.push(fan_items.len() as u32);
        fan_of_start.insert(start, id);
        *fan = id;
    }
    let untiled = memory::collect(
        (masks_of.iter().enumerate())
            .filter(|(_, &mask)| mask != LimitMask::Tiled)
            .map(|(i, _)| i as u32),
    )?;
    Ok(Some(Stencils {
        extended: None,
        extra_levels: 0,
        local: None,
        local_vertices: local,
        masks_of,
        composed,
        tiles,
        untiled,
        offsets,
        items,
        masks,
        joint,
        folded,
        curve_mask,
        corner_fan,
        fan_offsets,
        fan_closed,
        fan_vertex,
        fan_items,
        normals_split: OnceLock::new(),
    }))
}

/// Whether the vertices of `ring` (a neighbourhood of [`frame_items`]) other than its centre
/// are regular (valence 4, not `on_curve`) and all different: a polar grid around the centre.
fn polar_grid(last: &Level, ring: &[Labelled], on_curve: &dyn Fn(usize) -> bool) -> bool {
    let mut ids: Vec<usize> = Vec::with_capacity(ring.len());
    for &(label, w) in ring {
        if label != (0, 0, 0) && (last.corners_of_vertex(w).len() != 4 || on_curve(w)) {
            return false;
        }
        ids.push(w);
    }
    ids.sort_unstable();
    ids.dedup();
    ids.len() == ring.len()
}

/// The stencils of a chunk of targets: per target its mask (`None`: not clean) and the end of
/// its items in `items`.
#[derive(Default)]
struct ChunkStencils {
    masks: Vec<Option<LimitMask>>,
    ends: Vec<u32>,
    items: Vec<u32>,
}

/// The interior stencils of a quad level: the walk of [`sector_frames`] and the checks of
/// [`build_stencils`] on tables made once per level.
struct QuadWalk<'a> {
    level: &'a Level,
    /// [`Level::twin_corners`] of the level.
    twins: Vec<u32>,
    /// Per vertex: 0 if interior of valence 4 and on no curve (regular), else
    /// [`Stamps::IRREGULAR`]: the table each task's [`Stamps`] starts from.
    marks: Vec<u32>,
    /// The neighbourhood size `N`.
    n: usize,
    primal: bool,
}

/// What [`QuadWalk::interior`] found.
enum Walked {
    /// A clean neighbourhood: the mask (by valence), the items written.
    Clean(LimitMask),
    /// Not clean.
    NotClean,
    /// The walk around the centre does not close after its valence's sectors (a
    /// non-manifold vertex): left to the general walk.
    Other,
}

impl QuadWalk<'_> {
    /// The stencil of interior vertex `v`, its items appended to `items` in the order of
    /// [`frame_items`] (past their length on entry they are garbage unless it is clean): the
    /// frames of [`sector_frames`], each read as it is walked. `stamps` is kept between calls.
    fn interior(&self, v: usize, stamps: &mut Stamps, items: &mut Vec<u32>) -> Walked {
        let l = self.level;
        let (twins, verts) = (&self.twins[..], &l.corner_verts[..]);
        // On a quad, next(c) and prev(c) turn within the face's four corners; next(next(c))
        // is c ^ 2.
        let (next, prev) = (quad_next, quad_prev);
        let twin = |c: usize| {
            let t = twins[c];
            (t != NONE).then_some(t as usize)
        };
        let (n, side, primal) = (self.n, self.n + 1, self.primal);
        let corners = l.corners_of_vertex(v);
        let (Some(&first), k) = (corners.first(), corners.len()) else {
            return Walked::Other;
        };
        let first = first as usize;
        let centre = verts[first];
        stamps.start();
        // An irregular centre keeps its mark (and fails a walk back to it, as a regular one
        // then fails as seen).
        stamps.insert(centre);
        items.reserve(1 + k * n * side);
        if primal {
            items.push(centre);
        }
        let walk = |stamps: &mut Stamps, items: &mut Vec<u32>| -> Option<Option<usize>> {
            // Sector by sector counter-clockwise, as `SectorGrid`: the next sector lies across
            // the incoming edge of this one's corner at the centre.
            let mut start = first;
            for s in 0..k {
                if s > 0 {
                    start = twin(prev(start))?;
                    if start == first {
                        return Some(None);
                    }
                }
                // Row 0 (along the sector's first edge): its faces (even degrees).
                let mut o = start;
                for j in 0..side {
                    if j > 0 {
                        o = twin(o ^ 2)?;
                    }
                    if !primal && j < n {
                        items.push((o >> 2) as u32);
                    }
                }
                // Rows 1..=N: their vertices (within N rings, not the centre) must be regular
                // and all different (the neighbourhood is a disc).
                let mut row = start;
                for i in 1..side {
                    row = next(twin(next(row))?);
                    let mut o = row;
                    for j in 0..side {
                        if j > 0 {
                            o = twin(o ^ 2)?;
                        }
                        let w = verts[o];
                        if !stamps.insert(w) {
                            return None;
                        }
                        if primal {
                            items.push(w);
                        } else if i < n && j < n {
                            items.push((o >> 2) as u32);
                        }
                    }
                }
            }
            Some((twin(prev(start))? == first).then_some(k))
        };
        match walk(stamps, items) {
            None => Walked::NotClean,
            Some(None) => Walked::Other,
            Some(Some(2)) => Walked::Clean(LimitMask::Valence2(2)),
            Some(Some(k)) => Walked::Clean(LimitMask::Interior(k as u32)),
        }
    }
}

/// The vertices of one neighbourhood at a time, and the level's vertices that are not regular,
/// in one table per level vertex: each neighbourhood has its own stamp, so a new one starts
/// without clearing the table, and one read per vertex tells both whether it is regular and
/// whether the walk has met it (the neighbourhood is a disc).
#[derive(Default)]
struct Stamps {
    table: Vec<u32>,
    stamp: u32,
}

impl Stamps {
    /// The mark of a vertex that is not regular (never a neighbourhood's stamp).
    const IRREGULAR: u32 = u32::MAX;

    /// Stamps over `marks` (0 for a regular vertex, else [`Stamps::IRREGULAR`]), copied
    /// fallibly.
    fn new(marks: &[u32]) -> Result<Stamps> {
        let mut table = memory::with_capacity(marks.len())?;
        table.extend_from_slice(marks);
        Ok(Stamps { table, stamp: 0 })
    }

    /// Starts the (empty) set of a new neighbourhood.
    fn start(&mut self) {
        self.stamp += 1;
        if self.stamp == Self::IRREGULAR {
            // Every stamp used: the table forgets the neighbourhoods, not the marks.
            for e in self.table.iter_mut().filter(|e| **e != Self::IRREGULAR) {
                *e = 0;
            }
            self.stamp = 1;
        }
    }

    /// Adds vertex `w`; false if it is not regular or was there.
    fn insert(&mut self, w: u32) -> bool {
        match self.table.get_mut(w as usize) {
            Some(e) if *e != self.stamp && *e != Self::IRREGULAR => {
                *e = self.stamp;
                true
            }
            _ => false,
        }
    }
}

/// Per vertex of `level`, 0 when it is regular (valence 4, interior, on none of `curves`), else
/// [`Stamps::IRREGULAR`]: the marks of the stencils' and the tiles' walks.
fn regular_marks(level: &Level, curves: &CurveNetwork) -> Result<Vec<u32>> {
    gather_hinted(level.num_vertices, |w| {
        let regular =
            level.corners_of_vertex(w).len() == 4 && curves.vertex_index(w as u32).is_none();
        if regular {
            0
        } else {
            Stamps::IRREGULAR
        }
    })
}

/// Stamps taken from a pool for one parallel task, put back when it ends.
struct Pooled<'a> {
    stamps: Result<Stamps>,
    pool: &'a Mutex<Vec<Stamps>>,
}

impl<'a> Pooled<'a> {
    /// Stamps from `pool`, or new ones over `marks` when it is empty.
    fn take(pool: &'a Mutex<Vec<Stamps>>, marks: &[u32]) -> Pooled<'a> {
        let kept = pool.lock().unwrap_or_else(|e| e.into_inner()).pop();
        let stamps = kept.map_or_else(|| Stamps::new(marks), Ok);
        Pooled { stamps, pool }
    }
}

impl Drop for Pooled<'_> {
    fn drop(&mut self) {
        let stamps = std::mem::replace(&mut self.stamps, Ok(Stamps::default()));
        if let Ok(stamps) = stamps {
            self.pool
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .push(stamps);
        }
    }
}

/// Per curve vertex of `curves` (a step's network), true when its rules change in a later step:
/// a semi-sharp feature makes it (an end of a semi-sharp curve edge, a blend, a corner by a
/// semi-sharp tag of `semi_corners`, sorted cage vertices), or it is a corner whose cage point
/// is unknown (cut off on a partial level). Such a vertex has no fixed 1-D or corner rule, so
/// it is not clean: the limit must wait until the feature has become smooth.
fn transient_curve_vertices(curves: &CurveNetwork, semi_corners: &[u32]) -> Result<Vec<bool>> {
    let vertices = curves.vertices();
    let mut transient = memory::filled(vertices.len(), false)?;
    let mut curve_edges = memory::filled(vertices.len(), 0u8)?;
    for edge in curves.edges() {
        for end in edge.ends.into_iter().filter(|&x| x != NONE) {
            curve_edges[end as usize] = curve_edges[end as usize].saturating_add(1);
            transient[end as usize] |= is_semi_sharp(edge.sharpness);
        }
    }
    for (i, cv) in vertices.iter().enumerate() {
        // A corner on two curve edges (or none) is one by its tag alone: transient when the tag
        // is finite (then it becomes a curve vertex, or smooth); on one or three it stays one.
        let tagged = cv.edges.is_none() && matches!(curve_edges[i], 0 | 2);
        let semi_tag = tagged && semi_corners.binary_search(&cv.pin).is_ok();
        let cut_off = cv.edges.is_none() && cv.pin == NONE;
        transient[i] |= cv.weight < 1.0 || semi_tag || cut_off;
    }
    Ok(transient)
}

/// The limit's part of a plan: the stencils, built on first use and kept, and the limit's own
/// working arrays of the last level's size (the normals per vertex; the tiles' values had one
/// too before they were written in place), kept for the next call as the evaluation keeps its
/// buffers: made anew on every call, their page faults were about half of a cached limit's
/// time at degree 9 in the callgrind driver (two threads: 38.4 ms a call, 20.6 ms with the
/// arrays kept).
#[derive(Debug, Default)]
pub(crate) struct LimitCache(Mutex<Option<Arc<Stencils>>>, Scratch);

impl LimitCache {
    /// Frees the kept working arrays (the stencils stay).
    pub(crate) fn release_buffers(&self) {
        self.1.clear();
        // The whole plan extended keeps its own.
        let kept = self.0.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, scratch)) = kept.as_ref().and_then(|st| st.extended.as_ref()) {
            scratch.clear();
        }
    }
}

/// The stencils of `refinement`, built on first use (see the module documentation).
fn stencils(refinement: &Refinement, cache: &LimitCache) -> Result<Arc<Stencils>> {
    let mut kept = cache.0.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(st) = kept.as_ref() {
        return Ok(st.clone());
    }
    let st = Arc::new(build(refinement, Some(LOCAL_SHARE), true)?);
    *kept = Some(st.clone());
    Ok(st)
}

/// Builds the stencils of `refinement`: at its last level where every vertex is clean there;
/// else, with `local` (the [`LOCAL_SHARE`] it allows) and the averaging rules, the vertices
/// that are not clean (near irregular vertices, curves, and semi-sharp features until they
/// have become smooth) on partial levels around them; else on the whole refinement extended.
/// With `tiled`, the regular vertices of the plan's own last level go to limit tiles.
fn build(refinement: &Refinement, local: Option<usize>, tiled: bool) -> Result<Stencils> {
    let options = *refinement.options();
    let levels = options.levels;
    // Semi-sharp features must have left the last step's network (corners on isolated vertices
    // are no features: they have no place in the surface): a feature of sharpness s is in the
    // networks of the steps from levels below s, so the last step must start at ceil(s).
    let features = refinement.features();
    let finite = (features.edge_sharpness.iter())
        .chain(features.corners.iter().map(|c| &c.1))
        .copied()
        .filter(|&s| is_semi_sharp(s))
        .fold(0.0f32, f32::max);
    let semi_corners = semi_corners(refinement);
    let smooth = match finite > 0.0 {
        true => (finite.ceil() as u32 + 1).saturating_sub(levels),
        false => 0,
    };
    let first = smooth.max(u32::from(levels == 0));
    let clean = clean_levels(options.degree);
    let mut candidates = vec![first, first.max(clean)];
    candidates.extend((1..=MAX_EXTRA_LEVELS).map(|i| first.max(clean) + i));
    candidates.dedup();
    candidates.retain(|&m| m > 0);
    // The last level's edge and vertex -> corner tables, fallibly (`levels()` would panic).
    let all_levels = refinement.try_levels()?;
    let last = refinement.last_level();
    let outputs = last.num_vertices;
    let degree = options.degree;
    let whole = |i: usize| i;
    let below = |w: usize| (w < outputs).then_some(w);
    let share = local.filter(|_| matches!(refinement.scheme(), Scheme::Averaging { .. }));
    // A plan of level 0 has no step to make stencils on: always extended.
    if levels > 0 && (smooth == 0 || share.is_some()) {
        // The stencils at the plan's own last level; with the averaging rules, the vertices
        // that are not clean there get theirs on partial levels around them.
        let curves = refinement.last_network("the limit's stencils")?;
        let targets = Targets {
            count: outputs,
            output: last,
            output_vertex: &whole,
            vertex: &whole,
            corner: &Some,
            index: &below,
        };
        let unclean = match share {
            Some(_) => Unclean::Polar,
            None => Unclean::Refuse,
        };
        // Tiles over the faces of the highest quad level at most MAX_DEPTH levels above.
        let depth = (0..=levels.min(tiles::MAX_DEPTH))
            .rev()
            .map(|t| (t, &all_levels[(levels - t) as usize]))
            .find(|(_, above)| above.all_quads())
            .filter(|_| tiled);
        let built = build_stencils(
            last,
            curves,
            degree,
            &targets,
            &semi_corners,
            unclean,
            depth,
        )?;
        if let Some(mut st) = built {
            if st.local_vertices.is_empty() {
                return Ok(st);
            }
            let share = share.unwrap_or_default();
            let vertices = &st.local_vertices;
            let rings = local_rings(degree);
            let local_at = |m: u32, seeds: Vec<u64>, unclean: Unclean| {
                let levels = LocalLevels::new(refinement, &seeds, m, vertices, rings)?;
                local_stencils(refinement, vertices, m, levels, &semi_corners, unclean)
            };
            // Past semi-sharp features, the first stage, `clean` levels down (made once).
            let mut first_stage = None;
            for &m in &candidates {
                if smooth > 0 && m > clean && first_stage.is_none() {
                    let seeds = local_seeds(last, degree, vertices, clean)?;
                    first_stage = local_at(clean, seeds, Unclean::Local)?;
                }
                let built = match first_stage.take() {
                    Some(first)
                        if smooth > 0 && m > clean && !first.0.local_vertices.is_empty() =>
                    {
                        let stage = (clean, &first);
                        match staged_local_stencils(refinement, vertices, stage, m, &semi_corners)?
                        {
                            Some(second) => {
                                let (mut st1, levels1) = first;
                                st1.local = Some(second);
                                st1.extra_levels = m;
                                Some((st1, levels1))
                            }
                            None => {
                                first_stage = Some(first);
                                None
                            }
                        }
                    }
                    kept => {
                        first_stage = kept;
                        let seeds = local_seeds(last, degree, vertices, m)?;
                        // Partial levels are made on every evaluation, at more than the cost
                        // of a cached level per face: around most of the mesh, the whole plan
                        // extended (its topology kept) is cheaper.
                        if smooth == 0 && share * seeds.len() > last.num_faces() {
                            break;
                        }
                        match smooth == 0 && neighbourhood_size(degree) >= STEPWISE_RINGS {
                            true => {
                                stepwise_local_stencils(refinement, vertices, m, &semi_corners)?
                            }
                            false => local_at(m, seeds, Unclean::Refuse)?,
                        }
                    }
                };
                let Some(built) = built else {
                    continue;
                };
                // The whole plan extended has 4^m times the plan's faces per level; the
                // partial levels grow about 2^m times along semi-sharp features, and a
                // stepwise extension is made around fewer vertices each level: their sizes
                // decide.
                if (share as u64) * local_faces(&built) > whole_extension_faces(last, m) {
                    break;
                }
                st.local = Some(built);
                st.extra_levels = m;
                return Ok(st);
            }
        }
    }
    for m in candidates {
        let extended = Refinement::new(
            refinement.cage(),
            &Options {
                levels: levels + m,
                output: OutputKind::Primal,
                ..options
            },
        )?;
        extended.complete_levels()?;
        let spread = 4usize.pow(m);
        let corner = |c: usize| Some(c * spread);
        let targets = Targets {
            count: outputs,
            output: last,
            output_vertex: &whole,
            vertex: &whole,
            corner: &corner,
            index: &below,
        };
        let ext_last = extended.last_level();
        let curves = extended.last_network("the limit's stencils")?;
        if let Some(mut st) = build_stencils(
            ext_last,
            curves,
            degree,
            &targets,
            &semi_corners,
            Unclean::Refuse,
            None,
        )? {
            st.extended = Some((extended, Scratch::default()));
            st.extra_levels = m;
            return Ok(st);
        }
    }
    Err(Error::Internal(format!(
        "no clean neighbourhood for the limit within {MAX_EXTRA_LEVELS} extra levels"
    )))
}

/// The cage vertices tagged semi-sharp corners, sorted.
fn semi_corners(refinement: &Refinement) -> Vec<u32> {
    (refinement.features().corners.iter())
        .filter(|c| is_semi_sharp(c.1))
        .map(|c| c.0)
        .collect()
}

/// Levels past a vertex that make it clean unless another irregular vertex, a curve or a
/// semi-sharp feature is near: enough doubling to put `N` rings between it and its nearest
/// neighbour of the level.
fn clean_levels(degree: u32) -> u32 {
    let n = neighbourhood_size(degree) as u32;
    (1..).find(|&m| (1u32 << m) > n).unwrap_or(1)
}

/// The faces of the last level `last` whose descendants `m` levels down hold the `N + 1` rings
/// of every vertex of `vertices` (a ring there lies within `ceil(d / 2^m) + 1` rings of `last`),
/// sorted: the seeds of the local extension.
fn local_seeds(last: &Level, degree: u32, vertices: &[u32], m: u32) -> Result<Vec<u64>> {
    let n = neighbourhood_size(degree);
    let rings = 2 + (n + 1).div_ceil(1 << m);
    let mut marked = memory::filled(last.num_faces(), false)?;
    let mut frontier: Vec<usize> = Vec::new();
    for &v in vertices {
        for &c in last.corners_of_vertex(v as usize) {
            let f = last.face_of(c as usize);
            if !marked[f] {
                marked[f] = true;
                frontier.push(f);
            }
        }
    }
    last.grow_face_rings(&mut marked, frontier, rings - 1);
    Ok((0..marked.len() as u64)
        .filter(|&f| marked[f as usize])
        .collect())
}

/// The faces of levels `L + 1 ..= L + m` of the whole plan extended past its last level `last`
/// (4^k times its faces at level `L + k`).
fn whole_extension_faces(last: &Level, m: u32) -> u64 {
    (last.num_faces() as u64) * ((4u64 << (2 * m)) - 4) / 3
}

/// The faces a local extension's partial levels make, its stages' included.
fn local_faces(local: &(Box<Stencils>, LocalLevels)) -> u64 {
    let next = local.0.local.as_ref().map_or(0, local_faces);
    local.1.num_faces() + next
}

/// Face rings around a target vertex that the last partial level must hold: what
/// [`build_stencils`] reads around a vertex (its N rings, the valences of their vertices and
/// 1-D masks N + 1 curve edges long), one ring more to spare.
fn local_rings(degree: u32) -> usize {
    neighbourhood_size(degree) + 2
}

/// The stencils of the output vertices `vertices` (of the plan's last level `M_L`, none clean
/// there) on the last level of `local`, partial levels made around them up to `M_{L+m}`;
/// the vertices that are not clean there either make it `None` or are listed as local, for
/// partial levels past these, as `unclean` says.
fn local_stencils(
    refinement: &Refinement,
    vertices: &[u32],
    m: u32,
    local: LocalLevels,
    semi_corners: &[u32],
    unclean: Unclean,
) -> Result<Option<(Box<Stencils>, LocalLevels)>> {
    let last = refinement.last_level();
    let degree = refinement.options().degree;
    let mut at = Vec::with_capacity(vertices.len());
    for &v in vertices {
        match local.vert_uid().binary_search(&(v as u64)) {
            Ok(w) => at.push(w),
            Err(_) => return Ok(None),
        }
    }
    // Stencil of each vertex of M_L (a table: every output corner asks, twice).
    let mut slot_of = memory::filled(last.num_vertices, NONE)?;
    for (i, &v) in vertices.iter().enumerate() {
        slot_of[v as usize] = i as u32;
    }
    let slot = |v: usize| (slot_of[v] != NONE).then_some(slot_of[v] as usize);
    let shift = 2 * (m - 1);
    let vertex = |i: usize| at[i];
    let corner = |c: usize| {
        slot(last.corner_verts[c] as usize)?;
        let f = local
            .face_uid()
            .binary_search(&((c as u64) << shift))
            .ok()?;
        Some(4 * f)
    };
    let outputs = last.num_vertices as u64;
    let index = |w: usize| {
        let uid = local.vert_uid()[w];
        (uid < outputs).then(|| slot(uid as usize)).flatten()
    };
    let targets = Targets {
        count: vertices.len(),
        output: last,
        output_vertex: &|i| vertices[i] as usize,
        vertex: &vertex,
        corner: &corner,
        index: &index,
    };
    let (level, network) = (local.level(), local.network()?);
    let built = build_stencils(
        level,
        network,
        degree,
        &targets,
        semi_corners,
        unclean,
        None,
    )?;
    Ok(built.map(|st| (Box::new(st), local)))
}

/// The local extension past semi-sharp features, `m` levels past `M_L`, in two stages: the
/// vertices of `vertices` (of `M_L`, none clean there) that are clean `first` levels down get
/// their stencils there (most of them: near the features but not on them, near irregular
/// vertices and curves, and the curve vertices, corners and valence-2 vertices with their
/// fans); the others, which the features still reach, on partial levels past those, around
/// them alone. `None` when some vertex is not clean at `M_{L+m}`.
fn staged_local_stencils(
    refinement: &Refinement,
    vertices: &[u32],
    first: (u32, &(Box<Stencils>, LocalLevels)),
    m: u32,
    semi_corners: &[u32],
) -> Result<Option<(Box<Stencils>, LocalLevels)>> {
    let (m1, (st1, levels1)) = first;
    let rest: Vec<u32> = (st1.local_vertices.iter())
        .map(|&i| vertices[i as usize])
        .collect();
    let Some(levels2) = extend_local(refinement, levels1, &rest, m - m1)? else {
        return Ok(None);
    };
    local_stencils(refinement, &rest, m, levels2, semi_corners, Unclean::Refuse)
}

/// `extra` partial levels past `before`'s last around `rest` (vertices of `M_L`, targets of
/// the next stage); `None` when one of them is not on `before`'s last level.
fn extend_local(
    refinement: &Refinement,
    before: &LocalLevels,
    rest: &[u32],
    extra: u32,
) -> Result<Option<LocalLevels>> {
    let degree = refinement.options().degree;
    let mut at = Vec::with_capacity(rest.len());
    for &v in rest {
        match before.vert_uid().binary_search(&(v as u64)) {
            Ok(w) => at.push(w as u32),
            Err(_) => return Ok(None),
        }
    }
    let seeds = local_seeds(before.level(), degree, &at, extra)?;
    let rings = local_rings(degree);
    before
        .extend(refinement, &seeds, extra, rest, rings)
        .map(Some)
}

/// The local extension `m` levels past `M_L` one level at a time: the vertices of `vertices`
/// (of `M_L`, none clean there) that are clean one level down get their stencils there, the
/// others go on one more level, on partial levels around them alone, and every vertex is clean
/// at `M_{L+m}` or the result is `None`. A vertex `d` rings from an irregular vertex or a curve
/// is clean once `2^k d > N`, so most are clean before `m` (at degree 9, `N = 4`: those 3 and 4
/// rings away one level down, 2 rings two levels down, only the nearest ring three levels
/// down), and each level is made around fewer of them. Curve vertices, corners and valence-2
/// vertices go on with the others while some are not clean: their fans are at the level where
/// every vertex is, as in one stage.
fn stepwise_local_stencils(
    refinement: &Refinement,
    vertices: &[u32],
    m: u32,
    semi_corners: &[u32],
) -> Result<Option<(Box<Stencils>, LocalLevels)>> {
    let last = refinement.last_level();
    let degree = refinement.options().degree;
    let rings = local_rings(degree);
    let mut stages: Vec<(Box<Stencils>, LocalLevels)> = Vec::new();
    let mut rest = vertices.to_vec();
    for k in 1..=m {
        let levels = match stages.last() {
            None => {
                let seeds = local_seeds(last, degree, &rest, 1)?;
                LocalLevels::new(refinement, &seeds, 1, &rest, rings)?
            }
            Some((_, before)) => match extend_local(refinement, before, &rest, 1)? {
                Some(levels) => levels,
                None => return Ok(None),
            },
        };
        let unclean = match k == m {
            true => Unclean::Refuse,
            false => Unclean::LocalWithFans,
        };
        let Some(stage) = local_stencils(refinement, &rest, k, levels, semi_corners, unclean)?
        else {
            return Ok(None);
        };
        let next: Vec<u32> = (stage.0.local_vertices.iter())
            .map(|&i| rest[i as usize])
            .collect();
        stages.push(stage);
        if next.is_empty() {
            break;
        }
        rest = next;
    }
    // Each stage holds the next.
    let mut chain = None;
    while let Some(mut stage) = stages.pop() {
        stage.0.local = chain;
        chain = Some(stage);
    }
    Ok(chain)
}

/// How the limit of `refinement` is found, or why it cannot be (`normals`: normals too).
fn check(refinement: &Refinement, normals: bool) -> Result<LimitMethod> {
    if refinement.options().output != OutputKind::Primal {
        return Err(Error::InvalidInput(
            "limit positions and normals are given at the drawing mesh's vertices: use the \
             primal output"
                .into(),
        ));
    }
    let rule = refinement.scheme().limit(normals)?;
    if rule == LimitMethod::CatmullClark && refinement.curve_networks().is_empty() {
        return Err(Error::InvalidInput(
            "classic limit positions need at least one level".into(),
        ));
    }
    Ok(rule)
}

/// Levels the limit evaluation adds to the plan of `refinement` (built on first use).
pub(crate) fn extra_levels(refinement: &Refinement, cache: &LimitCache) -> Result<u32> {
    match check(refinement, false)? {
        LimitMethod::Interpolating | LimitMethod::CatmullClark => Ok(0),
        LimitMethod::Eigen => Ok(stencils(refinement, cache)?.extra_levels),
    }
}

/// Whether some output vertex has different limit normals at its corners (see
/// [`crate::Plan::limit_normals_split`]): the corners of a vertex take the normal of one
/// stage's stencil or of its fans ([`corner_source`]), and only fans differ among them (a
/// closed fan, as at a valence-2 vertex, is one for all of its vertex's corners).
pub(crate) fn normals_split(refinement: &Refinement, cache: &LimitCache) -> Result<bool> {
    match check(refinement, true)? {
        // Each face's bilinear patch has its own normal at its corners.
        LimitMethod::Interpolating => Ok(true),
        LimitMethod::CatmullClark => Err(Error::Internal(
            "limit: classic normals passed the check".into(),
        )),
        LimitMethod::Eigen => {
            let st = stencils(refinement, cache)?;
            Ok(*st.normals_split.get_or_init(|| {
                let stages: Vec<&Stencils> = std::iter::once(&*st)
                    .chain(st.locals().map(|(local, _)| local.as_ref()))
                    .collect();
                let last = refinement.last_level();
                // Every other vertex takes its stencil's normal at all of its corners.
                st.local_vertices.iter().chain(&st.fan_vertex).any(|&v| {
                    let corners = last.corners_of_vertex(v as usize);
                    let source = |c: &u32| corner_source(&stages, *c as usize, v);
                    let first = corners.first().map(source);
                    corners.iter().any(|c| Some(source(c)) != first)
                })
            }))
        }
    }
}

/// Where the limit normal at output corner `c` (of vertex `v`) comes from: `(k, i, fan)`, the
/// stage `k` of `stages` (the plan's stencils, then the local extension's) that has the
/// vertex's stencil `i`, and the fan of that stage the corner takes (`NONE`: the stencil's own
/// normal); `k` is past the stages if none has it.
fn corner_source(stages: &[&Stencils], c: usize, v: u32) -> (usize, u32, u32) {
    let mut i = v;
    for (k, st) in stages.iter().enumerate() {
        if st.masks_of[i as usize] == LimitMask::Local {
            // Its stencil is the next stage's at its place among the local ones.
            i = st.local_vertices.binary_search(&i).unwrap_or_default() as u32;
            continue;
        }
        return (k, i, st.corner_fan[c]);
    }
    (stages.len(), i, NONE)
}

/// Limit positions at the output vertices (the drawing mesh's) of any per-vertex data of the
/// cage (`channels` interleaved values per cage vertex, checked). Old vertices keep their ids,
/// so the first values are the limits at the cage vertices.
pub(crate) fn positions<T: Scalar>(
    refinement: &Refinement,
    scratch: &Scratch,
    cache: &LimitCache,
    values: &[T],
    channels: usize,
) -> Result<Vec<T>> {
    let rule = check(refinement, false)?;
    let per_group = |group: &[T], n: usize| -> Result<Vec<T>> {
        let limit = Limit {
            refinement,
            scratch,
            cache,
            rule,
        };
        Ok(match n {
            1 => limit.of::<T, 1>(group, None)?.0,
            2 => limit.of::<T, 2>(group, None)?.0,
            3 => limit.of::<T, 3>(group, None)?.0,
            _ => limit.of::<T, 4>(group, None)?.0,
        })
    };
    if channels <= 4 {
        return per_group(values, channels);
    }
    in_groups_of_four(values, channels, |group| per_group(&group, 4))
}

/// Limit positions (3 channels) and unit limit normals of the surface of `points` (3 per cage
/// vertex, checked): one normal per output face corner, the same for every corner of a smooth
/// vertex and one per side at curve vertices and corners (split normals). Degenerate geometry
/// gives zero vectors.
pub(crate) fn surface<T: Scalar>(
    refinement: &Refinement,
    scratch: &Scratch,
    cache: &LimitCache,
    points: &[T],
    domain: NormalDomain,
) -> Result<(Vec<T>, Vec<T>)> {
    let rule = check(refinement, true)?;
    let limit = Limit {
        refinement,
        scratch,
        cache,
        rule,
    };
    let (positions, normals) = limit.of::<T, 3>(points, Some(domain))?;
    let normals = normals.ok_or_else(|| Error::Internal("limit: no normals made".into()))?;
    Ok((positions, normals))
}

/// One limit request on a plan's refinement.
struct Limit<'a> {
    refinement: &'a Refinement,
    scratch: &'a Scratch,
    cache: &'a LimitCache,
    rule: LimitMethod,
}

impl Limit<'_> {
    /// Limit positions (and normals, per vertex or corner of the last level) of `N`-channel
    /// values.
    fn of<T: Scalar, const N: usize>(
        &self,
        values: &[T],
        domain: Option<NormalDomain>,
    ) -> Result<(Vec<T>, Option<Vec<T>>)> {
        let normals = domain.is_some();
        let r = self.refinement;
        let (points, _) = values.as_chunks::<N>();
        let compact = r.compact(points);
        match self.rule {
            LimitMethod::CatmullClark => {
                let Final::Primal(last) = run(r, self.scratch, &compact, false)? else {
                    return Err(Error::Internal(
                        "limit: a classic run left dual data".into(),
                    ));
                };
                let levels = r.try_levels()?;
                let j = levels.len() - 1;
                let sharpness = r.sharpness(j).ok_or_else(|| {
                    Error::Internal("limit: a Catmull-Clark level without sharpness".into())
                })?;
                let out = catmark_limit(&levels[j], sharpness, &last)?;
                Ok((out.into_flattened(), None))
            }
            LimitMethod::Interpolating => {
                // Bilinear: the surface interpolates the refined points; each face's patch has
                // its own normal at its corners.
                let Final::Primal(last) = run(r, self.scratch, &compact, false)? else {
                    return Err(Error::Internal(
                        "limit: a degree-1 run left dual data".into(),
                    ));
                };
                let normals = domain
                    .map(|domain| {
                        let corners = face_corner_normals(r.last_level(), &last)?;
                        match domain {
                            NormalDomain::Corner => Ok(corners.into_flattened()),
                            NormalDomain::Vertex => vertex_normals(r.last_level(), &corners),
                        }
                    })
                    .transpose()?;
                Ok((last.into_flattened(), normals))
            }
            LimitMethod::Eigen => {
                let st = stencils(r, self.cache)?;
                let (data, curve) = self.limit_data(&st, &compact)?;
                let kept = &self.cache.1;
                let (positions, vertex_normals) = stencil_values(&st, &data, normals, kept)?;
                // The local extension's stages, each past the one before.
                let chain: Vec<_> = st
                    .locals()
                    .map(|(local, levels)| (local.as_ref(), levels))
                    .collect();
                // The local extension is made at the plan's own last level.
                let two_d = match r.options().degree % 2 {
                    0 => &data[..r.last_level().num_faces()],
                    _ => &data[..],
                };
                let levels: Vec<&LocalLevels> = chain.iter().map(|&(_, l)| l).collect();
                let ldata = self.local_data(&levels, two_d, &curve, &compact)?;
                let mut stages = vec![StencilValues {
                    stencils: &st,
                    data,
                    positions,
                    normals: vertex_normals,
                }];
                for ((local, _), data) in chain.into_iter().zip(ldata) {
                    let (positions, normals) = stencil_values(local, &data, normals, kept)?;
                    stages.push(StencilValues {
                        stencils: local,
                        data,
                        positions,
                        normals,
                    });
                }
                // Each stage's local vertices take the positions of the next, from the last.
                for s in (1..stages.len()).rev() {
                    let (before, after) = stages.split_at_mut(s);
                    let (own, next) = (&mut before[s - 1], &after[0]);
                    for (i, &v) in own.stencils.local_vertices.iter().enumerate() {
                        own.positions[v as usize] = next.positions[i];
                    }
                }
                let normals = (domain)
                    .map(|domain| self.stencil_normals(&mut stages, domain))
                    .transpose()?;
                let own = stages.swap_remove(0);
                // The level's data goes back to the buffers of the run that made it, the
                // normals per vertex to the limit's.
                self.run_of(&st).1.give(own.data);
                kept.give(own.normals);
                Ok((own.positions.into_flattened(), normals))
            }
        }
    }

    /// The refinement that `st` reads the last level of, and the buffers of its runs: the
    /// whole plan extended, or the plan's own.
    fn run_of<'s>(&'s self, st: &'s Stencils) -> (&'s Refinement, &'s Scratch) {
        match &st.extended {
            Some((r, s)) => (r, s),
            None => (self.refinement, self.scratch),
        }
    }

    /// The data the stencils read: the last level's vertex values (odd degrees), or its face
    /// values, then the last step's curve-edge values, then the cage points (even degrees);
    /// and the last step's 1-D values (curve vertices, odd; curve edges, even), which the local
    /// extension starts from.
    fn limit_data<T: Scalar, const N: usize>(
        &self,
        st: &Stencils,
        compact: &[[T; N]],
    ) -> Result<Parts<T, N>> {
        let (refinement, scratch) = self.run_of(st);
        let (mut data, curve) = run_parts(refinement, scratch, compact)?;
        if self.refinement.options().degree.is_multiple_of(2) {
            memory::reserve(&mut data, curve.len() + compact.len())?;
            data.extend_from_slice(&curve);
            data.extend_from_slice(compact);
        }
        Ok((data, curve))
    }

    /// The data of the last level of each of the local extension's `stages` (each past the one
    /// before, the first past the plan's) in the layout of [`Limit::limit_data`], from the
    /// plan's last level `two_d` (per vertex or face) and 1-D `curve` data: the partial levels
    /// carry three channels, so the channels go through them three at a time.
    fn local_data<T: Scalar, const N: usize>(
        &self,
        stages: &[&LocalLevels],
        two_d: &[[T; N]],
        curve: &[[T; N]],
        compact: &[[T; N]],
    ) -> Result<Vec<Vec<[T; N]>>> {
        if stages.is_empty() {
            return Ok(Vec::new());
        }
        let even = self.refinement.options().degree.is_multiple_of(2);
        let mut out: Vec<Vec<[T; N]>> = vec![Vec::new(); stages.len()];
        for first in (0..N).step_by(3) {
            let cage = three_channels(compact, first)?;
            let (mut data, mut curve) =
                (three_channels(two_d, first)?, three_channels(curve, first)?);
            for (k, (levels, out)) in stages.iter().zip(&mut out).enumerate() {
                let (mut fine, fine_curve) = levels.evaluate(&cage, &data, &curve)?;
                // The last stage's data is needed no more: moved, not copied.
                let mut layout = match k + 1 < stages.len() {
                    true => fine.clone(),
                    false => std::mem::take(&mut fine),
                };
                if even {
                    layout.extend_from_slice(&fine_curve);
                    layout.extend_from_slice(&cage);
                }
                (data, curve) = (Cow::Owned(fine), Cow::Owned(fine_curve));
                if out.is_empty() {
                    *out = memory::filled(layout.len(), [T::default(); N])?;
                }
                for (o, x) in out.iter_mut().zip(&layout) {
                    let width = 3.min(N - first);
                    o[first..first + width].copy_from_slice(&x[..width]);
                }
            }
        }
        Ok(out)
    }

    /// Unit normals per corner or per vertex of the last level from the values of the
    /// stencils' `stages` (the plan's, then the local extension's; see [`surface`]): each
    /// vertex's from the stage that has its stencil. Per vertex, the plan's stage gives its
    /// array of normals up (it is the output).
    fn stencil_normals<T: Scalar, const N: usize>(
        &self,
        stages: &mut [StencilValues<T, N>],
        domain: NormalDomain,
    ) -> Result<Vec<T>> {
        let fans = (stages.iter())
            .map(|s| fan_normals(s.stencils, &s.data, &s.positions))
            .collect::<Result<Vec<_>>>()?;
        let last = self.refinement.last_level();
        let corners = &last.corner_verts;
        let stencils: Vec<&Stencils> = stages.iter().map(|s| s.stencils).collect();
        let resolved = |c: usize| match corner_source(&stencils, c, corners[c]) {
            (k, _, _) if k == stages.len() => [T::default(); 3],
            (k, i, NONE) => stages[k].normals[i as usize],
            (k, _, f) => fans[k][f as usize].to_array().map(T::from_f64),
        };
        let st = stages[0].stencils;
        let elsewhere = st.local_vertices.iter().chain(&st.fan_vertex);
        if domain == NormalDomain::Vertex {
            // The plan's own stencils' normals are every vertex's but those of the local
            // extension and of the fans, whose corners are put together.
            let put_right = memory::collect(elsewhere.map(|&v| {
                let at_corners = last.corners_of_vertex(v as usize).iter();
                (v, unit_sum(at_corners.map(|&c| resolved(c as usize))))
            }))?;
            let mut out = std::mem::take(&mut stages[0].normals);
            for (v, n) in put_right {
                out[v as usize] = n;
            }
            return Ok(out.into_flattened());
        }
        // Most corners take the plan's own stencil's normal at their vertex (a gather by the
        // corner table); the corners at the vertices of the local extension and of the fans
        // are then put right.
        let mut out = gather_indexed(&stages[0].normals, corners)?;
        for &v in elsewhere {
            for &c in last.corners_of_vertex(v as usize) {
                out[c as usize] = resolved(c as usize);
            }
        }
        Ok(out.into_flattened())
    }
}

/// Channels `first..first + 3` of `x` (zero past `N`): `x` itself when it has three (the plan's
/// whole last level goes through here: not copied then, fallibly otherwise).
fn three_channels<T: Scalar, const N: usize>(
    x: &[[T; N]],
    first: usize,
) -> Result<Cow<'_, [[T; 3]]>> {
    if N == 3 {
        return Ok(Cow::Borrowed(x.as_flattened().as_chunks::<3>().0));
    }
    let picked = x
        .iter()
        .map(|v| std::array::from_fn(|k| v.get(first + k).copied().unwrap_or_default()));
    Ok(Cow::Owned(memory::collect(picked)?))
}

/// A set of stencils with the data they read, their limit positions and their unit normals at
/// interior vertices (zero elsewhere; empty when normals were not asked for).
struct StencilValues<'a, T, const N: usize> {
    stencils: &'a Stencils,
    data: Vec<[T; N]>,
    positions: Vec<[T; N]>,
    normals: Vec<[T; 3]>,
}

/// Per stencil: its limit position and its unit normal in `T`.
type PositionsNormals<T, const N: usize> = (Vec<[T; N]>, Vec<[T; 3]>);

/// Limit positions of every stencil of `st` from `data` (zero for [`LimitMask::Local`]) and,
/// with `normals`, the unit normals at its interior vertices in `T` (zero elsewhere; empty
/// without): the tiles write theirs in place, then every other stencil makes its position and
/// tangents in one walk over its data. The normals' array comes from `kept`.
fn stencil_values<T: Scalar, const N: usize>(
    st: &Stencils,
    data: &[[T; N]],
    normals: bool,
    kept: &Scratch,
) -> Result<PositionsNormals<T, N>> {
    let n = st.masks_of.len();
    let mut positions: Vec<[T; N]> = with_capacity_hinted(n)?;
    let mut unit = match normals {
        true => {
            kept.provision::<[T; 3]>(n, 1)?;
            kept.take(n)
        }
        false => Vec::new(),
    };
    if positions.capacity() < n || (normals && unit.capacity() < n) {
        return Err(Error::Internal("limit: arrays without room".into()));
    }
    let (p, q) = (
        &mut positions.spare_capacity_mut()[..n],
        unit.spare_capacity_mut(),
    );
    let mut q = match normals {
        true => Some(&mut q[..n]),
        false => None,
    };
    if let Some(tiles) = &st.tiles {
        tiles.write(data, p, q.as_deref_mut())?;
    }
    let at = |x: &[f64; N]| rounded::<T>([x[0], x[1], x[2]]);
    let none = [T::default(); 3];
    let value = |v: usize| match st.masks_of[v] {
        LimitMask::Interior(m) if normals && !st.joint[m as usize].is_empty() => {
            let items = &st.items[st.offsets[v] as usize..st.offsets[v + 1] as usize];
            let [p, a, b] = match &st.folded[m as usize] {
                Some(fold) => fold.joint(data, items),
                None => combine_joint(
                    data,
                    items.iter().map(|&i| i as usize),
                    &st.joint[m as usize],
                ),
            };
            let normal = at(&a).cross(at(&b)).normalize_or_zero();
            (p.map(T::from_f64), normal.to_array().map(T::from_f64))
        }
        LimitMask::Composed(i) if normals => {
            let [p, a, b] = st.composed.joint(i as usize, data);
            let normal = at(&a).cross(at(&b)).normalize_or_zero();
            (p.map(T::from_f64), normal.to_array().map(T::from_f64))
        }
        _ => (stencil_position(st, data, v), none),
    };
    // The other stencils, in chunks of their list; the tiles' vertices are written already.
    let untiled = &st.untiled;
    let listed =
        untiled.windows(2).all(|w| w[0] < w[1]) && untiled.last().is_none_or(|&v| (v as usize) < n);
    if !listed {
        return Err(Error::Internal(
            "limit: the untiled stencils out of order".into(),
        ));
    }
    let (p, q) = (Disjoint::new(p), q.map(Disjoint::new));
    untiled.par_chunks(CHUNK).for_each(|vertices| {
        for &v in vertices {
            let v = v as usize;
            match &q {
                Some(q) => {
                    let (x, y) = value(v);
                    // SAFETY: `v` is below `n`, the length of both (checked above), and in
                    // one chunk once (the list is strictly increasing).
                    unsafe {
                        p.write(v, x);
                        q.write(v, y);
                    }
                }
                // SAFETY: as above.
                None => unsafe { p.write(v, stencil_position(st, data, v)) },
            }
        }
    });
    // SAFETY: every vertex is a tile's (written by `Tiles::write`, which returned `Ok` only
    // after writing each of its vertices) or was written above (a panic would have unwound
    // past here); the normals likewise when asked for.
    unsafe {
        positions.set_len(n);
        if normals {
            unit.set_len(n);
        }
    }
    Ok((positions, unit))
}

/// The limit position of stencil `v` of `st` from `data` (zero for [`LimitMask::Local`]).
fn stencil_position<T: Scalar, const N: usize>(st: &Stencils, data: &[[T; N]], v: usize) -> [T; N] {
    let items = &st.items[st.offsets[v] as usize..st.offsets[v + 1] as usize];
    let weights: &[f64] = match st.masks_of[v] {
        LimitMask::Interior(m) => match &st.folded[m as usize] {
            Some(fold) => return fold.position(data, items).map(T::from_f64),
            None => &st.masks[m as usize].position,
        },
        LimitMask::Valence2(m) => &st.masks[m as usize].position,
        LimitMask::Curve => &st.curve_mask,
        LimitMask::Corner => return data[items[0] as usize],
        LimitMask::Composed(i) => return st.composed.position(i as usize, data),
        LimitMask::Local | LimitMask::Tiled => return zero(),
    };
    combine(data, items, weights)
}

/// Unit normals of the fans of `st`, from `data` and the stencils' limit `positions`.
fn fan_normals<T: Scalar, const N: usize>(
    st: &Stencils,
    data: &[[T; N]],
    positions: &[[T; N]],
) -> Result<Vec<DVec3>> {
    let at = |x: &[T; N]| DVec3::new(x[0].to_f64(), x[1].to_f64(), x[2].to_f64());
    gather_hinted(st.fan_closed.len(), |f| {
        let items = &st.fan_items[st.fan_offsets[f] as usize..st.fan_offsets[f + 1] as usize];
        let centre = at(&positions[st.fan_vertex[f] as usize]);
        let q: Vec<DVec3> = items
            .iter()
            .map(|&i| at(&data[i as usize]) - centre)
            .collect();
        let pairs = q.len() - usize::from(!st.fan_closed[f]);
        (0..pairs)
            .map(|i| q[i].cross(q[(i + 1) % q.len()]))
            .sum::<DVec3>()
            .normalize_or_zero()
    })
}

/// One normal for a vertex from the normals at its corners: theirs when they are all the same
/// (so a smooth vertex's is bitwise its corners'), else the unit vector along their sum (zero
/// when it vanishes).
fn unit_sum<T: Scalar>(mut normals: impl Iterator<Item = [T; 3]> + Clone) -> [T; 3] {
    let Some(first) = normals.next() else {
        return [T::default(); 3];
    };
    if normals.clone().all(|n| n == first) {
        return first;
    }
    let at = |n: [T; 3]| DVec3::new(n[0].to_f64(), n[1].to_f64(), n[2].to_f64());
    (at(first) + normals.map(at).sum::<DVec3>())
        .normalize_or_zero()
        .to_array()
        .map(T::from_f64)
}

/// One normal per vertex of `level` from the normals at its corners (`corners`, per corner of
/// the level), each by [`unit_sum`].
fn vertex_normals<T: Scalar>(level: &Level, corners: &[[T; 3]]) -> Result<Vec<T>> {
    let vertex = |v: usize| {
        unit_sum(
            level
                .corners_of_vertex(v)
                .iter()
                .map(|&c| corners[c as usize]),
        )
    };
    Ok(memory::collect((0..level.num_vertices).map(vertex))?.into_flattened())
}

/// Unit normals of each face's bilinear patch at its corners, face after face.
fn face_corner_normals<T: Scalar, const N: usize>(
    level: &Level,
    points: &[[T; N]],
) -> Result<Vec<[T; 3]>> {
    let at = |v: u32| {
        let x = &points[v as usize];
        DVec3::new(x[0].to_f64(), x[1].to_f64(), x[2].to_f64())
    };
    let mut out = memory::with_capacity(level.num_corners())?;
    for f in 0..level.num_faces() {
        let face = &level.corner_verts[level.face_corners(f)];
        let k = face.len();
        for i in 0..k {
            let p = at(face[i]);
            let (next, prev) = (at(face[(i + 1) % k]) - p, at(face[(i + k - 1) % k]) - p);
            out.push(
                next.cross(prev)
                    .normalize_or_zero()
                    .to_array()
                    .map(T::from_f64),
            );
        }
    }
    Ok(out)
}

/// Classic Catmull-Clark limit positions at the vertices of `level`, which must be a quad level
/// (`j >= 1`): OpenSubdiv's limit masks (regular `[1 4 1]^T [1 4 1] / 36`, extraordinary
/// smooth, crease `(1/6, 2/3, 1/6)`, corners interpolated; at a level where a semi-sharp
/// feature is still sharp, its current rule is used, as OpenSubdiv's `PrimvarRefiner::Limit`
/// does). An interior vertex of valence 2 takes the general smooth mask (its true limit, which
/// Blender's limit surface gives), where Sdc's limit mask would keep the vertex itself. At an
/// infinitely sharp dart the mask is the dominant left eigenvector of the dart's 1-ring
/// subdivision matrix ([`dart_limit_mask`]), not Sdc's smooth mask.
fn catmark_limit<T: Scalar, const N: usize>(
    level: &Level,
    this: &LevelSharpness,
    values: &[Value<T, N>],
) -> Result<Vec<Value<T, N>>> {
    if !level.is_quads() {
        return Err(Error::Internal("limit positions need a quad level".into()));
    }
    gather_hinted(level.num_vertices, |v| match this.rule(v) {
        VertexRule::Dart
            if level
                .vertex_edges(v)
                .any(|e| is_infinitely_sharp(this.edge(e as usize))) =>
        {
            // A dart for good (a semi-sharp dart becomes smooth later: smooth mask).
            dart_limit(level, this, v, values)
        }
        VertexRule::Smooth | VertexRule::Dart => {
            let corners = level.corners_of_vertex(v);
            let (fw, ew, vw) = smooth_limit_weights(corners.len());
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
        VertexRule::Crease => {
            let ends = level.sharp_neighbours(v, |e| is_sharp(this.edge(e as usize)));
            let (vertex, neighbour) = CREASE_LIMIT_WEIGHTS;
            let out = scale(values[v], T::from_f64(vertex));
            mad(
                out,
                T::from_f64(neighbour),
                add(values[ends[0]], values[ends[1]]),
            )
        }
        VertexRule::Corner => values[v],
    })
}

/// The limit of an infinitely sharp dart `v` of a quad level from its 1-ring.
fn dart_limit<T: Scalar, const N: usize>(
    level: &Level,
    this: &LevelSharpness,
    v: usize,
    values: &[Value<T, N>],
) -> Value<T, N> {
    // The ring in rotation order: corner c_i has edge neighbour e_i = next(c_i), opposite
    // f_i = next(next(c_i)), and face i is (v, e_i, f_i, e_{i+1}).
    let k = level.corners_of_vertex(v).len();
    let mut ring = Vec::with_capacity(k);
    let mut at = level.corners_of_vertex(v)[0] as usize;
    for _ in 0..k {
        ring.push(at);
        let Some(next) = level.next_around_vertex(at) else {
            // Not a closed ring (cannot happen for a dart): keep the vertex.
            return values[v];
        };
        at = next;
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

/// The 1-D B-spline mask of `degree` at a knot, lowest offset first: over the `2N + 1` vertices
/// at offsets `-N..=N` (odd degrees) or the `2N` edges or cells at `+-1/2 .. +-(N - 1/2)` (even
/// degrees); `f` is [`cardinal_bspline`] for the value or its derivative for the slope.
fn knot_mask(degree: u32, f: fn(u32, f64) -> f64) -> Vec<f64> {
    let n = neighbourhood_size(degree);
    let (width, shift) = match degree % 2 {
        1 => (2 * n + 1, 0.0),
        _ => (2 * n, 0.5),
    };
    (0..width)
        .map(|k| f(degree, k as f64 - n as f64 + shift))
        .collect()
}

/// A tangent's three channels rounded to `T`, in f64: f32 data gives f32 tangents, as it gives
/// f32 positions (the stencils and the tiles alike, so that their normals agree).
fn rounded<T: Scalar>(x: [f64; 3]) -> DVec3 {
    DVec3::from_array(x.map(|c| T::from_f64(c).to_f64()))
}

/// `sum w_i data[items_i]`, accumulated in f64.
fn combine<T: Scalar, const N: usize>(data: &[[T; N]], items: &[u32], weights: &[f64]) -> [T; N] {
    let mut acc = [0.0f64; N];
    for (&i, &w) in items.iter().zip(weights) {
        let x = &data[i as usize];
        for k in 0..N {
            acc[k] += w * x[k].to_f64();
        }
    }
    acc.map(T::from_f64)
}

/// The masks of valence 4 folded over the four sectors: there the position weights are the
/// same in every sector and each tangent's weights in sectors 2 and 3 are those of sectors 0
/// and 1 negated (mode 1 of the rotation), so each item's four sector copies are summed first
/// and opposite ones subtracted, about half the products of [`combine_joint`].
#[derive(Debug)]
struct Folded {
    /// The centre's position weight (odd degrees; even ones have no centre item).
    centre: Option<f64>,
    /// Per item of a sector: its position weight and the tangents' weights `[a, b]` in sectors
    /// 0 and 1.
    groups: Vec<(f64, [[f64; 2]; 2])>,
}

impl Folded {
    /// The folded masks of `m` (`primal`: with a centre item), if its valence is 4, it has
    /// tangents and its weights have the symmetry (to rounding: the modes' phases are rounded).
    fn of(m: &VertexMasks, primal: bool) -> Option<Folded> {
        let [a, b] = &m.tangents;
        let off = usize::from(primal);
        let len = m.position.len();
        if m.valence != 4 || a.len() != len || b.len() != len || len < off + 4 {
            return None;
        }
        let p = (len - off) / 4;
        let largest = (m.position.iter().chain(a).chain(b)).fold(0.0f64, |x, &w| x.max(w.abs()));
        let close = |x: f64, y: f64| (x - y).abs() <= 1e-12 * largest;
        let at = |mask: &[f64], s: usize, i: usize| mask[off + s * p + i];
        let symmetric = 4 * p + off == len
            && (!primal || (close(a[0], 0.0) && close(b[0], 0.0)))
            && (0..p).all(|i| {
                (1..4).all(|s| at(&m.position, s, i) == at(&m.position, 0, i))
                    && [a, b].iter().all(|t| {
                        close(at(t, 2, i), -at(t, 0, i)) && close(at(t, 3, i), -at(t, 1, i))
                    })
            });
        symmetric.then(|| Folded {
            centre: primal.then(|| m.position[0]),
            groups: (0..p)
                .map(|i| {
                    let pair = |s: usize| [at(a, s, i), at(b, s, i)];
                    (at(&m.position, 0, i), [pair(0), pair(1)])
                })
                .collect(),
        })
    }

    /// The limit position of a stencil's `items` (in the order of [`frame_items`]) from `data`.
    fn position<T: Scalar, const N: usize>(&self, data: &[[T; N]], items: &[u32]) -> [f64; N] {
        self.sums::<T, N, false>(data, items).0
    }

    /// The position and the two tangents, as [`combine_joint`] gives them.
    fn joint<T: Scalar, const N: usize>(&self, data: &[[T; N]], items: &[u32]) -> [[f64; N]; 3] {
        let (p, t) = self.sums::<T, N, true>(data, items);
        [p, t.map(|t| t[0]), t.map(|t| t[1])]
    }

    /// The position and (with `TANGENTS`) the tangents `[a, b]` per channel; the position's
    /// sums are the same either way, so positions alone equal those given with normals.
    #[inline(always)]
    fn sums<T: Scalar, const N: usize, const TANGENTS: bool>(
        &self,
        data: &[[T; N]],
        items: &[u32],
    ) -> ([f64; N], [[f64; 2]; N]) {
        let at = |i: u32| data[i as usize].map(T::to_f64);
        let mut position = [0.0f64; N];
        let mut tangents = [[0.0f64; 2]; N];
        let mut rest = items;
        if let (Some(w), Some((&c, tail))) = (self.centre, items.split_first()) {
            let x = at(c);
            for k in 0..N {
                position[k] += w * x[k];
            }
            rest = tail;
        }
        let p = self.groups.len();
        let sector = |s: usize| rest.get(s * p..(s + 1) * p).unwrap_or_default();
        let rows = (self.groups.iter())
            .zip(sector(0))
            .zip(sector(1))
            .zip(sector(2))
            .zip(sector(3));
        for ((((&(w, [t0, t1]), &i0), &i1), &i2), &i3) in rows {
            let (x0, x1, x2, x3) = (at(i0), at(i1), at(i2), at(i3));
            for k in 0..N {
                position[k] += w * ((x0[k] + x1[k]) + (x2[k] + x3[k]));
                if TANGENTS {
                    let (d02, d13) = (x0[k] - x2[k], x1[k] - x3[k]);
                    for j in 0..2 {
                        tangents[k][j] += t0[j] * d02 + t1[j] * d13;
                    }
                }
            }
        }
        (position, tangents)
    }
}

/// The three sums `sum w_i[j] data[items_i]` (`j` = position, the two tangents) in one walk,
/// accumulated in f64 in the order of [`combine`] (per channel, the three sums side by side).
fn combine_joint<T: Scalar, const N: usize>(
    data: &[[T; N]],
    items: impl IntoIterator<Item = usize>,
    weights: &[[f64; 4]],
) -> [[f64; N]; 3] {
    let mut acc = [[0.0f64; 4]; N];
    for (i, w) in items.into_iter().zip(weights) {
        let x = data[i].map(T::to_f64);
        for (acc, &x) in acc.iter_mut().zip(&x) {
            for (a, &w) in acc.iter_mut().zip(w) {
                *a += w * x;
            }
        }
    }
    std::array::from_fn(|j| std::array::from_fn(|k| acc[k][j]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Cage;
    use std::mem::MaybeUninit;

    /// [`surface`] with normals per corner, on scratch buffers of its own.
    fn corner_surface<T: Scalar>(
        refinement: &Refinement,
        cache: &LimitCache,
        points: &[T],
    ) -> (Vec<T>, Vec<T>) {
        surface(
            refinement,
            &Scratch::default(),
            cache,
            points,
            NormalDomain::Corner,
        )
        .unwrap()
    }

    /// An n x n grid of unit quads in the plane z = bump(x, y) (boundary, valence-2 corners).
    fn grid(n: usize) -> (Cage, Vec<f64>) {
        let id = |i: usize, j: usize| (i * (n + 1) + j) as i64;
        let mut indices = Vec::new();
        for i in 0..n {
            for j in 0..n {
                indices.extend([id(i, j), id(i, j + 1), id(i + 1, j + 1), id(i + 1, j)]);
            }
        }
        let mut points = Vec::new();
        for i in 0..=n {
            for j in 0..=n {
                let (x, y) = (j as f64, i as f64);
                points.extend([x, y, 0.3 * (x * 0.7).sin() * (y * 0.9).cos()]);
            }
        }
        let cage = Cage::from_indices((n + 1) * (n + 1), &vec![4; n * n], &indices).unwrap();
        (cage, points)
    }

    /// A cube of quads (eight valence-3 vertices), slightly perturbed.
    fn cube() -> (Cage, Vec<f64>) {
        let faces = [
            [0, 1, 3, 2],
            [4, 6, 7, 5],
            [0, 4, 5, 1],
            [2, 3, 7, 6],
            [0, 2, 6, 4],
            [1, 5, 7, 3],
        ];
        let indices: Vec<i64> = faces.iter().flatten().copied().collect();
        let points: Vec<f64> = (0..8)
            .flat_map(|v| {
                let at = |bit: usize| if v >> bit & 1 == 1 { 1.0 } else { -1.0 };
                [at(0) * 1.1, at(1), at(2) + 0.05 * v as f64]
            })
            .collect();
        (Cage::from_indices(8, &[4; 6], &indices).unwrap(), points)
    }

    /// Calls `check` with a refinement of every case (name, cage, points) at every degree from
    /// 2 to 9 and every level of `levels`, and the case's name for messages.
    fn for_each_refinement<P: AsRef<[f64]>>(
        cases: &[(&str, Cage, P)],
        levels: std::ops::RangeInclusive<u32>,
        mut check: impl FnMut(&Refinement, &[f64], &str),
    ) {
        for (name, cage, points) in cases {
            for degree in 2..=9 {
                for levels in levels.clone() {
                    let options = Options {
                        degree,
                        levels,
                        ..Options::default()
                    };
                    let refinement = Refinement::new(cage, &options).unwrap();
                    let case = format!("{name}, degree {degree}, level {levels}");
                    check(&refinement, points.as_ref(), &case);
                }
            }
        }
    }

    /// The largest gap between `a` and `b`.
    fn worst(a: &[f64], b: &[f64]) -> f64 {
        (a.iter().zip(b))
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
    }

    /// The stencils of `refinement` with the local extension wherever it can be made (the
    /// share of the plan's faces not limited) and with the whole plan extended, the largest gap
    /// between their limit positions at `points`, and their normals (per output corner); both
    /// extend the plan by as many levels.
    #[allow(clippy::type_complexity)]
    fn local_and_whole(
        refinement: &Refinement,
        points: &[f64],
        case: &str,
    ) -> (Arc<Stencils>, Arc<Stencils>, f64, [Vec<f64>; 2]) {
        let whole = LimitCache::default();
        *whole.0.lock().unwrap() = Some(Arc::new(build(refinement, None, true).unwrap()));
        let local = LimitCache::default();
        *local.0.lock().unwrap() = Some(Arc::new(build(refinement, Some(0), true).unwrap()));
        let (p, n) = corner_surface(refinement, &local, points);
        let (q, m) = corner_surface(refinement, &whole, points);
        let extra = |c: &LimitCache| extra_levels(refinement, c).unwrap();
        // Composed stencils around isolated irregular vertices need no level where they take
        // every vertex that is not clean.
        let st = stencils(refinement, &local).unwrap();
        if st.local.is_some() || st.extended.is_some() {
            assert_eq!(extra(&local), extra(&whole), "{case}");
        } else {
            assert_eq!(extra(&local), 0, "{case}");
        }
        assert_eq!((p.len(), n.len()), (q.len(), m.len()), "{case}");
        let stencils = |c: &LimitCache| stencils(refinement, c).unwrap();
        (stencils(&local), stencils(&whole), worst(&p, &q), [n, m])
    }

    /// Unit normals per output corner from the fans of the whole plan extended `m` levels,
    /// where its curve vertices, corners and valence-2 vertices are clean (zero elsewhere): the
    /// fans that the first stage past semi-sharp features keeps.
    fn whole_fans(refinement: &Refinement, points: &[f64], m: u32) -> Vec<f64> {
        let options = *refinement.options();
        let extended = Options {
            levels: options.levels + m,
            output: OutputKind::Primal,
            ..options
        };
        let extended = Refinement::new(refinement.cage(), &extended).unwrap();
        extended.complete_levels().unwrap();
        let last = refinement.last_level();
        let spread = 4usize.pow(m);
        let (whole, below) = (|i| i, |w| (w < last.num_vertices).then_some(w));
        let targets = Targets {
            count: last.num_vertices,
            output: last,
            output_vertex: &whole,
            vertex: &whole,
            corner: &|c| Some(c * spread),
            index: &below,
        };
        let (ext_last, curves) = (extended.last_level(), extended.curve_networks().last());
        let semi = semi_corners(refinement);
        let degree = options.degree;
        let mut st = build_stencils(
            ext_last,
            curves.unwrap(),
            degree,
            &targets,
            &semi,
            Unclean::Local,
            None,
        )
        .unwrap()
        .unwrap();
        st.extended = Some((extended, Scratch::default()));
        st.extra_levels = m;
        let cache = LimitCache::default();
        *cache.0.lock().unwrap() = Some(Arc::new(st));
        corner_surface(refinement, &cache, points).1
    }

    /// A sphere of quads (an icosahedron's triangles split into three quads each, then `n x n`
    /// each): vertices of valence 3 and 5 among regular ones.
    fn ico_quads(n: usize) -> (Cage, Vec<f64>) {
        let t = (1.0 + 5f64.sqrt()) / 2.0;
        let corners = [
            [-1.0, t, 0.0],
            [1.0, t, 0.0],
            [-1.0, -t, 0.0],
            [1.0, -t, 0.0],
            [0.0, -1.0, t],
            [0.0, 1.0, t],
            [0.0, -1.0, -t],
            [0.0, 1.0, -t],
            [t, 0.0, -1.0],
            [t, 0.0, 1.0],
            [-t, 0.0, -1.0],
            [-t, 0.0, 1.0],
        ];
        let triangles = [
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ];
        // Points keyed by their position (rounded), so that shared edges share vertices.
        let mut points: Vec<f64> = Vec::new();
        let mut ids: HashMap<[i64; 3], i64> = HashMap::new();
        let mut id = |p: DVec3| -> i64 {
            let p = p.normalize() * (1.0 + 0.1 * (3.0 * p.x).sin() * p.y.cos());
            let key = (p * 1e9).round().to_array().map(|x| x as i64);
            *ids.entry(key).or_insert_with(|| {
                points.extend(p.to_array());
                (points.len() / 3 - 1) as i64
            })
        };
        let mut indices = Vec::new();
        for tri in triangles {
            let [a, b, c] = tri.map(|i| DVec3::from_array(corners[i]).normalize());
            let centre = (a + b + c) / 3.0;
            for (p, q, r) in [(a, b, c), (b, c, a), (c, a, b)] {
                // The quad at corner p: p, mid(p, q), centre, mid(r, p), as an n x n grid.
                let (u, v) = ((p + q) / 2.0, (r + p) / 2.0);
                let at = |i: usize, j: usize| {
                    let (x, y) = (i as f64 / n as f64, j as f64 / n as f64);
                    p * ((1.0 - x) * (1.0 - y))
                        + u * (x * (1.0 - y))
                        + centre * (x * y)
                        + v * ((1.0 - x) * y)
                };
                for j in 0..n {
                    for i in 0..n {
                        indices.extend(
                            [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)].map(&mut id),
                        );
                    }
                }
            }
        }
        let faces = indices.len() / 4;
        (
            Cage::from_indices(points.len() / 3, &vec![4; faces], &indices).unwrap(),
            points,
        )
    }

    /// Around isolated irregular vertices the composed stencils give the limits of the whole
    /// plan extended (to rounding: other sums of the same terms), at every degree; where they
    /// take every vertex that is not clean, no level is added. A crease at one irregular vertex
    /// leaves the vertices near it to the local extension (infinitely sharp: positions and
    /// normals as the whole plan extended's; semi-sharp: positions, the fans being the first
    /// stage's, see `semi_sharp_local_extension_matches_the_whole_plan_extended`).
    #[test]
    fn composed_stencils_match_the_whole_plan_extended() {
        let (sphere, points) = ico_quads(3);
        // The first face's first edge: at an icosahedron corner (valence 5).
        let edge = |s: f32| {
            let v = sphere.face_vertices();
            (sphere
                .clone()
                .with_creases(&[(v[0] as i64, v[1] as i64, s)]))
            .unwrap()
        };
        let cases = [
            ("sphere", sphere.clone(), points.clone()),
            ("creased sphere", edge(f32::INFINITY), points.clone()),
            ("semi-sharp sphere", edge(1.5), points.clone()),
        ];
        let (mut composed, mut mixed) = (0, 0);
        for_each_refinement(&cases, 1..=2, |refinement, points, case| {
            let whole = LimitCache::default();
            *whole.0.lock().unwrap() = Some(Arc::new(build(refinement, None, true).unwrap()));
            let (q, m) = corner_surface(refinement, &whole, points);
            let cache = LimitCache::default();
            let (p, n) = corner_surface(refinement, &cache, points);
            let st = stencils(refinement, &cache).unwrap();
            let count = (st.masks_of.iter())
                .filter(|m| matches!(m, LimitMask::Composed(_)))
                .count();
            composed += usize::from(count > 0);
            mixed += usize::from(count > 0 && st.local.is_some());
            if count > 0 && st.local_vertices.is_empty() {
                assert_eq!(st.extra_levels, 0, "{case}");
            }
            let (dp, dn) = (worst(&p, &q), worst(&n, &m));
            let semi = case.starts_with("semi");
            assert!(
                dp < 1e-12 && (semi || dn < 1e-11),
                "{case}: positions {dp:e}, normals {dn:e}"
            );
        });
        assert!(
            composed >= 36,
            "composed stencils made {composed} times of 48"
        );
        assert!(
            mixed >= 24,
            "composed and local stencils together {mixed} times of 32"
        );
        // The other valences' tables: a disc of one irregular vertex among ten rings of quads
        // (its boundary far enough at level 1), any data (positions compared).
        for valence in [6, 7, 8] {
            let disc = crate::analysis::polar_cage(valence, 10).unwrap();
            let data: Vec<f64> = (0..3 * disc.num_vertices())
                .map(|i| (0.7 * i as f64).sin())
                .collect();
            let cases = [("disc", disc, data)];
            for_each_refinement(&cases, 1..=1, |refinement, points, case| {
                let case = format!("{case}, valence {valence}");
                let whole = LimitCache::default();
                let st = build(refinement, None, true).unwrap();
                *whole.0.lock().unwrap() = Some(Arc::new(st));
                let q = positions(refinement, &Scratch::default(), &whole, points, 3).unwrap();
                // Local wherever it can be made: the boundary's vertices would take the
                // whole plan extended at most degrees, and the composed stencils with it.
                let cache = LimitCache::default();
                let st = build(refinement, Some(0), true).unwrap();
                *cache.0.lock().unwrap() = Some(Arc::new(st));
                let p = positions(refinement, &Scratch::default(), &cache, points, 3).unwrap();
                let st = stencils(refinement, &cache).unwrap();
                let count = (st.masks_of.iter())
                    .filter(|m| matches!(m, LimitMask::Composed(_)))
                    .count();
                let n = neighbourhood_size(refinement.options().degree);
                assert_eq!(count, valence * n * (n + 1), "{case}");
                assert!(worst(&p, &q) < 1e-12, "{case}: {:e}", worst(&p, &q));
            });
        }
    }

    /// The cages of the tiles' tests: the sphere of `ico_quads(n)` (irregular vertices), open
    /// and creased grids (boundaries, curves) and the cube (no grid anywhere).
    fn tile_cases(n: usize) -> Vec<(&'static str, Cage, Vec<f64>)> {
        let (sphere, sphere_points) = ico_quads(n);
        let (grid, grid_points) = grid(6);
        let crease = grid
            .clone()
            .with_creases(&[(8, 15, f32::INFINITY), (15, 22, f32::INFINITY)])
            .unwrap();
        vec![
            ("sphere", sphere, sphere_points),
            ("grid", grid, grid_points.clone()),
            ("creased grid", crease, grid_points),
            ("cube", cube().0, cube().1),
        ]
    }

    /// The limit tiles give the stencils' limits (other sums of the same masks: equal to
    /// rounding) and take most vertices; on a mesh with boundaries, creases and irregular
    /// vertices, at every degree and tile depth.
    #[test]
    fn tiles_match_the_stencils() {
        let cases = tile_cases(3);
        let mut engaged = 0;
        for_each_refinement(&cases, 1..=3, |refinement, points, case| {
            let with = |tiled: bool, cache: &LimitCache| {
                let st = build(refinement, Some(LOCAL_SHARE), tiled).unwrap();
                *cache.0.lock().unwrap() = Some(Arc::new(st));
                let scratch = Scratch::default();
                let (p, n) =
                    surface(refinement, &scratch, cache, points, NormalDomain::Corner).unwrap();
                let q = positions(refinement, &scratch, cache, points, 3).unwrap();
                assert_eq!(p, q, "{case}: positions alone");
                let single: Vec<f32> = points.iter().map(|&x| x as f32).collect();
                let (p32, n32) =
                    surface(refinement, &scratch, cache, &single, NormalDomain::Corner).unwrap();
                let widen = |x: Vec<f32>| x.into_iter().map(f64::from).collect::<Vec<_>>();
                (p, n, widen(p32), widen(n32))
            };
            let tiled_vertices = |cache: &LimitCache| {
                let st = cache.0.lock().unwrap().clone().unwrap();
                let tiled = (st.masks_of.iter())
                    .filter(|m| matches!(m, LimitMask::Tiled))
                    .count();
                (tiled, st.extended.is_none())
            };
            let (tiles, stencils) = (LimitCache::default(), LimitCache::default());
            let (p, n, p32, n32) = with(true, &tiles);
            let (q, m, q32, m32) = with(false, &stencils);
            let ((tiled, at_level), (none, _)) =
                (tiled_vertices(&tiles), tiled_vertices(&stencils));
            assert_eq!(none, 0);
            let scale = p.iter().fold(0.0f64, |x, y| x.max(y.abs()));
            let (dp, dn) = (worst(&p, &q), worst(&n, &m));
            assert!(
                dp < 1e-13 * scale && dn < 1e-11,
                "{case}: positions {dp:e}, normals {dn:e}"
            );
            // In f32: the same sums in f64, rounded once (a few ulps at most).
            let (dp, dn) = (worst(&p32, &q32), worst(&n32, &m32));
            assert!(
                dp < 1e-6 * scale && dn < 1e-5,
                "{case} (f32): positions {dp:e}, normals {dn:e}"
            );
            // Most vertices of the sphere are far from its irregular ones.
            let outputs = refinement.last_level().num_vertices;
            let levels = refinement.options().levels;
            if case.starts_with("sphere") && levels >= 3 && at_level {
                engaged += 1;
                assert!(
                    tiled * 10 >= outputs * 7,
                    "{case}: {tiled} of {outputs} vertices tiled"
                );
            }
        });
        assert!(
            engaged >= 6,
            "the sphere was tiled at level 3 for {engaged} degrees of 8"
        );
    }

    /// A torus of `n x m` quads (every vertex regular; small ones wrap around within a tile's
    /// window).
    fn torus(n: usize, m: usize) -> (Cage, Vec<f64>) {
        let id = |i: usize, j: usize| ((j % m) * n + i % n) as i64;
        let mut faces = Vec::new();
        for j in 0..m {
            for i in 0..n {
                faces.extend([id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        let points = (0..n * m)
            .flat_map(|k| {
                let (u, v) = (k % n, k / n);
                let (a, b) = (
                    std::f64::consts::TAU * u as f64 / n as f64,
                    std::f64::consts::TAU * v as f64 / m as f64,
                );
                [
                    (2.0 + b.cos()) * a.cos(),
                    (2.0 + b.cos()) * a.sin(),
                    b.sin(),
                ]
            })
            .collect();
        let cage = Cage::from_indices(n * m, &vec![4; n * m], &faces).unwrap();
        (cage, points)
    }

    #[test]
    fn fast_walks_are_the_walks() {
        // The tiles' cells from the faces above them are the walk's on their level: on the
        // sphere (irregular vertices), open and creased grids (boundaries, curves), the cube
        // (no grid above) and small tori (blocks that wrap around; the 2 x 5 one has doubled
        // edges, non-manifold).
        let mut cases = tile_cases(2);
        for (name, (n, m)) in [("torus 3 x 3", (3, 3)), ("torus 2 x 5", (2, 5))] {
            let (cage, points) = torus(n, m);
            cases.push((name, cage, points));
        }
        let mut from_above = HashMap::new();
        for_each_refinement(&cases, 1..=3, |refinement, _, case| {
            let levels = refinement.try_levels().unwrap();
            let (last, l) = (refinement.last_level(), levels.len() - 1);
            let depth = (l as u32).min(tiles::MAX_DEPTH);
            let above = &levels[l - depth as usize];
            let curves = refinement.last_network("test").unwrap();
            let marks = regular_marks(last, curves).unwrap();
            let twins = last.twin_corners().unwrap();
            let degree = refinement.options().degree;
            let (fast, all) = tiles::walks_agree(last, above, &twins, &marks, degree, depth);
            let name = case.split(',').next().unwrap().to_string();
            let counts = from_above.entry(name).or_insert((0, 0));
            *counts = (counts.0 + fast, counts.1 + all);
        });
        // A third of the small sphere's tiles take their cells from above (half of them at
        // most levels), all of the 3 x 3 torus', none of the cube's (every face has a corner of
        // valence 3) nor of the 2 x 5 torus' (its doubled edges are non-manifold).
        for (case, share) in [("sphere", 3), ("torus 3 x 3", 10), ("grid", 1)] {
            let (fast, all) = from_above[case];
            assert!(10 * fast >= share * all, "{case}: {fast} of {all}");
        }
        assert_eq!(from_above["cube"].0 + from_above["torus 2 x 5"].0, 0);
    }

    /// The local extension gives the limits of the whole plan extended (the stencils of the
    /// vertices clean at the plan's level are other masks of the same limit: equal to rounding;
    /// the others, curve normals included, are the same sums).
    /// The refinement of `cage` at level 3 with the averaging rules of `degree`.
    fn at_level_3(cage: &Cage, degree: u32) -> Refinement {
        let options = Options {
            degree,
            levels: 3,
            ..Options::default()
        };
        Refinement::new(cage, &options).unwrap()
    }

    #[test]
    fn kept_buffers_change_no_value() {
        // Each call reuses the arrays the one before left (tiles, normals, the level's data,
        // the whole plan extended's on the cube): a call between two on the same points
        // changes nothing, nor does freeing them.
        let (sphere, points) = ico_quads(3);
        let (cube, cube_points) = cube();
        let cases = [
            (&sphere, &points, 2, false),
            (&sphere, &points, 4, false),
            (&sphere, &points, 9, false),
            (&cube, &cube_points, 9, true),
        ];
        for (cage, points, degree, whole) in cases {
            let refinement = at_level_3(cage, degree);
            let other: Vec<f64> = points.iter().map(|&x| 2.0 * x + 0.25).collect();
            let (scratch, cache) = (Scratch::default(), LimitCache::default());
            let first =
                surface(&refinement, &scratch, &cache, points, NormalDomain::Corner).unwrap();
            let st = stencils(&refinement, &cache).unwrap();
            let extended = st.extended.as_ref().map(|e| &e.1);
            assert_eq!(extended.is_some(), whole, "degree {degree}");
            let between =
                surface(&refinement, &scratch, &cache, &other, NormalDomain::Corner).unwrap();
            let again =
                surface(&refinement, &scratch, &cache, points, NormalDomain::Corner).unwrap();
            assert_eq!(first, again, "degree {degree}");
            assert_ne!(first, between, "degree {degree}");
            assert!(extended.is_none_or(|s| s.kept_buffers() > 0));
            cache.release_buffers();
            assert!(extended.is_none_or(|s| s.kept_buffers() == 0));
            let released =
                surface(&refinement, &scratch, &cache, points, NormalDomain::Corner).unwrap();
            assert_eq!(first, released, "degree {degree}: buffers freed");
            let positions = positions(&refinement, &scratch, &cache, points, 3).unwrap();
            assert_eq!(positions, first.0, "degree {degree}: positions alone");
        }
    }

    /// Tiles own no output of their far column where the next tile holds it as its first (the
    /// claims of the near outputs come first), and then filter one column less.
    #[test]
    fn most_tiles_leave_their_far_column_to_the_next() {
        let (sphere, _) = ico_quads(3);
        let mut compared = 0;
        for degree in 2..=9 {
            let refinement = at_level_3(&sphere, degree);
            let cache = LimitCache::default();
            let st = stencils(&refinement, &cache).unwrap();
            let Some(tiles) = st.tiles.as_ref() else {
                continue;
            };
            compared += 1;
            let (wide, all) = tiles.far_column_tiles();
            // 46 % on this small sphere (every third tile on a seam between its base patches,
            // where a neighbour's frame may turn its far column away); 92 % with one claim of
            // all outputs in tile order.
            assert!(
                wide * 20 <= all * 11,
                "degree {degree}: {wide} of {all} tiles own a far column"
            );
        }
        assert!(compared >= 6, "tiles at {compared} degrees of 8");
    }

    #[test]
    fn wide_vectors_give_the_same_tiles() {
        if !tiles::wide_vectors() {
            eprintln!("no AVX2 here: the four-lane kernel is not compared");
            return;
        }
        let (sphere, points) = ico_quads(3);
        let single: Vec<f32> = points.iter().map(|&x| x as f32).collect();
        let mut compared = 0;
        for degree in 2..=9 {
            let refinement = at_level_3(&sphere, degree);
            let (scratch, cache) = (Scratch::default(), LimitCache::default());
            let limit = Limit {
                refinement: &refinement,
                scratch: &scratch,
                cache: &cache,
                rule: check(&refinement, true).unwrap(),
            };
            let st = stencils(&refinement, &cache).unwrap();
            // A sphere this small is extended whole at some degrees: no tiles there.
            let Some(tiles) = st.tiles.as_ref() else {
                continue;
            };
            compared += 1;
            let n = refinement.last_level().num_vertices;
            fn same<T: Scalar>(tiles: &Tiles, data: &[[T; 3]], normals: bool, n: usize) -> bool {
                let run = |wide: bool| {
                    // Initialised arrays: the items no tile writes stay zero in both runs.
                    let zero = MaybeUninit::new([T::default(); 3]);
                    let (mut p, mut q) = (vec![zero; n], vec![zero; n]);
                    let q_out = normals.then_some(&mut q[..]);
                    tiles.write_on(data, &mut p, q_out, wide).unwrap();
                    (p.iter().chain(&q))
                        // SAFETY: every item was initialised above.
                        .flat_map(|x| unsafe { x.assume_init() })
                        .map(|v| v.to_f64().to_bits())
                        .collect::<Vec<_>>()
                };
                run(false) == run(true)
            }
            let compact = refinement.compact(points.as_chunks::<3>().0);
            let (data, _) = limit.limit_data(&st, &compact).unwrap();
            let compact32 = refinement.compact(single.as_chunks::<3>().0);
            let (data32, _) = limit.limit_data(&st, &compact32).unwrap();
            for normals in [false, true] {
                assert!(same(tiles, &data, normals, n), "degree {degree} f64");
                assert!(same(tiles, &data32, normals, n), "degree {degree} f32");
            }
        }
        assert!(compared >= 6, "tiles at {compared} degrees of 8");
    }

    #[test]
    fn a_window_or_a_vertex_past_its_array_is_an_error_on_both_paths() {
        // The four-lane gather reads its items unchecked once the ids are checked against the
        // data, and the tiles write their vertices unchecked once they are checked against
        // both outputs: with data or an output too short for the level, both kernels must
        // refuse, not read or write past it.
        let (sphere, points) = ico_quads(3);
        let refinement = at_level_3(&sphere, 5);
        let cache = LimitCache::default();
        let st = stencils(&refinement, &cache).unwrap();
        let tiles = st.tiles.as_ref().expect("tiles on the sphere at degree 5");
        let n = refinement.last_level().num_vertices;
        let data = |len: usize| -> Vec<[f32; 3]> {
            (points.as_chunks::<3>().0.iter())
                .map(|p| p.map(|x| x as f32))
                .cycle()
                .take(len)
                .collect()
        };
        let (short, whole) = (data(n / 2), data(n));
        // (data, positions, normals; `None`: no normals asked for)
        let cases = [
            (&short, n, Some(n)),
            (&whole, n / 2, Some(n)),
            (&whole, n, Some(n / 2)),
            (&whole, n / 2, None),
        ];
        for wide in [false, tiles::wide_vectors()] {
            for (x, positions, normals) in cases {
                let mut p = vec![MaybeUninit::new([0.0f32; 3]); positions];
                let mut q = normals.map(|m| vec![MaybeUninit::new([0.0f32; 3]); m]);
                let result = tiles.write_on(x, &mut p, q.as_deref_mut(), wide);
                assert!(
                    matches!(result, Err(Error::Internal(_))),
                    "wide {wide}, data {}, outputs {positions} / {normals:?}: {result:?}",
                    x.len()
                );
            }
        }
    }

    #[test]
    fn local_extension_matches_the_whole_plan_extended() {
        let (grid, grid_points) = grid(5);
        let crease = grid
            .clone()
            .with_creases(&[(8, 14, f32::INFINITY)])
            .unwrap();
        let cases = [
            ("cube", cube().0, cube().1),
            ("grid", grid, grid_points.clone()),
            ("creased grid", crease, grid_points),
        ];
        let (mut engaged, mut stepwise) = (0, 0);
        for_each_refinement(&cases, 1..=2, |refinement, points, case| {
            let (st, _, dp, [n, m]) = local_and_whole(refinement, points, case);
            let dn = worst(&n, &m);
            engaged += usize::from(st.local.is_some());
            // A local extension made one level at a time (degrees 6 to 9).
            stepwise += usize::from(st.local.as_ref().is_some_and(|l| l.0.local.is_some()));
            assert!(st.extended.is_none(), "{case}: whole extension");
            assert!(
                dp < 1e-12 && dn < 1e-11,
                "{case}: positions {dp:e}, normals {dn:e}"
            );
        });
        assert!(
            engaged >= 40,
            "the local extension was used {engaged} times of 48"
        );
        assert!(
            stepwise >= 20,
            "the local extension was made level by level {stepwise} times of 24"
        );
    }

    /// Semi-sharp creases and corners take the local extension too: the vertices near them get
    /// partial levels until the features have become smooth, and their limits are those of the
    /// whole plan extended that far (to rounding, as in
    /// `local_extension_matches_the_whole_plan_extended`), with the same extra levels; in two
    /// stages, the fans clean at the first stage are those of the whole plan extended to it.
    #[test]
    fn semi_sharp_local_extension_matches_the_whole_plan_extended() {
        let (grid, grid_points) = grid(5);
        // Grid vertex (i, j) is 6i + j: a chain inside the grid (ends on one crease edge), a
        // row from boundary to boundary (corners where it meets the boundary), an infinitely
        // sharp crease going on as a semi-sharp one.
        let inside = |s: f32| [(13, 14, s), (14, 15, s), (15, 16, s)];
        let row = |s: f32| {
            [
                (18, 19, s),
                (19, 20, s),
                (20, 21, s),
                (21, 22, s),
                (22, 23, s),
            ]
        };
        let creased = |creases: &[(i64, i64, f32)]| grid.clone().with_creases(creases).unwrap();
        let (cube, cube_points) = cube();
        let top = |s: f32| [(4, 6, s), (6, 7, s), (7, 5, s), (5, 4, s)];
        let cases = [
            ("inside 0.5", creased(&inside(0.5)), &grid_points),
            ("row 1.5", creased(&row(1.5)), &grid_points),
            ("inside 2.5", creased(&inside(2.5)), &grid_points),
            ("row 2", creased(&row(2.0)), &grid_points),
            (
                "sharp then 1.5",
                creased(&[(8, 14, f32::INFINITY), (14, 15, 1.5)]),
                &grid_points,
            ),
            (
                "corners 1.5 inside, 0.5 on the boundary",
                grid.clone().with_corners(&[(14, 1.5), (2, 0.5)]).unwrap(),
                &grid_points,
            ),
            (
                "cube loop 2.5",
                cube.clone().with_creases(&top(2.5)).unwrap(),
                &cube_points,
            ),
        ];
        // Cases in two stages (some vertices clean before the features are smooth).
        let mut staged = 0;
        for_each_refinement(&cases, 1..=2, |refinement, points, case| {
            let (st, whole, dp, [mut n, mut m]) = local_and_whole(refinement, points, case);
            assert!(
                st.local.is_some() && st.extended.is_none(),
                "{case}: not local"
            );
            assert!(whole.extended.is_some());
            // Two stages: the corners of the first stage's fans against the whole
            // plan's fans at its level, the others against the whole plan extended.
            let mut dfans = 0.0;
            if let Some((first, _)) = st.local.as_ref().filter(|l| l.0.local.is_some()) {
                staged += 1;
                let m1 = clean_levels(refinement.options().degree);
                let fans = whole_fans(refinement, points, m1);
                let last = refinement.last_level();
                // A fan per side of a curve: its vertex once.
                let mut fan_vertices = first.fan_vertex.clone();
                fan_vertices.sort_unstable();
                fan_vertices.dedup();
                for &i in &fan_vertices {
                    let v = st.local_vertices[i as usize] as usize;
                    for &c in last.corners_of_vertex(v) {
                        let at = 3 * c as usize..3 * c as usize + 3;
                        dfans = worst(&n[at.clone()], &fans[at.clone()]).max(dfans);
                        n[at.clone()].fill(0.0);
                        m[at].fill(0.0);
                    }
                }
            }
            let dn = worst(&n, &m);
            assert!(
                dp < 1e-12 && dn < 1e-11 && dfans < 1e-11,
                "{case}: positions {dp:e}, normals {dn:e}, first-stage fans {dfans:e}"
            );
        });
        assert!(staged >= 20, "{staged} of 112 cases in two stages");
    }

    /// The masks of valence 4 fold for every degree, and the folded sums are those of the
    /// plain masks to rounding.
    #[test]
    fn valence_four_masks_fold() {
        for degree in 2..=9 {
            let m = cached_vertex_masks(degree, 4).unwrap();
            let fold = Folded::of(&m, degree % 2 == 1).expect("a folded mask");
            let joint: Vec<[f64; 4]> = (m.position.iter().zip(&m.tangents[0]))
                .zip(&m.tangents[1])
                .map(|((&p, &a), &b)| [p, a, b, 0.0])
                .collect();
            let data: Vec<[f64; 3]> = (0..joint.len())
                .map(|i| {
                    let x = i as f64;
                    [(0.7 * x).sin() + 3.0, (1.3 * x).cos() - 2.0, 0.1 * x]
                })
                .collect();
            let items: Vec<u32> = (0..joint.len() as u32).rev().collect();
            let plain = combine_joint(&data, items.iter().map(|&i| i as usize), &joint);
            let folded = fold.joint(&data, &items);
            assert_eq!(folded[0], fold.position(&data, &items));
            for (x, y) in plain.iter().flatten().zip(folded.iter().flatten()) {
                assert!((x - y).abs() <= 1e-13 * x.abs().max(1.0), "degree {degree}");
            }
        }
    }

    /// On a mesh whose unclean vertices are a small part (a large grid: its boundary and
    /// corners), the plan's own stencils take the local extension, also at level 1 where its
    /// seeds are a third of the level but its partial levels have at most 1 / LOCAL_SHARE of
    /// the whole extension's faces; on a small one (the cube, every vertex near an irregular
    /// one; a 12x12 grid at level 1, nearly all of it near its boundary), the whole plan is
    /// extended.
    #[test]
    fn the_local_extension_is_taken_where_it_is_a_small_part() {
        let taken = |cage: &Cage, degree: u32, levels: u32| {
            let options = Options {
                degree,
                levels,
                ..Options::default()
            };
            let r = Refinement::new(cage, &options).unwrap();
            let st = stencils(&r, &LimitCache::default()).unwrap();
            assert!(!(st.local.is_some() && st.extended.is_some()));
            let local = st.local.as_ref()?;
            let last = r.last_level();
            let seeds = local_seeds(last, degree, &st.local_vertices, st.extra_levels).unwrap();
            let whole = whole_extension_faces(last, st.extra_levels);
            assert!(LOCAL_SHARE as u64 * local_faces(local) <= whole);
            Some(seeds.len() as f64 / last.num_faces() as f64)
        };
        let (large, _) = grid(24);
        assert!(taken(&large, 4, 3).is_some());
        for degree in [4, 9] {
            let share = taken(&large, degree, 1);
            assert!(share.is_some_and(|s| s > 0.3), "degree {degree}: {share:?}");
            assert_eq!(taken(&grid(12).0, degree, 1), None, "degree {degree}");
        }
        assert_eq!(taken(&cube().0, 4, 3), None);
    }
}
