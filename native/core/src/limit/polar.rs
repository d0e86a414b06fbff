//! Limit stencils around an isolated irregular vertex, composed once per degree and valence.
//!
//! Near an irregular interior vertex `c` of valence `k` (within `N` rings, `N` as in
//! [`neighbourhood_size`]) no vertex of the plan's last level `M_L` is clean: its limit needs
//! more levels, on which its neighbourhood is a grid. But the limit of a vertex is a fixed
//! linear function of the data of `M_L`, and where every other vertex that this function reads
//! (and one ring more) is interior, of valence 4 and on no curve, that function depends only on
//! the degree, `k` and the vertex's place in the polar grid around `c`: it is the same around
//! every such `c` of every mesh. It is computed here once per `(degree, k)` for the process,
//! as the local extension would compute it: unit impulses on level 1 of a polar cage run
//! through [`clean_levels`] steps of the engine, then the valence-4 masks at each target. A plan
//! then only labels the grid around each isolated `c` ([`sector_frames`]) and reads its
//! targets' stencils off the table, and a cached limit applies them to `M_L`'s data: no partial
//! levels, made or evaluated. (The same function, so equal to the local extension's values up
//! to the rounding of another summation order.)
//!
//! Tangents are taken in each target's frame at the level where it is clean; only their cross
//! product is used, whose direction does not depend on the frame's rotation.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

use crate::analysis::{
    cached_vertex_masks, frame_items, neighbourhood_size, polar_cage, sector_frames, steps_values,
    Label,
};
use crate::error::{Error, Result};
use crate::options::Options;
use crate::refinement::Refinement;
use crate::scalar::Scalar;
use crate::topology::Level;
use rayon::prelude::*;

use super::{clean_levels, combine_joint, polar_grid};

/// The highest valence given composed stencils. A table's cost grows with the valence (a polar
/// cage of that many sectors run through `clean_levels` steps): 691M instructions for degree 9
/// at valences 3 and 5 together (one thread, callgrind driver), about 86M a sector. Higher
/// valences (rarer) take the local extension.
const MAX_VALENCE: usize = 8;

/// Impulses run through the steps at a time (the channels of one evaluation).
const IMPULSES: usize = 16;

/// The composed limit stencils of the vertices within `N` rings of an irregular vertex of one
/// valence, for one degree (module documentation).
#[derive(Debug)]
pub(super) struct PolarStencils {
    /// Rings of the grid around the centre that a mesh must have regular (every vertex other
    /// than the centre interior, of valence 4 and on no curve, all distinct) for the stencils
    /// to hold: one more than the farthest item they read.
    pub check_rings: usize,
    /// Per target, its frame index in the grid of [`sector_frames`] walked `check_rings`
    /// rings (`s (R+1)^2 + i (R+1) + j`, `R = check_rings`): the target is the vertex of that
    /// frame.
    pub targets: Vec<u32>,
    /// Offsets into `items` and `weights` per target.
    pub offsets: Vec<u32>,
    /// Frame index of each item read (same grid): its vertex for odd degrees, its face for
    /// even ones.
    pub items: Vec<u32>,
    /// Per item its weights in the limit position and the two tangents, and a zero (the
    /// layout of the interior masks' joint weights).
    pub weights: Vec<[f64; 4]>,
}

/// [`PolarStencils`] of `degree` around a vertex of `valence`, computed once per process.
pub(super) fn cached(degree: u32, valence: usize) -> Result<Arc<PolarStencils>> {
    type Cache = Mutex<HashMap<(u32, usize), Arc<PolarStencils>>>;
    static CACHE: OnceLock<Cache> = OnceLock::new();
    let cache = CACHE.get_or_init(Default::default);
    let key = (degree, valence);
    if let Some(s) = cache.lock().unwrap_or_else(|e| e.into_inner()).get(&key) {
        return Ok(s.clone());
    }
    let stencils = Arc::new(compose(degree, valence, 0)?);
    (cache.lock().unwrap_or_else(|e| e.into_inner())).insert(key, stencils.clone());
    Ok(stencils)
}

/// Ring of a label of [`frame_items`]: a vertex `(s, i, j)` lies on ring `max(i, j)`, a face
/// `(s, i, j)` between rings `max(i, j)` and `max(i, j) + 1`.
fn ring(label: Label, primal: bool) -> usize {
    label.1.max(label.2) + usize::from(!primal)
}

/// Computes [`PolarStencils`] (see the module documentation), on a polar cage of `more` rings
/// more than needed (tests).
fn compose(degree: u32, valence: usize, more: usize) -> Result<PolarStencils> {
    let internal = |what: &str| Error::Internal(format!("polar limit stencils: {what}"));
    if !(3..=MAX_VALENCE).contains(&valence) || degree < 2 {
        return Err(internal("a valence of 3 to 8 and a degree of 2 or more"));
    }
    let primal = degree % 2 == 1;
    let n = neighbourhood_size(degree);
    let m = clean_levels(degree) as usize;
    let reach = degree.div_ceil(2) as usize;
    // A target lies within `n` rings of the centre; its mask at level `1 + m` reads `n` rings
    // there (within `n + 1` rings of level 1), and `m` steps back from there reach fewer than
    // `reach` rings of level 1 more: the items lie within `rings` rings, which level 1 (`2 R`
    // rings) must hold. The impulses start at level 1, so only the steps from there run: the
    // cage's boundary (ring `2 R` of level 1) changes the values within `reach` fine rings of
    // it per step, within `reach` rings of level 1 over the `m` steps, clear of the masks'
    // items when `2 R - reach > n + 1`. (A test checks that a larger cage changes nothing.)
    let rings = n + 2 + reach;
    let cage_rings = (rings + 1).div_ceil(2) + more;
    let cage = polar_cage(valence, cage_rings)?;
    let options = Options {
        degree,
        levels: (1 + m) as u32,
        ..Options::default()
    };
    let refinement = Refinement::new(&cage, &options)?;
    let levels = refinement.try_levels()?;
    let (base, top) = (&levels[1], &levels[1 + m]);
    // The centre keeps id 0 at every level, and the child corner of corner `c` at its vertex
    // is `4 c`.
    let first = base.corners_of_vertex(0)[0] as usize;
    let first_top = first << (2 * m);
    if top.corner_verts[first_top] != 0 {
        return Err(internal("the centre's corner lost"));
    }
    let frames = sector_frames(base, first, rings).ok_or_else(|| internal("a short cage"))?;
    let labelled = frame_items(base, &frames, rings, rings, !primal);
    // The targets, (s, i, j) with 1 <= i <= n, 0 <= j <= n, each once; at level 1 + m, where
    // it is clean, each target's masks in the frame of its place in the polar grid there, so
    // that a target's frame turns with its sector.
    let spread = 1usize << m;
    let top_side = spread * n + 1;
    let top_frames =
        sector_frames(top, first_top, spread * n).ok_or_else(|| internal("a short cage"))?;
    let masks = cached_vertex_masks(degree, 4)?;
    let [a, b] = &masks.tangents;
    let mut targets: Vec<Label> = Vec::new();
    let mut reads: Vec<Vec<usize>> = Vec::new();
    for s in 0..valence {
        for i in 1..=n {
            for j in 0..=n {
                let at = top_frames[s * top_side * top_side + spread * (i * top_side + j)];
                let around = sector_frames(top, at, n).ok_or_else(|| internal("a short cage"))?;
                let items = frame_items(top, &around, n, n, !primal);
                if items.len() != masks.position.len() || a.len() != items.len() {
                    return Err(internal("masks and neighbourhood of different sizes"));
                }
                targets.push((s, i, j));
                reads.push(items.into_iter().map(|(_, i)| i).collect());
            }
        }
    }
    let per_sector = n * (n + 1);
    // Impulses on the centre and sector 0, IMPULSES at a time: by the rotational symmetry,
    // target (s, i, j) weighs item (t, a, b) as target (s - t, i, j) weighs item (0, a, b).
    let size = match primal {
        true => base.num_vertices,
        false => base.num_faces(),
    };
    let first_sector: Vec<usize> = (0..labelled.len())
        .filter(|&q| labelled[q].0 .0 == 0)
        .collect();
    // Per target and sector-0 item, the weights.
    let mut sector0 = vec![vec![[0.0f64; 4]; first_sector.len()]; targets.len()];
    let mut impulses = vec![[0.0f64; IMPULSES]; size];
    for (group, chunk) in first_sector.chunks(IMPULSES).enumerate() {
        for (c, &q) in chunk.iter().enumerate() {
            impulses[labelled[q].1][c] = 1.0;
        }
        let response = steps_values(&refinement, 1, m, &impulses)?;
        for (t, read) in reads.iter().enumerate() {
            for c in 0..chunk.len() {
                let mut w = [0.0f64; 4];
                for (k, &i) in read.iter().enumerate() {
                    let x = response[i][c];
                    w[0] += masks.position[k] * x;
                    w[1] += a[k] * x;
                    w[2] += b[k] * x;
                }
                sector0[t][group * IMPULSES + c] = w;
            }
        }
        for &q in chunk {
            impulses[labelled[q].1] = [0.0; IMPULSES];
        }
    }
    let index_in_sector0: HashMap<(usize, usize), usize> = (first_sector.iter().enumerate())
        .map(|(k, &q)| ((labelled[q].0 .1, labelled[q].0 .2), k))
        .collect();
    let weight = |t: usize, q: usize| -> [f64; 4] {
        let ((s, _, _), (u, i, j)) = (targets[t], labelled[q].0);
        let rotated = (s + valence - u) % valence;
        let k = index_in_sector0[&(i, j)];
        sector0[rotated * per_sector + t % per_sector][k]
    };
    let weights: Vec<Vec<[f64; 4]>> = (0..targets.len())
        .map(|t| (0..labelled.len()).map(|q| weight(t, q)).collect())
        .collect();
    // The items read: the farthest decides the rings a mesh must have regular.
    let read_at = |t: usize, q: usize| weights[t][q] != [0.0; 4];
    let farthest = (0..targets.len())
        .flat_map(|t| (0..labelled.len()).filter(move |&q| read_at(t, q)))
        .map(|q| ring(labelled[q].0, primal))
        .max()
        .ok_or_else(|| internal("no weights"))?;
    if farthest + 1 >= rings {
        return Err(internal("stencils reaching the rings' end"));
    }
    let check_rings = farthest + 1;
    let check_side = check_rings + 1;
    let frame_of = |(s, i, j): Label| (s * check_side * check_side + i * check_side + j) as u32;
    let mut out = PolarStencils {
        check_rings,
        targets: Vec::with_capacity(targets.len()),
        offsets: vec![0],
        items: Vec::new(),
        weights: Vec::new(),
    };
    for (t, &label) in targets.iter().enumerate() {
        out.targets.push(frame_of(label));
        for (q, &(item, _)) in labelled.iter().enumerate() {
            if read_at(t, q) {
                out.items.push(frame_of(item));
                out.weights.push(weights[t][q]);
            }
        }
        out.offsets.push(out.items.len() as u32);
    }
    Ok(out)
}

/// Stencils read off [`PolarStencils`] on a level: per centre its table and the data item at
/// each frame of its grid, per stencil its centre and its target in the table. (The weights
/// stay in the table: a copy per stencil would be some hundred items of 36 bytes per vertex.)
#[derive(Debug, Default)]
pub(super) struct Composed {
    centres: Vec<(Arc<PolarStencils>, Vec<u32>)>,
    stencils: Vec<(u32, u32)>,
}

impl Composed {
    /// The data items of stencil `i` and their weights.
    fn stencil(&self, i: usize) -> (impl Iterator<Item = usize> + '_, &[[f64; 4]]) {
        let (centre, t) = self.stencils[i];
        let (template, items) = &self.centres[centre as usize];
        let range =
            template.offsets[t as usize] as usize..template.offsets[t as usize + 1] as usize;
        let frames = &template.items[range.clone()];
        let at = frames.iter().map(move |&f| items[f as usize] as usize);
        (at, &template.weights[range])
    }

    /// The limit position and the two tangents of stencil `i` from `data`.
    pub(super) fn joint<T: Scalar, const N: usize>(
        &self,
        i: usize,
        data: &[[T; N]],
    ) -> [[f64; N]; 3] {
        let (at, weights) = self.stencil(i);
        combine_joint(data, at, weights)
    }

    /// The limit position of stencil `i` from `data`.
    pub(super) fn position<T: Scalar, const N: usize>(&self, i: usize, data: &[[T; N]]) -> [T; N] {
        let (at, weights) = self.stencil(i);
        let mut acc = [0.0f64; N];
        for (i, w) in at.zip(weights) {
            for (a, x) in acc.iter_mut().zip(&data[i]) {
                *a += w[0] * x.to_f64();
            }
        }
        acc.map(T::from_f64)
    }
}

/// The composed stencils of the vertices of `last` (a quad level, the plan's last) that
/// `wanted` picks and that lie within `N` rings of an isolated irregular vertex (interior, of
/// valence 3 to [`MAX_VALENCE`] but 4, the grid of [`PolarStencils::check_rings`] rings
/// around it regular):
/// those vertices in increasing order, and their stencils in the same order. `on_curve` tells
/// the vertices on the step's curves.
pub(super) fn stencils_around(
    last: &Level,
    degree: u32,
    on_curve: &(dyn Fn(usize) -> bool + Sync),
    wanted: &(dyn Fn(usize) -> bool + Sync),
) -> Result<(Vec<u32>, Composed)> {
    let primal = degree % 2 == 1;
    let centres: Vec<usize> = (0..last.num_vertices)
        .filter(|&v| {
            let k = last.corners_of_vertex(v).len();
            (3..=MAX_VALENCE).contains(&k) && k != 4 && !on_curve(v)
        })
        .collect();
    // The tables first, one valence at a time (the centres' tasks would make one several
    // times over).
    let mut valences: Vec<usize> = (centres.iter())
        .map(|&c| last.corners_of_vertex(c).len())
        .collect();
    valences.sort_unstable();
    valences.dedup();
    let tables = (valences.iter())
        .map(|&k| cached(degree, k))
        .collect::<Result<Vec<_>>>()?;
    // Per isolated centre: its table, the data item at each frame, and its targets that
    // `wanted` picks (vertex, target).
    type Found = Option<(Arc<PolarStencils>, Vec<u32>, Vec<(u32, u32)>)>;
    let found: Vec<Found> = (centres.par_iter())
        .map(|&c| -> Result<Found> {
            let corners = last.corners_of_vertex(c);
            let at = valences.binary_search(&corners.len());
            let template =
                tables[at.map_err(|_| Error::Internal("polar: a valence".into()))?].clone();
            let r = template.check_rings;
            let Some(frames) = sector_frames(last, corners[0] as usize, r) else {
                return Ok(None);
            };
            if !polar_grid(last, &frame_items(last, &frames, r, r, false), on_curve) {
                return Ok(None);
            }
            let items = (frames.iter())
                .map(|&frame| match primal {
                    true => last.corner_verts[frame],
                    false => last.face_of(frame) as u32,
                })
                .collect();
            let targets = (template.targets.iter().enumerate())
                .map(|(t, &f)| (last.corner_verts[frames[f as usize]], t as u32))
                .filter(|&(v, _)| wanted(v as usize))
                .collect();
            Ok(Some((template, items, targets)))
        })
        .collect::<Result<_>>()?;
    let mut composed = Composed::default();
    let mut all: Vec<(u32, u32, u32)> = Vec::new();
    for (template, items, targets) in found.into_iter().flatten() {
        let centre = composed.centres.len() as u32;
        all.extend(targets.into_iter().map(|(v, t)| (v, centre, t)));
        composed.centres.push((template, items));
    }
    all.sort_unstable();
    // A vertex near two centres would be no isolated one's: left to the local extension.
    let twice = |i: usize| {
        (i > 0 && all[i - 1].0 == all[i].0) || (i + 1 < all.len() && all[i + 1].0 == all[i].0)
    };
    let mut vertices = Vec::with_capacity(all.len());
    for (i, &(v, centre, t)) in all.iter().enumerate() {
        if !twice(i) {
            vertices.push(v);
            composed.stencils.push((centre, t));
        }
    }
    Ok((vertices, composed))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The polar cage is large enough: with two rings more, the same stencils (to rounding);
    /// and the items lie within the rings walked.
    #[test]
    fn a_larger_cage_gives_the_same_stencils() {
        for degree in 2..=9 {
            for valence in [3, 5, 7] {
                let (a, b) = (compose(degree, valence, 0), compose(degree, valence, 2));
                let (a, b) = (a.unwrap(), b.unwrap());
                let case = format!("degree {degree}, valence {valence}");
                assert_eq!(a.check_rings, b.check_rings, "{case}");
                assert_eq!((&a.targets, &a.offsets), (&b.targets, &b.offsets), "{case}");
                assert_eq!(a.items, b.items, "{case}");
                let worst = (a.weights.iter().flatten())
                    .zip(b.weights.iter().flatten())
                    .map(|(x, y)| (x - y).abs())
                    .fold(0.0, f64::max);
                assert!(worst < 1e-14, "{case}: {worst:e}");
                // The position weights sum to one.
                for t in 0..a.targets.len() {
                    let range = a.offsets[t] as usize..a.offsets[t + 1] as usize;
                    let sum: f64 = a.weights[range].iter().map(|w| w[0]).sum();
                    assert!(
                        (sum - 1.0).abs() < 1e-12,
                        "{case}: target {t} sums to {sum}"
                    );
                }
            }
        }
    }
}
