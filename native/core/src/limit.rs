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
//! handled by refining further: the plan is extended by `m` levels, which doubles their
//! distances `m` times while the old vertices keep their ids, until every one of them is clean.
//! Semi-sharp creases are refined past the level where they become smooth.
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
//! Everything topological (the extended refinement, the stencils, the fans) is built on first
//! use and kept in the plan ([`LimitCache`]), so re-evaluating a deformed cage costs one
//! evaluation of the extended refinement plus one small gather per vertex.
//!
//! Classic Catmull-Clark limit positions use OpenSubdiv's limit masks (`catmark_limit`).
//!
//! Everything here is at the vertices and corners of the whole last level: holes change no rule
//! (their points shape their neighbours), so the plan selects the drawing mesh's vertices and
//! corners from these values ([`crate::output::OutputMesh::vertex_values`]).

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use glam::DVec3;

use crate::analysis::{
    cached_vertex_masks, frame_items, neighbourhood_size, sector_frames, VertexMasks,
};
use crate::curves::LevelSharpness;
use crate::error::{Error, Result};
use crate::evaluate::{in_groups_of_four, run};
use crate::memory;
use crate::options::{Options, OutputKind};
use crate::parallel::gather_hinted;
use crate::refinement::Refinement;
use crate::scalar::{add, mad, scale, zero, Scalar, Value};
use crate::scheme::catmark::{
    dart_limit_mask, smooth_limit_weights, VertexRule, CREASE_LIMIT_WEIGHTS,
};
use crate::scheme::{cardinal_bspline, is_infinitely_sharp, is_semi_sharp, is_sharp, LimitMethod};
use crate::step::{Final, Scratch};
use crate::topology::{Level, NONE};

/// Extra levels tried at most beyond the first guess before giving up.
const MAX_EXTRA_LEVELS: u32 = 8;

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
}

/// Everything topological the limit needs, built once per plan (see the module documentation).
#[derive(Debug)]
pub(crate) struct Stencils {
    /// The refinement extended by `extra_levels` levels and its evaluation buffers (`None` when
    /// the plan's own refinement is enough).
    extended: Option<(Refinement, Scratch)>,
    /// Levels added to the plan.
    extra_levels: u32,
    /// Mask of each output vertex.
    masks_of: Vec<LimitMask>,
    /// Offsets into `items` per output vertex.
    offsets: Vec<u32>,
    /// Indices into the data the stencils read (see `Limit::limit_data`).
    items: Vec<u32>,
    /// Interior masks by valence.
    masks: Vec<Arc<VertexMasks>>,
    /// The 1-D position mask along curves (symmetric, centred).
    curve_mask: Vec<f64>,
    /// Fan of each output face corner at a curve vertex or corner (index into `fan_offsets`),
    /// `NONE` elsewhere.
    corner_fan: Vec<u32>,
    /// Offsets into `fan_items` per fan, and whether the fan closes on itself.
    fan_offsets: Vec<u32>,
    fan_closed: Vec<bool>,
    /// The output vertex each fan turns around.
    fan_vertex: Vec<u32>,
    /// Data indices of each fan's points, counter-clockwise around its vertex.
    fan_items: Vec<u32>,
}

/// Builds the stencils with `refinement` (the plan's or an extended one) for the first
/// `outputs` vertices of its last level, the output corners `output_corners` (corner `c` of
/// the output is corner `c * 4^extra` of the last level). `None` when some vertex is not clean.
fn build_stencils(
    refinement: &Refinement,
    outputs: usize,
    output_corners: usize,
    extra: u32,
) -> Result<Option<Stencils>> {
    let degree = refinement.options().degree;
    let primal = degree % 2 == 1;
    let n = neighbourhood_size(degree);
    // The last level's edge and vertex -> corner tables, fallibly (`levels()` would panic).
    refinement.complete_levels()?;
    let last = refinement.levels().last().expect("a level");
    let curves = refinement.curve_networks().last().expect("a step");
    let nf = last.num_faces();
    let nc = curves.edges().len();
    // Data layout (see `limit_data`): odd degrees, the vertices; even degrees, the faces,
    // then the last step's curve edges, then the cage points (for corners).
    let cage_item = |v: usize| if primal { v } else { nf + nc + v };
    // Curve vertex of each vertex id (index into the step's curve vertices).
    let curve_of = |v: usize| curves.vertex_index(v as u32).map(|i| i as usize);
    if curves.vertices().iter().any(|cv| cv.weight < 1.0) {
        return Ok(None);
    }
    let curve_index = |e: u32| curves.edge_index(e);
    let is_curve_edge = |e: u32| curve_index(e).is_some();

    // 1-D masks: odd degrees on curve vertices at offsets -N..=N, even degrees on curve edges
    // at offsets +-1/2 .. +-(N - 1/2).
    let curve_mask: Vec<f64> = if primal {
        (-(n as i64)..=n as i64)
            .map(|i| cardinal_bspline(degree, i as f64))
            .collect()
    } else {
        (0..2 * n)
            .map(|i| cardinal_bspline(degree, i as f64 - n as f64 + 0.5))
            .collect()
    };

    let mut valences: Vec<usize> = Vec::new();
    // Per vertex: rule and items, or None when not clean.
    let stencil_of = |v: usize| -> Option<(LimitMask, Vec<u32>)> {
        if let Some(i) = curve_of(v) {
            let cv = &curves.vertices()[i];
            let Some([a, _]) = cv.edges else {
                return Some((LimitMask::Corner, vec![cage_item(cv.pin as usize) as u32]));
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
                    edge = if x as usize == edge { y } else { x } as usize;
                    at = next;
                }
                Some(out)
            };
            let [a, b] = [a, cv.edges.expect("a curve vertex")[1]];
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
        let mut ids: Vec<usize> = Vec::with_capacity(ring.len());
        for &(label, w) in &ring {
            if label != (0, 0, 0) && (last.corners_of_vertex(w).len() != 4 || curve_of(w).is_some())
            {
                return None;
            }
            ids.push(w);
        }
        ids.sort_unstable();
        ids.dedup();
        if ids.len() != ring.len() {
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
    // The tables are allocated fallibly; the per-vertex stencils are gathered a block of
    // vertices at a time, so that what is held besides the tables stays small.
    const BLOCK: usize = 1 << 16;
    let mut masks_of = memory::with_capacity(outputs)?;
    let mut offsets = memory::with_capacity(outputs + 1)?;
    let mut items: Vec<u32> = Vec::new();
    offsets.push(0u32);
    for start in (0..outputs).step_by(BLOCK) {
        let end = (start + BLOCK).min(outputs);
        let block = gather_hinted(end - start, |i| stencil_of(start + i))?;
        if block.iter().any(Option::is_none) {
            return Ok(None);
        }
        let size: usize = block.iter().flatten().map(|(_, its)| its.len()).sum();
        if items.capacity() - items.len() < size {
            // Doubling, as `extend` would grow it.
            let more = size.max(items.len());
            memory::reserve(&mut items, more)?;
        }
        for (mask, its) in block.into_iter().flatten() {
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
            items.extend(its);
            offsets.push(items.len() as u32);
        }
    }
    let masks = valences
        .iter()
        .map(|&k| cached_vertex_masks(degree, k))
        .collect::<Result<Vec<_>>>()?;

    // Fans at curve vertices and corners, one per output corner there.
    let spread = 4usize.pow(extra);
    let on_curve = |c: usize| {
        let v = last.corner_verts[c * spread] as usize;
        let fan = matches!(
            masks_of[v],
            LimitMask::Curve | LimitMask::Corner | LimitMask::Valence2(_)
        );
        (v < outputs && fan).then_some(v)
    };
    // At most one fan per such corner, and at most three items per corner of a fan (its
    // outline, or its faces and two curve edges).
    let fan_corners = (0..output_corners)
        .filter(|&c| on_curve(c).is_some())
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
    for (c, fan) in corner_fan.iter_mut().enumerate() {
        let d = c * spread;
        let Some(v) = on_curve(c) else {
            continue;
        };
        // Clockwise to the fan's start: across outgoing edges until a curve edge.
        let mut start = d;
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
                break;
            }
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
                    let across = last
                        .opposite(last.corner_edges()[y] as usize, y)
                        .expect("a clean neighbourhood");
                    fan_items.push(last.face_of(across) as u32);
                }
            }
        } else {
            let curve_item = |e: u32| nf as u32 + curve_index(e).expect("a curve edge of the step");
            if !closed {
                fan_items.push(curve_item(last.corner_edges()[start]));
            }
            fan_items.extend(corners.iter().map(|&x| last.face_of(x) as u32));
            if !closed {
                let x = *corners.last().expect("a corner");
                fan_items.push(curve_item(last.corner_edges()[last.prev(x)]));
            }
        }
        let id = fan_closed.len() as u32;
        fan_closed.push(closed);
        fan_vertex.push(v as u32);
        fan_offsets.push(fan_items.len() as u32);
        fan_of_start.insert(start, id);
        *fan = id;
    }
    Ok(Some(Stencils {
        extended: None,
        extra_levels: extra,
        masks_of,
        offsets,
        items,
        masks,
        curve_mask,
        corner_fan,
        fan_offsets,
        fan_closed,
        fan_vertex,
        fan_items,
    }))
}

/// The limit's part of a plan: the stencils, built on first use and kept.
#[derive(Debug, Default)]
pub(crate) struct LimitCache(Mutex<Option<Arc<Stencils>>>);

/// The stencils of `refinement`, built on first use (see the module documentation).
fn stencils(refinement: &Refinement, cache: &LimitCache) -> Result<Arc<Stencils>> {
    let mut kept = cache.0.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(st) = kept.as_ref() {
        return Ok(st.clone());
    }
    let options = *refinement.options();
    let levels = options.levels;
    let n = neighbourhood_size(options.degree) as u32;
    // Semi-sharp features must have become smooth by the last level (corners on isolated
    // vertices are no features: they have no place in the surface).
    let cage = refinement.cage();
    let finite = cage
        .creases()
        .iter()
        .map(|c| c.sharpness)
        .chain(refinement.features().corners.iter().map(|c| c.1))
        .filter(|&s| is_semi_sharp(s))
        .fold(0.0f32, f32::max);
    let first = (finite.ceil() as u32)
        .saturating_sub(levels)
        .max(u32::from(levels == 0));
    // Enough doubling to put N rings between a vertex and its nearest neighbour.
    let clean = (1..).find(|&m| (1u32 << m) > n).unwrap_or(1);
    let mut candidates = vec![first, first.max(clean)];
    candidates.extend((1..=MAX_EXTRA_LEVELS).map(|i| first.max(clean) + i));
    candidates.dedup();
    let outputs = refinement.levels().last().expect("a level").num_vertices;
    let output_corners = refinement.levels().last().expect("a level").num_corners();
    for m in candidates {
        let built = if m == 0 {
            build_stencils(refinement, outputs, output_corners, 0)?
        } else {
            let extended = Refinement::new(
                cage,
                &Options {
                    levels: levels + m,
                    output: OutputKind::Primal,
                    ..options
                },
            )?;
            build_stencils(&extended, outputs, output_corners, m)?.map(|mut st| {
                st.extended = Some((extended, Scratch::default()));
                st
            })
        };
        if let Some(st) = built {
            let st = Arc::new(st);
            *kept = Some(st.clone());
            return Ok(st);
        }
    }
    Err(Error::Internal(format!(
        "no clean neighbourhood for the limit within {MAX_EXTRA_LEVELS} extra levels"
    )))
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
            1 => limit.of::<T, 1>(group, false)?.0,
            2 => limit.of::<T, 2>(group, false)?.0,
            3 => limit.of::<T, 3>(group, false)?.0,
            _ => limit.of::<T, 4>(group, false)?.0,
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
) -> Result<(Vec<T>, Vec<T>)> {
    let rule = check(refinement, true)?;
    let limit = Limit {
        refinement,
        scratch,
        cache,
        rule,
    };
    let (positions, normals) = limit.of::<T, 3>(points, true)?;
    Ok((positions, normals.expect("normals were asked for")))
}

/// One limit request on a plan's refinement.
struct Limit<'a> {
    refinement: &'a Refinement,
    scratch: &'a Scratch,
    cache: &'a LimitCache,
    rule: LimitMethod,
}

impl Limit<'_> {
    /// Limit positions (and normals) of `N`-channel values.
    fn of<T: Scalar, const N: usize>(
        &self,
        values: &[T],
        normals: bool,
    ) -> Result<(Vec<T>, Option<Vec<T>>)> {
        let r = self.refinement;
        let (points, _) = values.as_chunks::<N>();
        let compact = r.compact(points);
        match self.rule {
            LimitMethod::CatmullClark => {
                let Final::Primal(last) = run(r, self.scratch, &compact, false)? else {
                    unreachable!("primal classic run")
                };
                r.complete_levels()?;
                let j = r.levels().len() - 1;
                let sharpness = r.sharpness(j).expect("Catmull-Clark levels have sharpness");
                let out = catmark_limit(&r.levels()[j], sharpness, &last)?;
                Ok((out.into_flattened(), None))
            }
            LimitMethod::Interpolating => {
                // Bilinear: the surface interpolates the refined points; each face's patch has
                // its own normal at its corners.
                let Final::Primal(last) = run(r, self.scratch, &compact, false)? else {
                    unreachable!("degree 1 is primal")
                };
                let normals = match normals {
                    true => Some(face_corner_normals(r.last_level(), &last)?),
                    false => None,
                };
                Ok((last.into_flattened(), normals))
            }
            LimitMethod::Eigen => {
                let st = stencils(r, self.cache)?;
                let data = self.limit_data(&st, &compact)?;
                let positions: Vec<[T; N]> = gather_hinted(st.masks_of.len(), |v| {
                    let items = &st.items[st.offsets[v] as usize..st.offsets[v + 1] as usize];
                    let weights: &[f64] = match st.masks_of[v] {
                        LimitMask::Interior(m) | LimitMask::Valence2(m) => {
                            &st.masks[m as usize].position
                        }
                        LimitMask::Curve => &st.curve_mask,
                        LimitMask::Corner => return data[items[0] as usize],
                    };
                    combine(&data, items, weights)
                })?;
                let normals = match normals {
                    true => Some(self.stencil_normals(&st, &data, &positions)?),
                    false => None,
                };
                Ok((positions.into_flattened(), normals))
            }
        }
    }

    /// The data the stencils read: the last level's vertex values (odd degrees), or its face
    /// values, then the last step's curve-edge values, then the cage points (even degrees).
    fn limit_data<T: Scalar, const N: usize>(
        &self,
        st: &Stencils,
        compact: &[[T; N]],
    ) -> Result<Vec<[T; N]>> {
        let (refinement, scratch) = match &st.extended {
            Some((r, s)) => (r, s),
            None => (self.refinement, self.scratch),
        };
        let even = self.refinement.options().degree.is_multiple_of(2);
        Ok(match run(refinement, scratch, compact, even)? {
            Final::Primal(vertices) => vertices,
            Final::Dual {
                mut faces,
                curve_edges,
            } => {
                memory::reserve(&mut faces, curve_edges.len() + compact.len())?;
                faces.extend(curve_edges);
                faces.extend_from_slice(compact);
                faces
            }
        })
    }

    /// Unit normals per output corner from the stencils (see [`surface`]).
    fn stencil_normals<T: Scalar, const N: usize>(
        &self,
        st: &Stencils,
        data: &[[T; N]],
        positions: &[[T; N]],
    ) -> Result<Vec<T>> {
        let at = |x: &[T; N]| DVec3::new(x[0].to_f64(), x[1].to_f64(), x[2].to_f64());
        let vertex_normals: Vec<DVec3> = gather_hinted(st.masks_of.len(), |v| {
            let LimitMask::Interior(m) = st.masks_of[v] else {
                return DVec3::ZERO;
            };
            let items = &st.items[st.offsets[v] as usize..st.offsets[v + 1] as usize];
            let [a, b] = &st.masks[m as usize].tangents;
            let (a, b) = (at(&combine(data, items, a)), at(&combine(data, items, b)));
            a.cross(b).normalize_or_zero()
        })?;
        let fan_normals: Vec<DVec3> = gather_hinted(st.fan_closed.len(), |f| {
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
        })?;
        let corners = &self.refinement.last_level().corner_verts;
        let mut out = memory::with_capacity(3 * corners.len())?;
        for (c, &v) in corners.iter().enumerate() {
            let n = match st.corner_fan[c] {
                NONE => vertex_normals[v as usize],
                f => fan_normals[f as usize],
            };
            out.extend(n.to_array().map(T::from_f64));
        }
        Ok(out)
    }
}

/// Unit normals of each face's bilinear patch at its corners, face after face.
fn face_corner_normals<T: Scalar, const N: usize>(
    level: &Level,
    points: &[[T; N]],
) -> Result<Vec<T>> {
    let at = |v: u32| {
        let x = &points[v as usize];
        DVec3::new(x[0].to_f64(), x[1].to_f64(), x[2].to_f64())
    };
    let mut out = memory::with_capacity(3 * level.num_corners())?;
    for f in 0..level.num_faces() {
        let face = &level.corner_verts[level.face_corners(f)];
        let k = face.len();
        for i in 0..k {
            let p = at(face[i]);
            let (next, prev) = (at(face[(i + 1) % k]) - p, at(face[(i + k - 1) % k]) - p);
            out.extend(
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
    assert!(level.is_quads(), "limit positions need a quad level");
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
