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
//! eigenvectors of the boundary subdivision matrices). Degree 1 is bilinear: positions are the
//! refined points, normals those of each face's bilinear patch at its corner.
//!
//! Everything topological (the extended plan, the stencils, the fans) is built on first use and
//! kept in the plan, so re-evaluating a deformed cage costs one evaluation of the extended plan
//! plus one small gather per vertex.

use std::borrow::Cow;
use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

use glam::DVec3;
use nalgebra::DMatrix;

use crate::analysis::{self, frame_items, neighbourhood_size, sector_frames, C64};
use crate::error::{Error, Result};
use crate::evaluate::{gather, in_groups_of_four, Final, Scalar};
use crate::mesh::check_values;
use crate::plan::{Options, OutputKind, Plan, Rules};
use crate::topology::{Level, NONE};
use crate::INFINITELY_SHARP;

/// Extra levels tried at most beyond the first guess before giving up.
const MAX_EXTRA_LEVELS: u32 = 8;

/// The centred cardinal B-spline of degree `n` (support `[-(n+1)/2, (n+1)/2]`, integral 1) at
/// `t`, by the Cox–de Boor recursion (stable for every degree).
pub fn cardinal_bspline(n: u32, t: f64) -> f64 {
    // x in the support [0, n+1] of the uncentred spline; values[i] holds N_d(x - i).
    let x = t + (n as f64 + 1.0) / 2.0;
    let n = n as usize;
    let mut values: Vec<f64> = (0..=n)
        .map(|i| {
            let y = x - i as f64;
            if (0.0..1.0).contains(&y) {
                1.0
            } else {
                0.0
            }
        })
        .collect();
    for d in 1..=n {
        for i in 0..=n - d {
            let y = x - i as f64;
            values[i] = (y * values[i] + (d as f64 + 1.0 - y) * values[i + 1]) / d as f64;
        }
    }
    values[0]
}

/// Derivative of [`cardinal_bspline`] with respect to `t` (`n >= 1`).
pub fn cardinal_bspline_derivative(n: u32, t: f64) -> f64 {
    cardinal_bspline(n - 1, t + 0.5) - cardinal_bspline(n - 1, t - 0.5)
}

/// Limit masks of one degree at an interior vertex of one valence, over the minimal
/// neighbourhood in the order of [`crate::analysis`]'s neighbourhoods with `rings = N`.
#[derive(Debug, Clone)]
pub struct VertexMasks {
    /// Degree of the scheme.
    pub degree: u32,
    /// Valence of the vertex.
    pub valence: usize,
    /// Subdominant eigenvalue (the tangents' eigenvalue).
    pub lambda1: f64,
    /// Limit position mask (dominant left eigenvector, summing to 1).
    pub position: Vec<f64>,
    /// Two tangent masks (subdominant left eigenvectors), ordered so that their cross product
    /// points to the side the faces' orientation makes the outside.
    pub tangents: [Vec<f64>; 2],
}

/// The planar, counter-clockwise embedding of a polar neighbourhood item: vertex `(s, i, j)`
/// at `i e(s) + j e(s+1)`, face `(s, i, j)` at its centre, `e(s)` the unit vector at `2 pi s/k`.
fn planar(label: (usize, usize, usize), valence: usize, primal: bool) -> [f64; 2] {
    let (s, i, j) = label;
    let e = |s: usize| {
        let a = 2.0 * std::f64::consts::PI * (s % valence) as f64 / valence as f64;
        [a.cos(), a.sin()]
    };
    let (a, b) = (e(s), e(s + 1));
    let off = if primal { 0.0 } else { 0.5 };
    let (x, y) = (i as f64 + off, j as f64 + off);
    [x * a[0] + y * b[0], x * a[1] + y * b[1]]
}

/// Computes the masks of `degree` at valence `valence` from the engine's subdivision matrix
/// (its Fourier blocks 0 and 1). Every eigenvector is checked against the full matrix.
pub fn vertex_masks(degree: u32, valence: usize) -> Result<VertexMasks> {
    let internal = |what: &str| {
        Error::Internal(format!(
            "limit masks of degree {degree} at valence {valence}: {what}"
        ))
    };
    let sm = analysis::subdivision_matrix(degree, valence)?;
    let primal = sm.is_primal();
    let blocks = sm.fourier_blocks();
    let (k, p) = (valence, sm.sector_size());
    let w =
        |e: usize| C64::from_polar(1.0, -2.0 * std::f64::consts::PI * (e % k) as f64 / k as f64);
    // Left eigenvector of block m for eigenvalue `lambda`, spread over the sectors:
    // l(s, a) = w^(-s m) u_a with u^T B_m = lambda u^T (see the derivation in the tests).
    let left = |m: usize, lambda: C64| -> Result<(C64, Vec<C64>)> {
        let bt = blocks[m].matrix.transpose();
        let (value, u) =
            analysis::eigenvector(&bt, lambda).ok_or_else(|| internal("no eigenvector"))?;
        let off = usize::from(primal && m == 0);
        let mut l = Vec::with_capacity(sm.labels.len());
        if primal {
            l.push(if m == 0 { u[0] } else { C64::from(0.0) });
        }
        for s in 0..k {
            for a in 0..p {
                l.push(w(s * m) * u[off + a]);
            }
        }
        Ok((value, l))
    };
    let residual = |l: &[f64], lambda: f64| -> f64 {
        let row = DMatrix::from_row_slice(1, l.len(), l);
        let scale = l.iter().map(|x| x.abs()).fold(0.0, f64::max);
        ((&row * &sm.matrix) - &row * lambda).amax() / scale
    };

    // Dominant: mode 0, eigenvalue 1; the centre weighs u_0 against u_a / k per sector item
    // (mode 0's centre row sums over the sectors), fixed by checking the residual.
    let (_, dominant) = left(0, C64::from(1.0))?;
    let mut position: Vec<f64> = dominant.iter().map(|z| z.re).collect();
    if primal {
        for x in &mut position[1..] {
            *x /= k as f64;
        }
    }
    let total: f64 = position.iter().sum();
    if total.abs() < 1e-12 {
        return Err(internal("the dominant eigenvector sums to zero"));
    }
    position.iter_mut().for_each(|x| *x /= total);
    if residual(&position, 1.0) > 1e-9 {
        return Err(internal("the dominant eigenvector does not check"));
    }

    // Subdominant: the largest eigenvalue of mode 1 (real for these schemes).
    let spectrum = analysis::complex_eigenvalues(&blocks[1 % k].matrix)
        .ok_or_else(|| internal("the eigenvalue iteration did not converge"))?;
    let (lambda1, sub) = left(1 % k, spectrum[0])?;
    if lambda1.im.abs() > 1e-9 {
        return Err(internal("the subdominant eigenvalue is not real"));
    }
    let lambda1 = lambda1.re;
    let mut t0: Vec<f64> = sub.iter().map(|z| z.re).collect();
    let mut t1: Vec<f64> = sub.iter().map(|z| z.im).collect();
    for t in [&t0, &t1] {
        if residual(t, lambda1) > 1e-8 {
            return Err(internal("a subdominant eigenvector does not check"));
        }
    }
    // Orientation: on the planar counter-clockwise embedding the normal must point up.
    let tangent = |mask: &[f64]| {
        mask.iter()
            .zip(&sm.labels)
            .fold([0.0; 2], |acc, (&m, &label)| {
                let q = planar(label, k, primal);
                [acc[0] + m * q[0], acc[1] + m * q[1]]
            })
    };
    let (a, b) = (tangent(&t0), tangent(&t1));
    let cross = a[0] * b[1] - a[1] * b[0];
    let scale = (a[0].hypot(a[1]) * b[0].hypot(b[1])).max(1e-300);
    if cross.abs() < 1e-6 * scale {
        return Err(internal("the tangent masks are degenerate"));
    }
    if cross < 0.0 {
        t1.iter_mut().for_each(|x| *x = -*x);
    }
    // Normalise the tangents to unit planar length (the scale carries no meaning).
    let (la, lb) = (a[0].hypot(a[1]), b[0].hypot(b[1]));
    t0.iter_mut().for_each(|x| *x /= la);
    t1.iter_mut().for_each(|x| *x /= lb);

    // Restrict to the minimal neighbourhood; what lies outside must vanish.
    let n = neighbourhood_size(degree);
    let minimal = |&(_, i, j): &(usize, usize, usize)| {
        if primal {
            i <= n && j <= n
        } else {
            i < n && j < n
        }
    };
    let mut restricted = [Vec::new(), Vec::new(), Vec::new()];
    for (idx, label) in sm.labels.iter().enumerate() {
        let masks = [&position, &t0, &t1];
        if minimal(label) {
            for (r, m) in restricted.iter_mut().zip(masks) {
                r.push(m[idx]);
            }
        } else if masks.iter().any(|m| m[idx].abs() > 1e-9) {
            return Err(internal("a mask reaches beyond the minimal neighbourhood"));
        }
    }
    let [position, t0, t1] = restricted;
    Ok(VertexMasks {
        degree,
        valence,
        lambda1,
        position,
        tangents: [t0, t1],
    })
}

/// [`vertex_masks`], computed once per `(degree, valence)` for the whole process.
fn cached_masks(degree: u32, valence: usize) -> Result<Arc<VertexMasks>> {
    type Cache = Mutex<HashMap<(u32, usize), Arc<VertexMasks>>>;
    static CACHE: OnceLock<Cache> = OnceLock::new();
    let cache = CACHE.get_or_init(Default::default);
    if let Some(m) = cache
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .get(&(degree, valence))
    {
        return Ok(m.clone());
    }
    let masks = Arc::new(vertex_masks(degree, valence)?);
    cache
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .insert((degree, valence), masks.clone());
    Ok(masks)
}

/// How the limit at one output vertex is computed.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Rule {
    /// An interior vertex: masks of its valence (index into `Stencils::masks`).
    Interior(u32),
    /// A curve vertex: the 1-D B-spline mask along the curve.
    Curve,
    /// A corner: its cage point.
    Corner,
}

/// Everything topological the limit needs, built once per plan (see the module documentation).
#[derive(Debug)]
pub(crate) struct Stencils {
    /// The plan extended by `extra_levels` levels (`None` when the plan itself is enough).
    extended: Option<Plan>,
    /// Levels added to the plan.
    extra_levels: u32,
    /// Rule of each output vertex.
    rules: Vec<Rule>,
    /// Offsets into `items` per output vertex.
    offsets: Vec<u32>,
    /// Indices into the data the stencils read (see [`Plan::limit_data`]).
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

/// The corner on the other side of edge `e` from corner `c` (`None` on a boundary).
fn across(level: &Level, e: usize, c: usize) -> Option<usize> {
    let [a, b] = level.edge_corners()[e];
    let other = if a as usize == c { b } else { a };
    (other != NONE).then_some(other as usize)
}

/// Builds the stencils with the plan `plan` (the user's or an extended one) for the first
/// `outputs` vertices of its last level, the output corners `output_corners` (corner `c` of
/// the output is corner `c * 4^extra` of the last level). `None` when some vertex is not clean.
fn build_stencils(
    plan: &Plan,
    outputs: usize,
    output_corners: usize,
    extra: u32,
) -> Result<Option<Stencils>> {
    let degree = plan.options().degree;
    let primal = degree % 2 == 1;
    let n = neighbourhood_size(degree);
    let last = plan.levels().last().expect("a level");
    let step = plan.steps().last().expect("a step");
    let nf = last.num_faces();
    let nc = step.curve_edges.len();
    // Data layout (see Plan::limit_data): odd degrees, the vertices; even degrees, the faces,
    // then the last step's curve edges, then the cage points (for corners).
    let cage_item = |v: usize| if primal { v } else { nf + nc + v };
    // Curve vertex of each vertex id (index into the step's curve vertices).
    let curve_of = |v: usize| {
        step.curve_vertices
            .binary_search_by_key(&(v as u32), |cv| cv.vertex)
            .ok()
    };
    if step.curve_vertices.iter().any(|cv| cv.weight < 1.0) {
        return Ok(None);
    }
    // (edge id, index in the step's curve edges), sorted by edge id.
    let mut curve_edge_ids: Vec<(u32, u32)> = (step.curve_edges.iter())
        .enumerate()
        .map(|(i, e)| (e.edge, i as u32))
        .collect();
    curve_edge_ids.sort_unstable();
    let curve_index = |e: u32| {
        curve_edge_ids
            .binary_search_by_key(&e, |&(edge, _)| edge)
            .ok()
            .map(|at| curve_edge_ids[at].1)
    };
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
    let per_vertex: Vec<Option<(Rule, Vec<u32>)>> = gather(outputs, |v| {
        if let Some(i) = curve_of(v) {
            let cv = &step.curve_vertices[i];
            let Some([a, _]) = cv.edges else {
                return Some((Rule::Corner, vec![cage_item(v) as u32]));
            };
            // Walk the polyline both ways: curve vertices (odd) or edges (even).
            let walk = |first_edge: u32, from: usize, count: usize| -> Option<Vec<u32>> {
                let mut out = Vec::with_capacity(count);
                let (mut edge, mut at) = (first_edge as usize, from);
                for _ in 0..count {
                    let ends = step.curve_edges[edge].ends;
                    let next = if ends[0] as usize == at {
                        ends[1]
                    } else {
                        ends[0]
                    } as usize;
                    if primal {
                        out.push(step.curve_vertices[next].vertex);
                    } else {
                        out.push((nf + edge) as u32);
                    }
                    let [x, y] = step.curve_vertices[next].edges?;
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
            return (sorted.len() == items.len()).then_some((Rule::Curve, items));
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
        Some((
            Rule::Interior(valence as u32),
            items.iter().map(|&(_, i)| i as u32).collect(),
        ))
    });
    if per_vertex.iter().any(Option::is_none) {
        return Ok(None);
    }
    let mut rules = Vec::with_capacity(outputs);
    let mut offsets = Vec::with_capacity(outputs + 1);
    let mut items = Vec::new();
    offsets.push(0u32);
    for (rule, its) in per_vertex.into_iter().flatten() {
        let rule = match rule {
            Rule::Interior(k) => {
                let at = match valences.iter().position(|&x| x == k as usize) {
                    Some(at) => at,
                    None => {
                        valences.push(k as usize);
                        valences.len() - 1
                    }
                };
                Rule::Interior(at as u32)
            }
            r => r,
        };
        rules.push(rule);
        items.extend(its);
        offsets.push(items.len() as u32);
    }
    let masks = valences
        .iter()
        .map(|&k| cached_masks(degree, k))
        .collect::<Result<Vec<_>>>()?;

    // Fans at curve vertices and corners, one per output corner there.
    let spread = 4usize.pow(extra);
    let mut corner_fan = vec![NONE; output_corners];
    let mut fan_offsets = vec![0u32];
    let mut fan_closed = Vec::new();
    let mut fan_vertex = Vec::new();
    let mut fan_items = Vec::new();
    let mut fan_of_start: HashMap<usize, u32> = HashMap::new();
    for (c, fan) in corner_fan.iter_mut().enumerate() {
        let d = c * spread;
        let v = last.corner_verts[d] as usize;
        if v >= outputs || !matches!(rules[v], Rule::Curve | Rule::Corner) {
            continue;
        }
        // Clockwise to the fan's start: across outgoing edges until a curve edge.
        let mut start = d;
        let mut closed = false;
        loop {
            let e = last.corner_edges()[start];
            if is_curve_edge(e) {
                break;
            }
            match across(last, e as usize, start) {
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
            match across(last, e as usize, p) {
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
        rules,
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

impl Plan {
    /// The stencils of this plan, built on first use (see the module documentation).
    fn limit_stencils(&self) -> Result<Arc<Stencils>> {
        let mut kept = self.limit_cache().lock().unwrap_or_else(|e| e.into_inner());
        if let Some(st) = kept.as_ref() {
            return Ok(st.clone());
        }
        let options = *self.options();
        let levels = options.levels;
        let n = neighbourhood_size(options.degree) as u32;
        // Semi-sharp features must have become smooth by the last level.
        let cage = self.cage();
        let finite = cage
            .creases()
            .iter()
            .map(|c| c.sharpness)
            .chain(cage.corners().iter().map(|c| c.sharpness))
            .filter(|&s| s > 0.0 && s < INFINITELY_SHARP)
            .fold(0.0f32, f32::max);
        let first = (finite.ceil() as u32)
            .saturating_sub(levels)
            .max(u32::from(levels == 0));
        // Enough doubling to put N rings between a vertex and its nearest neighbour.
        let clean = (1..).find(|&m| (1u32 << m) > n).unwrap_or(1);
        let mut candidates = vec![first, first.max(clean)];
        candidates.extend((1..=MAX_EXTRA_LEVELS).map(|i| first.max(clean) + i));
        candidates.dedup();
        let outputs = self.levels().last().expect("a level").num_vertices;
        let output_corners = self.levels().last().expect("a level").num_corners();
        for m in candidates {
            let built = if m == 0 {
                build_stencils(self, outputs, output_corners, 0)?
            } else {
                let extended = Plan::new(
                    cage,
                    &Options {
                        levels: levels + m,
                        output: OutputKind::Primal,
                        ..options
                    },
                )?;
                build_stencils(&extended, outputs, output_corners, m)?.map(|mut st| {
                    st.extended = Some(extended);
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

    /// Levels the limit evaluation adds to this plan (built on first use).
    pub fn limit_extra_levels(&self) -> Result<u32> {
        self.check_limit(false)?;
        if self.options().degree == 1 || self.catmark().is_some() {
            return Ok(0);
        }
        Ok(self.limit_stencils()?.extra_levels)
    }

    fn check_limit(&self, normals: bool) -> Result<()> {
        if self.options().output != OutputKind::Primal {
            return Err(Error::InvalidInput(
                "limit positions and normals are given at the drawing mesh's vertices: use the \
                 primal output"
                    .into(),
            ));
        }
        if self.options().rules == Rules::Classic {
            if self.options().degree != 3 {
                return Err(Error::InvalidInput(
                    "limit positions with classic rules exist for degree 3 (Catmull-Clark) only"
                        .into(),
                ));
            }
            if normals {
                return Err(Error::InvalidInput(
                    "limit normals with classic rules are not implemented; use the averaging \
                     rules"
                        .into(),
                ));
            }
            if self.steps().is_empty() {
                return Err(Error::InvalidInput(
                    "classic limit positions need at least one level".into(),
                ));
            }
        }
        Ok(())
    }

    /// Limit positions at the output vertices (the drawing mesh's), for any per-vertex data of
    /// the cage (`channels` interleaved values per cage vertex, as [`Plan::evaluate`]). Old
    /// vertices keep their ids, so the first values are the limits at the cage vertices.
    /// Averaging rules: every degree (see the module documentation); classic rules: degree 3
    /// (OpenSubdiv's limit masks).
    pub fn limit_positions<T: Scalar>(&self, values: &[T], channels: usize) -> Result<Vec<T>> {
        check_values(values, channels, self.num_input_vertices())?;
        self.check_limit(false)?;
        let per_group = |group: &[T], n: usize| -> Result<Vec<T>> {
            Ok(match n {
                1 => self.limit_n::<T, 1>(group, false)?.0,
                2 => self.limit_n::<T, 2>(group, false)?.0,
                3 => self.limit_n::<T, 3>(group, false)?.0,
                _ => self.limit_n::<T, 4>(group, false)?.0,
            })
        };
        if channels <= 4 {
            return per_group(values, channels);
        }
        let error = Mutex::new(None);
        let out = in_groups_of_four(values, channels, |group| {
            per_group(&group, 4).unwrap_or_else(|e| {
                *error.lock().unwrap_or_else(|e| e.into_inner()) = Some(e);
                vec![T::default(); 4 * self.num_output_vertices()]
            })
        });
        match error.into_inner().unwrap_or_else(|e| e.into_inner()) {
            Some(e) => Err(e),
            None => Ok(out),
        }
    }

    /// Limit positions (3 channels) and unit limit normals of the surface of `points` (3 per
    /// cage vertex): one normal per output face corner (in the order of
    /// [`Plan::output_face_vertices`]), the same for every corner of a smooth vertex and one
    /// per side at curve vertices and corners (split normals). Degenerate geometry gives zero
    /// vectors.
    pub fn limit_surface<T: Scalar>(&self, points: &[T]) -> Result<(Vec<T>, Vec<T>)> {
        check_values(points, 3, self.num_input_vertices())?;
        self.check_limit(true)?;
        let (positions, normals) = self.limit_n::<T, 3>(points, true)?;
        Ok((positions, normals.expect("normals were asked for")))
    }

    /// Limit positions (and normals) of `N`-channel values.
    fn limit_n<T: Scalar, const N: usize>(
        &self,
        values: &[T],
        normals: bool,
    ) -> Result<(Vec<T>, Option<Vec<T>>)> {
        let (points, _) = values.as_chunks::<N>();
        let compact: Cow<[[T; N]]> = match self.vertex_map() {
            None => Cow::Borrowed(points),
            Some(map) => Cow::Owned(map.iter().map(|&v| points[v as usize]).collect()),
        };
        if let Some(catmark) = self.catmark() {
            let Final::Primal(last) = self.run(&compact, false) else {
                unreachable!("primal classic run")
            };
            let j = self.levels().len() - 1;
            let out = catmark.limit(j, &self.levels()[j], &last);
            return Ok((out.into_flattened(), None));
        }
        if self.options().degree == 1 {
            // Bilinear: the surface interpolates the refined points; each face's patch has its
            // own normal at its corners.
            let Final::Primal(last) = self.run(&compact, false) else {
                unreachable!("degree 1 is primal")
            };
            let normals = normals.then(|| self.face_corner_normals(&last));
            return Ok((last.into_flattened(), normals));
        }
        let st = self.limit_stencils()?;
        let data = self.limit_data(&st, &compact);
        let positions: Vec<[T; N]> = gather(st.rules.len(), |v| {
            let items = &st.items[st.offsets[v] as usize..st.offsets[v + 1] as usize];
            let weights: &[f64] = match st.rules[v] {
                Rule::Interior(m) => &st.masks[m as usize].position,
                Rule::Curve => &st.curve_mask,
                Rule::Corner => return data[items[0] as usize],
            };
            combine(&data, items, weights)
        });
        let normals = normals.then(|| self.stencil_normals(&st, &data, &positions));
        Ok((positions.into_flattened(), normals))
    }

    /// The data the stencils read: the last level's vertex values (odd degrees), or its face
    /// values, then the last step's curve-edge values, then the cage points (even degrees).
    fn limit_data<T: Scalar, const N: usize>(
        &self,
        st: &Stencils,
        compact: &[[T; N]],
    ) -> Vec<[T; N]> {
        let plan = st.extended.as_ref().unwrap_or(self);
        match plan.run(compact, self.options().degree.is_multiple_of(2)) {
            Final::Primal(vertices) => vertices,
            Final::Dual {
                mut faces,
                curve_edges,
            } => {
                faces.extend(curve_edges);
                faces.extend_from_slice(compact);
                faces
            }
        }
    }

    /// Unit normals per output corner from the stencils (see [`Plan::limit_surface`]).
    fn stencil_normals<T: Scalar, const N: usize>(
        &self,
        st: &Stencils,
        data: &[[T; N]],
        positions: &[[T; N]],
    ) -> Vec<T> {
        let at = |x: &[T; N]| DVec3::new(x[0].to_f64(), x[1].to_f64(), x[2].to_f64());
        let vertex_normals: Vec<DVec3> = gather(st.rules.len(), |v| {
            let Rule::Interior(m) = st.rules[v] else {
                return DVec3::ZERO;
            };
            let items = &st.items[st.offsets[v] as usize..st.offsets[v + 1] as usize];
            let [a, b] = &st.masks[m as usize].tangents;
            let (a, b) = (at(&combine(data, items, a)), at(&combine(data, items, b)));
            a.cross(b).normalize_or_zero()
        });
        let fan_normals: Vec<DVec3> = gather(st.fan_closed.len(), |f| {
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
        });
        let corners = self.output_face_vertices();
        let mut out = Vec::with_capacity(3 * corners.len());
        for (c, &v) in corners.iter().enumerate() {
            let n = match st.corner_fan[c] {
                NONE => vertex_normals[v as usize],
                f => fan_normals[f as usize],
            };
            out.extend(n.to_array().map(T::from_f64));
        }
        out
    }

    /// Unit normals of each output face's bilinear patch at its corners.
    fn face_corner_normals<T: Scalar, const N: usize>(&self, points: &[[T; N]]) -> Vec<T> {
        let at = |v: u32| {
            let x = &points[v as usize];
            DVec3::new(x[0].to_f64(), x[1].to_f64(), x[2].to_f64())
        };
        let (offsets, verts) = (self.output_face_offsets(), self.output_face_vertices());
        let mut out = Vec::with_capacity(3 * verts.len());
        for f in 0..offsets.len() - 1 {
            let face = &verts[offsets[f] as usize..offsets[f + 1] as usize];
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
        out
    }
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
