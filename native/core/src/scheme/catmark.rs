//! Catmull-Clark exactly as OpenSubdiv's `catmark` scheme (Sdc `catmarkScheme.h`, `scheme.h`,
//! `crease.cpp`): the vertex rules (smooth, dart, crease, corner), how semi-sharp sharpness
//! decreases (uniform or Chaikin), the fractional blend where a vertex changes rule between
//! levels, and the weights of the face, edge, vertex and limit masks. Nothing here knows how a
//! level is stored: [`crate::curves::LevelSharpness`] lays the sharpness and rules out on the
//! levels, [`crate::step`] and [`crate::limit`] gather the neighbourhoods the masks weigh.

use super::{decrement, is_infinitely_sharp, is_semi_sharp, is_sharp};
use crate::mesh::INFINITELY_SHARP;
use crate::options::Creasing;

/// The subdivision rule of a vertex (OpenSubdiv's `Crease::Rule`), from its sharpness and the
/// number of sharp edges at it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(u8)]
pub enum VertexRule {
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

impl VertexRule {
    /// True for the rules that use the smooth masks.
    #[inline]
    pub fn is_smooth(self) -> bool {
        matches!(self, VertexRule::Smooth | VertexRule::Dart)
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
    if is_infinitely_sharp(s) {
        return INFINITELY_SHARP;
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
pub fn vertex_rule(vertex: f32, sharp_edges: usize) -> VertexRule {
    if is_sharp(vertex) {
        return VertexRule::Corner;
    }
    match sharp_edges {
        0 => VertexRule::Smooth,
        1 => VertexRule::Dart,
        2 => VertexRule::Crease,
        _ => VertexRule::Corner,
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

/// The smooth vertex mask of an interior vertex of `k` faces: `(k-2)/k` on the vertex, `1/k^2`
/// on each edge neighbour and each face point.
#[inline]
pub(crate) fn smooth_vertex_weights(k: usize) -> (f64, f64) {
    let kf = k as f64;
    ((kf - 2.0) / kf, 1.0 / (kf * kf))
}

/// The crease vertex mask: `3/4` on the vertex, `1/8` on each of its two crease neighbours.
pub(crate) const CREASE_VERTEX_WEIGHTS: (f64, f64) = (0.75, 0.125);

/// The smooth edge mask: `1/4` on each end and, shared by the edge's faces, `1/2` on their
/// face points.
pub(crate) const SMOOTH_EDGE_WEIGHTS: (f64, f64) = (0.25, 0.5);

/// The crease edge mask: the midpoint of its ends.
pub(crate) const CREASE_EDGE_WEIGHT: f64 = 0.5;

/// The edge mask of a semi-sharp edge of sharpness `s < 1` between its crease and smooth
/// masks (OpenSubdiv's `ComputeEdgeVertexMask` with a fractional weight): the weight on each
/// end and the total shared by the face points.
#[inline]
pub(crate) fn blended_edge_weights(s: f32) -> (f64, f64) {
    let p = s as f64;
    (p * 0.5 + (1.0 - p) * 0.25, 0.5 * (1.0 - p))
}

/// The smooth limit mask at a vertex of valence `k` of a quad level: the weights on the
/// opposite corners of its faces, on its edge neighbours and on itself (`[1 4 1]^T [1 4 1] /
/// 36` when `k = 4`, else `1/(k(k+5))`, `4/(k(k+5))` and the rest).
#[inline]
pub(crate) fn smooth_limit_weights(k: usize) -> (f64, f64, f64) {
    if k == 4 {
        (1.0 / 36.0, 1.0 / 9.0, 4.0 / 9.0)
    } else {
        let kf = k as f64;
        let f = 1.0 / (kf * (kf + 5.0));
        (f, 4.0 * f, 1.0 - kf * 5.0 * f)
    }
}

/// The crease limit mask: `2/3` on the vertex, `1/6` on each crease neighbour.
pub(crate) const CREASE_LIMIT_WEIGHTS: (f64, f64) = (2.0 / 3.0, 1.0 / 6.0);

/// Limit mask of an infinitely sharp dart of valence `k` whose sharp edge is edge `sharp` of
/// its 1-ring: weights on `(v, e_0..e_{k-1}, f_0..f_{k-1})` (edge neighbours and opposite
/// corners, face `i` being `(v, e_i, f_i, e_{i+1})`), the left eigenvector of eigenvalue 1 of
/// the 1-ring's Catmull-Clark matrix (smooth vertex rule, midpoint on the sharp edge), found
/// by power iteration from the smooth limit mask. (OpenSubdiv keeps the smooth mask at a dart;
/// Blender's limit surface is the true limit, which this is.)
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
