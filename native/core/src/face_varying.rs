//! Face-varying data (UVs, any channel count) subdivided by the scheme of the points, in
//! OpenSubdiv's six `FVarLinearInterpolation` modes (`docs/research/face-varying.md`).
//!
//! The values live on another cage, `M^fv`: the cage's faces and corners, its vertices the
//! distinct values (corners of one cage vertex with equal values share one), so a seam is a
//! boundary of it. This module builds `M^fv` as a [`Cage`] whose creases are the cage's curve
//! edges carried over and whose corners are the cage's corners carried to every value plus the
//! values the mode keeps (OpenSubdiv's `Vtr::FVarLevel` rules, mapped onto DESIGN.md §2 in
//! `face-varying.md` §5), then refines it with the plan's own options: the same
//! [`Refinement`], the same step primitive, every degree. Its level-`L` faces are the cage's
//! level-`L` faces in the same order, so output corner `k` of one is output corner `k` of the
//! other. `all` (linear, OpenSubdiv's `FVAR_LINEAR_ALL`) refines `M^fv` with the bilinear
//! scheme; limits of face-varying values are [`limit::positions`] on `M^fv`. Results come per
//! output corner or in the indexed form ([`SharedValues`]: the values at `M^fv`'s last-level
//! vertices and one kept index per output corner), one the other's expansion, bitwise.

use std::sync::{Arc, Mutex};

use crate::error::{Error, Result};
use crate::evaluate;
use crate::limit::{self, LimitCache};
use crate::memory;
use crate::mesh::{Cage, INFINITELY_SHARP};
use crate::options::{Boundary, Options, OutputKind, Rules};
use crate::output::OutputMesh;
use crate::parallel::{fill_rows, gather_indexed, in_pool};
use crate::refinement::Refinement;
use crate::scalar::Scalar;
use crate::scheme::{is_infinitely_sharp, is_semi_sharp, is_sharp};
use crate::step::{Final, Scratch};
use crate::topology::{Level, NONE};

/// How the boundaries of the face-varying mesh (seams and the mesh boundary) and its corners
/// behave: OpenSubdiv's `Sdc::Options::FVarLinearInterpolation` (Blender's `uv_smooth`, USD's
/// `faceVaryingLinearInterpolation`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum FaceVaryingMode {
    /// Smooth everywhere (`FVAR_LINEAR_NONE`; Blender's *All*): only the geometry's own corners.
    None,
    /// As `None`, and every value in one face is kept (`FVAR_LINEAR_CORNERS_ONLY`).
    CornersOnly,
    /// As `CornersOnly`, and junctions of 3 or more values are kept (`CORNERS_PLUS1`, USD's
    /// default).
    CornersPlus1,
    /// As `CornersPlus1`, and the concave side of a kept corner and seam ends are kept
    /// (`CORNERS_PLUS2`).
    CornersPlus2,
    /// Seams and the boundary stay linear, smooth inside (`FVAR_LINEAR_BOUNDARIES`; Blender's
    /// default *Keep Boundaries*).
    #[default]
    Boundaries,
    /// Linear everywhere (`FVAR_LINEAR_ALL`; Blender's *None*).
    All,
}

/// The face-varying topology of a set of values: how corners of one cage vertex share values.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Topology<'a> {
    /// Corners of one cage vertex whose values are equal (every channel) share one.
    ByValue,
    /// One index per cage corner (OpenSubdiv's face-varying index buffer, OBJ's `vt` indices):
    /// corners of one cage vertex with the same index share one value, whatever the values.
    Indexed(&'a [u32]),
}

/// Welds values given per cage corner (`channels` interleaved per corner) into the
/// face-varying topology `topology`. Returns the value of each corner (numbered vertex by
/// vertex, in order of first appearance) and the number of values.
fn weld<T: Scalar>(
    level0: &Level,
    values: &[T],
    channels: usize,
    topology: Topology,
) -> (Vec<u32>, usize) {
    let row = |c: u32| &values[c as usize * channels..(c as usize + 1) * channels];
    let equal = |a: u32, b: u32| match topology {
        Topology::ByValue => row(a).iter().zip(row(b)).all(|(x, y)| x == y),
        Topology::Indexed(index) => index[a as usize] == index[b as usize],
    };
    let mut value_of = vec![NONE; level0.num_corners()];
    let mut count = 0u32;
    for v in 0..level0.num_vertices {
        let corners = level0.corners_of_vertex(v);
        for (i, &c) in corners.iter().enumerate() {
            let same = corners[..i].iter().find(|&&d| equal(c, d));
            value_of[c as usize] = match same {
                Some(&d) => value_of[d as usize],
                None => {
                    count += 1;
                    count - 1
                }
            };
        }
    }
    (value_of, count as usize)
}

/// Values given OpenSubdiv's way (`channels` interleaved per value, and one index into them
/// per cage corner, checked) as values per cage corner.
pub(crate) fn per_corner_values<T: Scalar>(
    values: &[T],
    channels: usize,
    indices: &[u32],
) -> Result<Vec<T>> {
    let count = values.len() / channels.max(1);
    if let Some(c) = indices.iter().position(|&i| i as usize >= count) {
        return Err(Error::InvalidInput(format!(
            "face-varying index {} of corner {c} is out of range: there are {count} values",
            indices[c]
        )));
    }
    let mut out = memory::with_capacity(indices.len() * channels)?;
    for &i in indices {
        out.extend_from_slice(&values[i as usize * channels..][..channels]);
    }
    Ok(out)
}

/// For each corner of `level`, a representative of the fan of faces around its vertex it is
/// in (corners joined across the level's interior edges): a vertex whose corners have more
/// than one representative is a bowtie.
fn fans(level: &Level) -> Vec<u32> {
    let mut parent: Vec<u32> = (0..level.num_corners() as u32).collect();
    fn root(parent: &mut [u32], mut c: u32) -> u32 {
        while parent[c as usize] != c {
            parent[c as usize] = parent[parent[c as usize] as usize];
            c = parent[c as usize];
        }
        c
    }
    for &[c0, c1] in level.edge_corners() {
        if c1 == NONE {
            continue;
        }
        // The faces of c0 and c1 run the edge in opposite directions.
        for (a, b) in [
            (c0, level.next(c1 as usize) as u32),
            (c1, level.next(c0 as usize) as u32),
        ] {
            let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
            parent[ra.max(rb) as usize] = ra.min(rb);
        }
    }
    (0..parent.len() as u32)
        .map(|c| root(&mut parent, c))
        .collect()
}

/// Number of fans at each vertex of `level`.
fn fan_counts(level: &Level) -> Vec<u32> {
    let fan = fans(level);
    (0..level.num_vertices)
        .map(|v| {
            let corners = level.corners_of_vertex(v);
            corners
                .iter()
                .filter(|&&c| fan[c as usize] == c)
                .count()
                .max(1) as u32
        })
        .collect()
}

/// The face-varying mesh `M^fv` of a cage refinement's level `M_0` for the topology
/// `value_of` (the value of each corner, `num_values` values) and `mode`: its cage, with the
/// mode's corners (`face-varying.md` §1 and §5); `All` has none (it is refined bilinearly).
fn face_varying_cage(
    cage_refinement: &Refinement,
    value_of: &[u32],
    num_values: usize,
    mode: FaceVaryingMode,
) -> Result<Cage> {
    use FaceVaryingMode as M;
    let level0 = &cage_refinement.levels_as_built()[0];
    let features = cage_refinement.features();
    let sizes: Vec<i64> = (0..level0.num_faces())
        .map(|f| level0.face_corners(f).len() as i64)
        .collect();
    let indices: Vec<i64> = value_of.iter().map(|&x| x as i64).collect();
    let bare = Cage::from_indices(num_values, &sizes, &indices)?;
    if mode == M::All {
        // Refined bilinearly: no rule of the cage's features changes a linear interpolation.
        return Ok(bare);
    }
    let fv = Level::from_cage(&bare, num_values, value_of.to_vec())?;

    // Per value: its cage vertex, its corners (span), and what lies inside its span.
    let mut vertex_of = vec![NONE; num_values];
    let mut span = vec![0u32; num_values];
    for (c, &x) in value_of.iter().enumerate() {
        vertex_of[x as usize] = level0.corner_verts[c];
        span[x as usize] += 1;
    }
    let cage_edge = |fv_edge: usize| level0.corner_edges()[fv.edge_corners()[fv_edge][0] as usize];
    let mut inside_inf = vec![false; num_values];
    let mut inside_semi: Vec<Vec<f32>> = vec![Vec::new(); num_values];
    let nv = level0.num_vertices;
    let mut discontinuous = vec![false; nv];
    let mut on_fv_boundary = vec![false; num_values];
    let mut creases: Vec<(i64, i64, f32)> = Vec::new();
    for (e, &[a, b]) in fv.edge_verts().iter().enumerate() {
        let g = cage_edge(e) as usize;
        let s = features.edge_sharpness[g];
        if fv.is_boundary_edge(e) {
            on_fv_boundary[a as usize] = true;
            on_fv_boundary[b as usize] = true;
            if !level0.is_boundary_edge(g) {
                discontinuous[vertex_of[a as usize] as usize] = true;
                discontinuous[vertex_of[b as usize] as usize] = true;
            }
        } else if is_sharp(s) {
            creases.push((a as i64, b as i64, s));
            for x in [a, b] {
                if is_infinitely_sharp(s) {
                    inside_inf[x as usize] = true;
                } else if is_semi_sharp(s) {
                    inside_semi[x as usize].push(s);
                }
            }
        }
    }
    let mut values_at: Vec<Vec<u32>> = vec![Vec::new(); nv];
    for x in 0..num_values as u32 {
        values_at[vertex_of[x as usize] as usize].push(x);
    }
    let fv_fans = fan_counts(&fv);
    let cage_fans = fan_counts(level0);
    let disjoint = |x: u32| fv_fans[x as usize] > 1;
    let mut geo_boundary = vec![false; nv];
    for (e, &[a, b]) in level0.edge_verts().iter().enumerate() {
        if level0.is_boundary_edge(e) {
            geo_boundary[a as usize] = true;
            geo_boundary[b as usize] = true;
        }
    }
    let mut vertex_sharpness = vec![0.0f32; nv];
    for &(v, s) in &features.corners {
        vertex_sharpness[v as usize] = s;
    }

    // OpenSubdiv's flags (`sdc/options.h`, `FVarLevel::completeTopologyFromFaceValues`).
    let linear_boundaries = mode == M::Boundaries;
    let dependent_sharpness = matches!(mode, M::CornersPlus1 | M::CornersPlus2);
    let corners_are_sharp = mode != M::None;
    let sharpen_both_if_one_corner = mode == M::CornersPlus2;
    let sharpen_darts = sharpen_both_if_one_corner || linear_boundaries;

    let mut corners: Vec<(i64, f32)> = Vec::new();
    for v in 0..nv {
        let xs = &values_at[v];
        for &x in xs {
            if vertex_sharpness[v] > 0.0 {
                corners.push((x as i64, vertex_sharpness[v]));
            }
        }
        let non_manifold = cage_fans[v] > 1;
        let mismatched = discontinuous[v]
            || (non_manifold && xs.len() > 1)
            || (geo_boundary[v] && linear_boundaries)
            || (corners_are_sharp && xs.iter().any(|&x| span[x as usize] == 1));
        if !mismatched {
            continue;
        }
        let mut all_sharp = linear_boundaries
            || is_infinitely_sharp(vertex_sharpness[v])
            || non_manifold
            || (dependent_sharpness && xs.len() > 2)
            || (sharpen_darts && xs.len() == 1 && !geo_boundary[v]);
        let mut dependent: Option<(u32, u32)> = None;
        if dependent_sharpness && xs.len() == 2 {
            all_sharp |= xs.iter().any(|&x| inside_inf[x as usize] || disjoint(x));
            if sharpen_both_if_one_corner {
                all_sharp |= xs.iter().any(|&x| span[x as usize] == 1);
            }
            let semi = |x: u32| !inside_semi[x as usize].is_empty();
            if semi(xs[0]) != semi(xs[1]) {
                // (the value without semi-sharp edges, the one it depends on)
                dependent = Some(if semi(xs[0]) {
                    (xs[1], xs[0])
                } else {
                    (xs[0], xs[1])
                });
            }
        }
        for &x in xs {
            let i = x as usize;
            if disjoint(x) || all_sharp || inside_inf[i] || (span[i] == 1 && corners_are_sharp) {
                corners.push((x as i64, INFINITELY_SHARP));
            } else if !inside_semi[i].is_empty() || is_semi_sharp(vertex_sharpness[v]) {
                // Semi-sharp by its own edges and vertex: M^fv's rules do it as they are.
            } else if let Some((d, other)) = dependent.filter(|&(d, _)| d == x) {
                corners.push((
                    d as i64,
                    dependent_sharpness_of(&inside_semi[other as usize]),
                ));
            }
        }
    }
    bare.with_creases(&creases)?.with_corners(&corners)
}

/// The vertex sharpness that gives a value OpenSubdiv's dependent sharpness (the fractional
/// weight of the other value of its vertex, whose span holds semi-sharp edges of sharpness
/// `edges`): under uniform creasing that weight comes from the edges that become smooth last
/// (those of the largest `ceil`), the mean of their sharpness at that level
/// (`Crease::ComputeFractionalWeightAtVertex`), which a corner of their mean sharpness
/// reproduces level by level.
fn dependent_sharpness_of(edges: &[f32]) -> f32 {
    let last = edges.iter().fold(0.0f32, |m, &s| m.max(s.ceil()));
    let kept: Vec<f32> = edges.iter().copied().filter(|s| s.ceil() == last).collect();
    kept.iter().sum::<f32>() / kept.len() as f32
}

/// The face-varying mesh `M^fv` of `values` (one per cage corner, `channels` interleaved,
/// checked) in `mode` (not `All`) over `cage_refinement`, and the value of each of its
/// vertices (`channels` interleaved): for [`crate::adaptive`], which refines it on its own
/// partial levels.
pub(crate) fn face_varying_mesh<T: Scalar>(
    cage_refinement: &Refinement,
    values: &[T],
    channels: usize,
    mode: FaceVaryingMode,
    topology: Topology,
) -> Result<(Cage, Vec<T>)> {
    let level0 = &cage_refinement.levels_as_built()[0];
    let (value_of, num_values) = weld(level0, values, channels, topology);
    let cage = face_varying_cage(cage_refinement, &value_of, num_values, mode)?;
    let per_value = values_of(&first_corners(&value_of, num_values), values, channels);
    Ok((cage, per_value))
}

/// The first cage corner of each of the `num_values` face-varying values (`value_of` per
/// corner): where a value's data is read from.
fn first_corners(value_of: &[u32], num_values: usize) -> Vec<u32> {
    let mut first_corner = vec![NONE; num_values];
    for (c, &x) in value_of.iter().enumerate().rev() {
        first_corner[x as usize] = c as u32;
    }
    first_corner
}

/// The data (`channels` interleaved per cage corner) of each face-varying value, read at its
/// first corner.
fn values_of<T: Scalar>(first_corner: &[u32], values: &[T], channels: usize) -> Vec<T> {
    first_corner
        .iter()
        .flat_map(|&c| values[c as usize * channels..][..channels].iter().copied())
        .collect()
}

/// Face-varying values in OpenSubdiv's indexed form (USD's indexed primvar, OBJ's shared `vt`
/// lines): the refined values, one per vertex of the refined face-varying mesh `M^fv` that the
/// output uses, and one index into them per output face corner. The indices are topology: kept
/// in the plan and shared by every evaluation of the same face-varying topology and mode, so a
/// cached evaluation writes one value per face-varying vertex instead of one per face corner.
#[derive(Debug, Clone, PartialEq)]
pub struct SharedValues<T> {
    /// The values, `channels` interleaved per value.
    pub values: Vec<T>,
    /// The value of each output face corner (in the order of
    /// [`crate::Plan::output_face_vertices`]).
    pub indices: Arc<[u32]>,
}

impl<T: Scalar> SharedValues<T> {
    /// The values per output face corner (`channels` interleaved per corner), as
    /// [`crate::Plan::evaluate_face_varying`] gives them.
    pub fn per_corner(&self, channels: usize) -> Result<Vec<T>> {
        pick_rows(&self.values, channels, &self.indices)
    }
}

/// Where the output takes the values of `M^fv`'s last level in the indexed form: the vertices
/// its corners use, and each output corner's index among them.
#[derive(Debug)]
struct SharedTopology {
    /// The last level's vertices the output uses, in their order; `None` when it uses all.
    used: Option<Vec<u32>>,
    /// Index of each output corner into the used vertices.
    indices: Arc<[u32]>,
}

/// The refinement of one face-varying topology in one mode, with its evaluation buffers and
/// limit stencils.
#[derive(Debug)]
pub(crate) struct FaceVarying {
    mode: FaceVaryingMode,
    /// Value of each cage corner.
    value_of: Vec<u32>,
    /// One corner of each value (where its data is read).
    first_corner: Vec<u32>,
    refinement: Refinement,
    scratch: Scratch,
    limit: LimitCache,
    /// The indexed form's topology, built on first use.
    shared: Mutex<Option<Arc<SharedTopology>>>,
}

impl FaceVarying {
    /// Builds `M^fv` for `value_of` (`num_values` values) in `mode` over the cage refinement
    /// `cage_refinement`, with its options (primal output: face-varying values are given per
    /// corner of the drawing mesh and mapped to the dual mesh's corners after); `All` is
    /// refined with the bilinear scheme.
    fn new(
        cage_refinement: &Refinement,
        value_of: Vec<u32>,
        num_values: usize,
        mode: FaceVaryingMode,
    ) -> Result<FaceVarying> {
        let cage = face_varying_cage(cage_refinement, &value_of, num_values, mode)?;
        let mut options = Options {
            output: OutputKind::Primal,
            boundary: Boundary::EdgeOnly,
            ..*cage_refinement.options()
        };
        if mode == FaceVaryingMode::All {
            options.degree = 1;
            options.rules = Rules::Averaging;
        }
        let refinement = Refinement::new(&cage, &options)?;
        let first_corner = first_corners(&value_of, num_values);
        Ok(FaceVarying {
            mode,
            value_of,
            first_corner,
            refinement,
            scratch: Scratch::default(),
            limit: LimitCache::default(),
            shared: Mutex::new(None),
        })
    }

    /// Values per cage corner (interleaved) -> the values at `M^fv`'s last-level vertices that
    /// `index` picks, one row per index (`None`: every vertex, in order).
    fn evaluate<T: Scalar>(
        &self,
        values: &[T],
        channels: usize,
        limit: bool,
        index: Option<&[u32]>,
    ) -> Result<Vec<T>> {
        let per_value = values_of(&self.first_corner, values, channels);
        // `All` is bilinear: its refined values are on its limit.
        if !limit || self.mode == FaceVaryingMode::All {
            return match channels {
                1 => self.refined::<T, 1>(&per_value, index),
                2 => self.refined::<T, 2>(&per_value, index),
                3 => self.refined::<T, 3>(&per_value, index),
                4 => self.refined::<T, 4>(&per_value, index),
                _ => evaluate::in_groups_of_four(&per_value, channels, |group| {
                    self.refined::<T, 4>(&group, index)
                }),
            };
        }
        let at_vertices = limit::positions(
            &self.refinement,
            &self.scratch,
            &self.limit,
            &per_value,
            channels,
        )?;
        match index {
            None => Ok(at_vertices),
            Some(index) => pick_rows(&at_vertices, channels, index),
        }
    }

    /// The refined values (`N` channels interleaved per value) at `M^fv`'s last-level vertices
    /// that `index` picks, or at all of them (`None`: the run's own buffer is handed over). The
    /// values at its vertices stay in the kept buffers otherwise: only the picked rows are new
    /// memory (a new buffer is the kernel's zeroing of every page on its first touch).
    fn refined<T: Scalar, const N: usize>(
        &self,
        per_value: &[T],
        index: Option<&[u32]>,
    ) -> Result<Vec<T>> {
        let (points, _) = per_value.as_chunks::<N>();
        let compact = self.refinement.compact(points);
        let at_vertices = match evaluate::run(&self.refinement, &self.scratch, &compact, false)? {
            Final::Primal(at_vertices) => at_vertices,
            Final::Dual { .. } => {
                return Err(Error::Internal(
                    "a run asked for primal data returned dual data".into(),
                ))
            }
        };
        let Some(index) = index else {
            return Ok(at_vertices.into_flattened());
        };
        let out = gather_indexed(&at_vertices, index);
        self.scratch.give(at_vertices);
        Ok(out?.into_flattened())
    }

    /// The indexed form's topology for the plan's `output`, built on first use: the last
    /// level's vertices that the output's corners use (in their order) and each output
    /// corner's index among them.
    fn shared_topology(&self, output: &OutputMesh) -> Result<Arc<SharedTopology>> {
        let mut kept = self.shared.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(topology) = kept.as_ref() {
            return Ok(topology.clone());
        }
        let corner_verts = &self.refinement.last_level().corner_verts;
        let topology = match output.corner_sources() {
            None => SharedTopology {
                used: None,
                indices: memory::collect(corner_verts.iter().copied())?.into(),
            },
            Some(sources) => {
                let num_vertices = self.refinement.last_level().num_vertices;
                // 0 marks a used vertex until the pass below numbers it.
                let mut new_index = memory::filled(num_vertices, NONE)?;
                for &c in sources {
                    new_index[corner_verts[c as usize] as usize] = 0;
                }
                let mut used = memory::with_capacity(num_vertices)?;
                for (x, slot) in new_index.iter_mut().enumerate() {
                    if *slot == 0 {
                        *slot = used.len() as u32;
                        used.push(x as u32);
                    }
                }
                let indices = memory::collect(
                    sources
                        .iter()
                        .map(|&c| new_index[corner_verts[c as usize] as usize]),
                )?;
                SharedTopology {
                    used: (used.len() < num_vertices).then_some(used),
                    indices: indices.into(),
                }
            }
        };
        let topology = Arc::new(topology);
        *kept = Some(topology.clone());
        Ok(topology)
    }
}

/// The rows (`channels` interleaved) of `values` that `index` names, one per index.
fn pick_rows<T: Scalar>(values: &[T], channels: usize, index: &[u32]) -> Result<Vec<T>> {
    match channels {
        1 => rows_at::<T, 1>(values, index),
        2 => rows_at::<T, 2>(values, index),
        3 => rows_at::<T, 3>(values, index),
        4 => rows_at::<T, 4>(values, index),
        _ => {
            let mut out = memory::filled(index.len() * channels, T::default())?;
            fill_rows(&mut out, channels, |c, row| {
                let x = index[c] as usize;
                row.copy_from_slice(&values[x * channels..][..channels]);
            });
            Ok(out)
        }
    }
}

/// [`pick_rows`] of `N` channels: one gather of fixed-size rows into an unfilled buffer.
fn rows_at<T: Scalar, const N: usize>(values: &[T], index: &[u32]) -> Result<Vec<T>> {
    let (rows, _) = values.as_chunks::<N>();
    Ok(gather_indexed(rows, index)?.into_flattened())
}

/// Face-varying topologies kept per plan (the most recent ones).
const KEPT: usize = 4;

/// The face-varying part of a plan: the `M^fv` refinements of the topologies and modes asked
/// for, built on first use and kept (most recent first).
#[derive(Debug, Default)]
pub(crate) struct FaceVaryingCache(Mutex<Vec<Arc<FaceVarying>>>);

impl FaceVaryingCache {
    /// Frees the evaluation buffers of every kept refinement.
    pub(crate) fn release_buffers(&self) {
        for fv in self.0.lock().unwrap_or_else(|e| e.into_inner()).iter() {
            fv.scratch.clear();
        }
    }

    fn get(
        &self,
        refinement: &Refinement,
        value_of: Vec<u32>,
        num_values: usize,
        mode: FaceVaryingMode,
    ) -> Result<Arc<FaceVarying>> {
        {
            let mut kept = self.0.lock().unwrap_or_else(|e| e.into_inner());
            if let Some(i) = kept
                .iter()
                .position(|fv| fv.mode == mode && fv.value_of == value_of)
            {
                let fv = kept.remove(i);
                kept.insert(0, fv.clone());
                return Ok(fv);
            }
        }
        let fv = Arc::new(FaceVarying::new(refinement, value_of, num_values, mode)?);
        let mut kept = self.0.lock().unwrap_or_else(|e| e.into_inner());
        kept.insert(0, fv.clone());
        kept.truncate(KEPT);
        Ok(fv)
    }
}

/// Face-varying values (one per cage corner, `channels` interleaved, checked) with the
/// face-varying `topology` through the plan's refinement in `mode`: one value per output face
/// corner. `limit`: limit values (the same masks as limit positions; `All` refines `M^fv`
/// bilinearly, its refined values are its limit).
#[allow(clippy::too_many_arguments)]
pub(crate) fn evaluate<T: Scalar>(
    refinement: &Refinement,
    output: &OutputMesh,
    cache: &FaceVaryingCache,
    values: &[T],
    channels: usize,
    topology: Topology,
    mode: FaceVaryingMode,
    limit: bool,
) -> Result<Vec<T>> {
    in_pool(|| {
        let fv = kept(refinement, cache, values, channels, topology, mode, limit)?;
        let corners = &fv.refinement.last_level().corner_verts;
        let per_corner = fv.evaluate(values, channels, limit, Some(corners))?;
        output.face_varying(per_corner, channels)
    })
}

/// [`evaluate()`] in the indexed form: the values at the vertices of the refined face-varying
/// mesh that the output uses, and the index of each output corner (kept in the plan).
#[allow(clippy::too_many_arguments)]
pub(crate) fn evaluate_shared<T: Scalar>(
    refinement: &Refinement,
    output: &OutputMesh,
    cache: &FaceVaryingCache,
    values: &[T],
    channels: usize,
    topology: Topology,
    mode: FaceVaryingMode,
    limit: bool,
) -> Result<SharedValues<T>> {
    in_pool(|| {
        let fv = kept(refinement, cache, values, channels, topology, mode, limit)?;
        let shared = fv.shared_topology(output)?;
        Ok(SharedValues {
            values: fv.evaluate(values, channels, limit, shared.used.as_deref())?,
            indices: shared.indices.clone(),
        })
    })
}

/// The kept refinement of the face-varying mesh of `values` (welded by `topology`) in `mode`,
/// built on first use; limits are refused on the dual output.
fn kept<T: Scalar>(
    refinement: &Refinement,
    cache: &FaceVaryingCache,
    values: &[T],
    channels: usize,
    topology: Topology,
    mode: FaceVaryingMode,
    limit: bool,
) -> Result<Arc<FaceVarying>> {
    if limit && mode != FaceVaryingMode::All && refinement.options().output != OutputKind::Primal {
        return Err(Error::InvalidInput(
            "limit face-varying values are given at the drawing mesh's corners: use the primal \
             output"
                .into(),
        ));
    }
    let level0 = &refinement.levels_as_built()[0];
    let (value_of, num_values) = weld(level0, values, channels, topology);
    cache.get(refinement, value_of, num_values, mode)
}
