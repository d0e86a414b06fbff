//! Analysis of the schemes (the paper's §4), computed from the engine itself: the subdivision
//! matrix of the invariant neighbourhood of an irregular vertex (odd degrees) or face (even
//! degrees) of valence k, obtained by running unit impulses through one step of the step
//! primitive on a refinement, and its eigenvalues.
//!
//! Ordering of the neighbourhood (the paper's Fig. 16). Let `N = degree / 2` (even degrees) or
//! `(degree - 1) / 2` (odd). The neighbourhood is split into `k` sectors `s = 0..k`, counter-
//! clockwise around the centre; within a sector, grid positions `(i, j)` count steps along the
//! sector's first edge (`i`) and its second edge (`j`).
//! - Even degrees (dual data, one value per face): faces `(s, i, j)`, `0 <= i, j <= N`, at index
//!   `s (N+1)^2 + i (N+1) + j`; face `(s, 0, 0)` touches the centre vertex (the k-gon of the dual).
//! - Odd degrees (primal data, one value per vertex): the centre at index 0, then vertices
//!   `(s, i, j)`, `1 <= i <= N+1`, `0 <= j <= N+1`, at `1 + s (N+1)(N+2) + (i-1)(N+2) + j`.
//!
//! On top of the matrix (see [`SubdivisionMatrix::fourier_blocks`], [`SubdivisionMatrix::report`],
//! [`characteristic_map`] and [`vertex_masks`]):
//! - the Fourier block structure: the rotational symmetry makes `A[(s,a),(t,b)]` depend on
//!   `t - s` only, so the modes `m = 0..k` of the discrete Fourier transform over the sectors
//!   decouple into `k` complex blocks `B_m = sum_d C_d w^(d m)`, `w = exp(2 pi i / k)`, of one
//!   sector's size (plus the centre in `B_0` for primal schemes). The spectrum of the matrix is
//!   the union of the blocks' spectra; the blocks are small, so their eigenvalues are the
//!   accurate route;
//! - the limit masks at a vertex of valence k ([`vertex_masks`]): the dominant left eigenvector
//!   (limit position) and the subdominant pair (tangents), which the limit evaluation uses, and
//!   on curves the 1-D B-spline [`cardinal_bspline`];
//! - the paper's checks (§4.3, §4.4): `lambda0 = 1` simple, the subdominant pair real and equal,
//!   coming from the modes `1` and `k - 1`, isolated from the rest of the spectrum; the
//!   characteristic map (the control net of the subdominant eigenvectors, refined by the engine)
//!   regular (its Jacobian has one sign on a ring around the centre) and of winding number one,
//!   which together give C1 (the paper's Theorem 2); and the third eigenvalue against the square
//!   of the subdominant one, which excludes C2 when it is larger.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

use nalgebra::{Complex, DMatrix, DVector, Schur};

use crate::error::{Error, Result};
use crate::memory;
use crate::mesh::Cage;
use crate::options::Options;
use crate::refinement::Refinement;
use crate::step::{LevelData, Scratch};
use crate::topology::Level;

pub use crate::scheme::{cardinal_bspline, cardinal_bspline_derivative};

/// A subdivision matrix with the ordering of the module documentation.
#[derive(Debug, Clone)]
pub struct SubdivisionMatrix {
    /// Degree of the scheme.
    pub degree: u32,
    /// Valence of the irregular vertex (odd degrees) or face (even degrees).
    pub valence: usize,
    /// `(sector, i, j)` of each row and column (`(0, 0, 0)` for the primal centre).
    pub labels: Vec<(usize, usize, usize)>,
    /// The matrix: row `r` gives the new value at item `r` from the old values.
    pub matrix: DMatrix<f64>,
}

/// Neighbourhood size `N` of a degree: the minimal invariant neighbourhood has `N` rings, the
/// complete one (used here) `N + 1`.
pub fn neighbourhood_size(degree: u32) -> usize {
    (if degree.is_multiple_of(2) {
        degree / 2
    } else {
        (degree - 1) / 2
    }) as usize
}

/// The cage used to build matrices: `rings` rings of quads around a vertex of valence `k`
/// (vertex 0), sector `s` a `rings x rings` grid whose second edge is sector `s+1`'s first.
pub fn polar_cage(valence: usize, rings: usize) -> Result<Cage> {
    let r = rings;
    let id = |s: usize, i: usize, j: usize| -> i64 {
        let v = if i == 0 && j == 0 {
            0
        } else if i == 0 {
            1 + ((s + 1) % valence) * r * (r + 1) + (j - 1) * (r + 1)
        } else {
            1 + s * r * (r + 1) + (i - 1) * (r + 1) + j
        };
        v as i64
    };
    let too_large = || {
        Error::InvalidInput(format!(
            "a polar cage of valence {valence} and {rings} rings is more than 32-bit indices \
             can address"
        ))
    };
    let num_faces = (valence.checked_mul(r))
        .and_then(|n| n.checked_mul(r))
        .filter(|&n| n <= u32::MAX as usize / 4)
        .ok_or_else(too_large)?;
    let mut faces = memory::with_capacity(4 * num_faces)?;
    for s in 0..valence {
        for i in 0..r {
            for j in 0..r {
                faces.extend([
                    id(s, i, j),
                    id(s, i + 1, j),
                    id(s, i + 1, j + 1),
                    id(s, i, j + 1),
                ]);
            }
        }
    }
    let sizes = memory::filled(num_faces, 4)?;
    Cage::from_indices(1 + valence * r * (r + 1), &sizes, &faces)
}

/// Walks the quad grid around a vertex of a quad level: `frame(s, i, j)` is the corner at grid
/// vertex `(i, j)` of the face `(i, j)` of sector `s`, oriented so that its next corner is
/// `(i+1, j)` and its previous `(i, j+1)`. Walks that would cross a boundary give `None`; the
/// grid is a true polar grid only where every vertex passed is interior of valence 4, which
/// callers check (see [`crate::limit`]).
pub(crate) struct SectorGrid<'a> {
    level: &'a Level,
    starts: Vec<usize>,
}

impl<'a> SectorGrid<'a> {
    /// Sectors counter-clockwise from `first`, a corner at the centre; `None` at a boundary.
    pub(crate) fn new(level: &'a Level, first: usize) -> Option<SectorGrid<'a>> {
        // Room for the common valences without reallocation.
        let mut starts = Vec::with_capacity(8);
        starts.push(first);
        loop {
            let last = *starts.last()?;
            // The next sector lies across the incoming edge of this sector's corner.
            let p = level.prev(last);
            let next = level.opposite(level.corner_edges()[p] as usize, p)?;
            if next == first {
                break;
            }
            starts.push(next);
        }
        Some(SectorGrid { level, starts })
    }

    /// Number of sectors (the valence of the centre).
    pub(crate) fn valence(&self) -> usize {
        self.starts.len()
    }

    pub(crate) fn frame(&self, s: usize, i: usize, j: usize) -> Option<usize> {
        let l = self.level;
        let mut o = self.starts[s];
        for _ in 0..i {
            let n = l.next(o);
            o = l.next(l.opposite(l.corner_edges()[n] as usize, n)?);
        }
        for _ in 0..j {
            let n2 = l.next(l.next(o));
            o = l.opposite(l.corner_edges()[n2] as usize, n2)?;
        }
        Some(o)
    }
}

/// A neighbourhood label `(sector, i, j)`.
pub(crate) type Label = (usize, usize, usize);

/// A neighbourhood item: its label and its index in the level.
pub(crate) type Labelled = (Label, usize);

/// The frames `(s, i, j)` of [`SectorGrid::frame`] for `0 <= i, j <= last`, sector by sector
/// and row by row (index `s (last+1)^2 + i (last+1) + j`), walked incrementally (one step per
/// frame); `None` when the walk meets a boundary.
pub(crate) fn sector_frames(level: &Level, first: usize, last: usize) -> Option<Vec<usize>> {
    let grid = SectorGrid::new(level, first)?;
    let l = level;
    let step_i = |o: usize| -> Option<usize> {
        let n = l.next(o);
        Some(l.next(l.opposite(l.corner_edges()[n] as usize, n)?))
    };
    let step_j = |o: usize| -> Option<usize> {
        let n2 = l.next(l.next(o));
        l.opposite(l.corner_edges()[n2] as usize, n2)
    };
    let mut frames = Vec::with_capacity(grid.valence() * (last + 1) * (last + 1));
    for &start in &grid.starts {
        let mut row = start;
        for i in 0..=last {
            if i > 0 {
                row = step_i(row)?;
            }
            let mut o = row;
            frames.push(o);
            for _ in 0..last {
                o = step_j(o)?;
                frames.push(o);
            }
        }
    }
    Some(frames)
}

/// Labels and level indices of the neighbourhood of `rings` rings around the vertex of corner
/// `first` (the ordering of the module documentation): faces `(s, i, j)`, `0 <= i, j < rings`,
/// for even degrees; the centre and vertices `(s, i, j)`, `1 <= i <= rings`, `0 <= j <= rings`,
/// for odd ones. `rings = N + 1` is the complete neighbourhood, `N` the minimal one. `None`
/// when the walk meets a boundary.
pub(crate) fn neighbourhood(
    level: &Level,
    first: usize,
    degree: u32,
    rings: usize,
) -> Option<Vec<Labelled>> {
    let even = degree.is_multiple_of(2);
    let last = if even { rings.max(1) - 1 } else { rings };
    let frames = sector_frames(level, first, last)?;
    Some(frame_items(level, &frames, last, rings, even))
}

/// The items of [`neighbourhood`] read off the frames of [`sector_frames`] (walked up to
/// `last`): faces of `rings` rings (`even`) or the centre and the vertices of `rings` rings.
pub(crate) fn frame_items(
    level: &Level,
    frames: &[usize],
    last: usize,
    rings: usize,
    even: bool,
) -> Vec<Labelled> {
    let side = last + 1;
    let sectors = frames.len() / (side * side);
    let frame = |s: usize, i: usize, j: usize| frames[s * side * side + i * side + j];
    let mut items = Vec::with_capacity(match even {
        true => sectors * rings * rings,
        false => 1 + sectors * rings * (rings + 1),
    });
    if even {
        for s in 0..sectors {
            for i in 0..rings {
                for j in 0..rings {
                    items.push(((s, i, j), level.face_of(frame(s, i, j))));
                }
            }
        }
    } else {
        items.push(((0, 0, 0), level.corner_verts[frame(0, 0, 0)] as usize));
        for s in 0..sectors {
            for i in 1..=rings {
                for j in 0..=rings {
                    items.push(((s, i, j), level.corner_verts[frame(s, i, j)] as usize));
                }
            }
        }
    }
    items
}

/// The complete neighbourhood of the polar cages built here, which have no boundary nearby
/// (they are made with rings enough for it: an internal error otherwise).
fn complete_neighbourhood(level: &Level, first: usize, degree: u32) -> Result<Vec<Labelled>> {
    neighbourhood(level, first, degree, neighbourhood_size(degree) + 1).ok_or_else(|| {
        Error::Internal(format!(
            "the polar cage of degree {degree} must have no boundary within the complete \
             neighbourhood of its centre"
        ))
    })
}

/// The subdivision matrix of degree `degree` around an irregular vertex or face of valence
/// `valence`, built by running unit impulses through one step of the engine (level 1 to 2 of
/// a polar cage, far from its boundary).
pub fn subdivision_matrix(degree: u32, valence: usize) -> Result<SubdivisionMatrix> {
    // The columns and the dense matrix: 16 bytes per entry.
    let (labels, columns) = impulse_responses(degree, valence, |_| true, 16)?;
    let mut matrix = DMatrix::zeros(labels.len(), labels.len());
    for (col, column) in columns.iter().enumerate() {
        matrix.set_column(col, &DVector::from_column_slice(column));
    }
    Ok(SubdivisionMatrix {
        degree,
        valence,
        labels,
        matrix,
    })
}

/// Rings of the polar cage the impulses run on: enough that the boundary's rules cannot reach
/// the matrix. Its rows are the complete neighbourhood at level 2 (`N + 1` rings); a fine value
/// depends on the replicated values within `k = ceil(degree / 2)` fine rings of it, and the
/// boundary of a cage of `R` rings lies at ring `4 R` of level 2, so its rules reach rings
/// `>= 4 R - k - 1`: `4 R > N + k + 2` suffices (one ring more is kept), and level 1 (`2 R`
/// rings) must hold the columns (`N + 1` rings) with a ring to spare. The cost of the masks
/// grows with the valence times `R^2`.
fn analysis_rings(degree: u32) -> usize {
    let n = neighbourhood_size(degree);
    let k = degree.div_ceil(2) as usize;
    ((n + k + 2).div_ceil(4) + 1).max((n + 2).div_ceil(2) + 1)
}

/// Impulses run through one step at a time (the channels of one evaluation).
const IMPULSES_PER_STEP: usize = 8;

/// The labels of the complete neighbourhood of valence `valence` (rows and columns of the
/// subdivision matrix alike) and the columns of the matrix for the labels `wanted` picks, in
/// label order: each the response of one step of the engine (level 1 to 2 of a polar cage, far
/// from its boundary) to a unit impulse, [`IMPULSES_PER_STEP`] impulses per evaluation.
/// `bytes_per_entry` (8 for the columns alone) is what the caller holds per entry of the
/// columns: the request is refused over the default memory budget before they are made (a
/// dense matrix grows with the square of the valence).
fn impulse_responses(
    degree: u32,
    valence: usize,
    wanted: impl Fn((usize, usize, usize)) -> bool,
    bytes_per_entry: u64,
) -> Result<(Vec<Label>, Vec<Vec<f64>>)> {
    if valence < 2 {
        return Err(Error::InvalidInput(format!("valence {valence} is below 2")));
    }
    let cage = polar_cage(valence, analysis_rings(degree))?;
    let plan = Refinement::new(
        &cage,
        &Options {
            degree,
            levels: 2,
            ..Options::default()
        },
    )?;
    let levels = plan.try_levels()?;
    let (coarse, fine) = (&levels[1], &levels[2]);
    // The centre keeps id 0 at every level; its child corners are 4c for its coarse corners c.
    let first = coarse.corners_of_vertex(0)[0] as usize;
    let columns = complete_neighbourhood(coarse, first, degree)?;
    let rows = complete_neighbourhood(fine, 4 * first, degree)?;
    let size = if degree.is_multiple_of(2) {
        coarse.num_faces()
    } else {
        coarse.num_vertices
    };
    let picked: Vec<usize> = columns
        .iter()
        .filter(|(label, _)| wanted(*label))
        .map(|&(_, item)| item)
        .collect();
    let entries = picked.len() as u64 * rows.len() as u64;
    memory::check_request(
        entries.saturating_mul(bytes_per_entry),
        fine.num_faces() as u64,
        memory::default_memory_budget(),
    )?;
    let mut out = memory::with_capacity(picked.len())?;
    let mut impulses = vec![[0.0; IMPULSES_PER_STEP]; size];
    for group in picked.chunks(IMPULSES_PER_STEP) {
        for (c, &item) in group.iter().enumerate() {
            impulses[item][c] = 1.0;
        }
        let response = step_values(&plan, 1, &impulses)?;
        for (c, &item) in group.iter().enumerate() {
            impulses[item][c] = 0.0;
            out.push(memory::collect(
                rows.iter().map(|&(_, at)| response[at][c]),
            )?);
        }
    }
    Ok((rows.into_iter().map(|r| r.0).collect(), out))
}

/// One step `M_j -> M_{j+1}` (`j >= 1`) of `refinement` applied to arbitrary data (`C`
/// channels) of the kind the scheme carries at level `j` (per vertex for odd degrees, per face
/// for even ones), through the step primitive: the subdivision matrices are built from it.
/// Curve 1-D data is read off the 2-D data (vertex values, or the value of an edge's face);
/// corners are pinned at zero.
fn step_values<const C: usize>(
    refinement: &Refinement,
    j: usize,
    values: &[[f64; C]],
) -> Result<Vec<[f64; C]>> {
    steps_values(refinement, j, 1, values)
}

/// [`step_values`] for `steps` steps `M_j -> M_{j+steps}`: the data of level `j + steps`.
pub(crate) fn steps_values<const C: usize>(
    refinement: &Refinement,
    j: usize,
    steps: usize,
    values: &[[f64; C]],
) -> Result<Vec<[f64; C]>> {
    let (levels, networks) = (refinement.try_levels()?, refinement.curve_networks());
    if j == 0 || steps == 0 || j + steps > networks.len() {
        return Err(Error::Internal(format!(
            "steps_values needs 1 <= j and 1 <= steps with j + steps <= {} (the refinement's \
             steps), not j = {j}, steps = {steps}",
            networks.len()
        )));
    }
    let (coarse, previous) = (&levels[j], &networks[j - 1]);
    let cage = vec![[0.0f64; C]; levels[0].num_vertices];
    let primal = refinement.scheme().is_primal();
    let curve = if primal {
        (previous.vertices().iter())
            .map(|cv| values[cv.vertex as usize])
            .collect()
    } else {
        let face_of_edge = |e: u32| coarse.face_of(coarse.edge_corners()[e as usize][0] as usize);
        (previous.edges().iter())
            .map(|ce| values[face_of_edge(ce.edge)])
            .collect()
    };
    // The last step's fine level is the largest: the scratch is provisioned for it.
    let scratch = Scratch::default();
    let last = refinement.step(j + steps - 1);
    let mut data =
        LevelData::on_level(&cage, primal, values, curve).with_scratch_for(&scratch, &last)?;
    for k in j..j + steps {
        data.step(&refinement.step(k))?;
    }
    Ok(data.into_parts().0)
}

/// [`step_values`] of one channel.
fn step_scalar(refinement: &Refinement, j: usize, data: &[f64]) -> Result<Vec<f64>> {
    let values: Vec<[f64; 1]> = data.iter().map(|&x| [x]).collect();
    Ok(step_values(refinement, j, &values)?
        .into_iter()
        .map(|[x]| x)
        .collect())
}

/// The columns of a subdivision matrix for the centre and sector 0 only: by the rotational
/// symmetry (see [`SubdivisionMatrix::symmetry_defect`], checked in the tests) they determine
/// the whole matrix, at the cost of one sector's impulses whatever the valence (the limit masks
/// of a valence-400 vertex need 31 impulses instead of 12,001, and no dense matrix).
struct SectorColumns {
    valence: usize,
    primal: bool,
    /// Items per sector.
    sector_size: usize,
    labels: Vec<(usize, usize, usize)>,
    /// Column of the centre (primal) then of sector 0's items, over all rows.
    columns: Vec<Vec<f64>>,
}

impl SectorColumns {
    fn new(degree: u32, valence: usize) -> Result<SectorColumns> {
        let (labels, columns) = impulse_responses(degree, valence, |(s, _, _)| s == 0, 8)?;
        let primal = degree % 2 == 1;
        let sector_size = (labels.len() - usize::from(primal)) / valence;
        Ok(SectorColumns {
            valence,
            primal,
            sector_size,
            labels,
            columns,
        })
    }

    /// Entry `(row, col)` of the whole matrix: the column's sector is rotated to sector 0, and
    /// the row with it.
    fn entry(&self, row: usize, col: usize) -> f64 {
        let (k, p, off) = (self.valence, self.sector_size, usize::from(self.primal));
        if col < off {
            return self.columns[0][row];
        }
        let (t, b) = ((col - off) / p, (col - off) % p);
        let row = if row < off {
            row
        } else {
            let (s, a) = ((row - off) / p, (row - off) % p);
            off + ((s + k - t) % k) * p + a
        };
        self.columns[off + b][row]
    }

    /// Largest `|l^T A - lambda l^T|` over the measured columns, relative to `max |l|`.
    fn residual(&self, l: &[f64], lambda: f64) -> f64 {
        let scale = l.iter().map(|x| x.abs()).fold(0.0, f64::max);
        (self.columns.iter().enumerate())
            .map(|(c, column)| {
                let lt_a: f64 = l.iter().zip(column).map(|(x, a)| x * a).sum();
                (lt_a - lambda * l[c]).abs()
            })
            .fold(0.0, f64::max)
            / scale
    }
}

/// Fourier block of mode `m` of a rotationally symmetric matrix given by `entry(row, col)`
/// (valence `k`, `p` items per sector, a centre first when `primal`): see [`FourierBlock`].
fn fourier_block(
    k: usize,
    p: usize,
    primal: bool,
    m: usize,
    entry: impl Fn(usize, usize) -> f64,
) -> DMatrix<C64> {
    let w = |e: usize| C64::from_polar(1.0, 2.0 * std::f64::consts::PI * (e % k) as f64 / k as f64);
    let off0 = usize::from(primal);
    let index = |s: usize, a: usize| off0 + (s % k) * p + a;
    let centre = primal && m == 0;
    let off = usize::from(centre);
    let mut b = DMatrix::<C64>::zeros(p + off, p + off);
    for d in 0..k {
        let phase = w(d * m);
        for i in 0..p {
            for j in 0..p {
                b[(off + i, off + j)] += phase * entry(index(0, i), index(d, j));
            }
        }
    }
    if centre {
        b[(0, 0)] = C64::from(entry(0, 0));
        for i in 0..p {
            b[(1 + i, 0)] = C64::from(entry(index(0, i), 0));
            let row: f64 = (0..k).map(|t| entry(0, index(t, i))).sum();
            b[(0, 1 + i)] = C64::from(row);
        }
    }
    b
}

/// Limit masks of one degree at an interior vertex of one valence, over the minimal
/// neighbourhood in the order of this module's neighbourhoods with `rings = N`.
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
    /// points to the side the faces' orientation makes the outside; empty at valence 2, where
    /// the limit surface has no tangent plane in general (see [`vertex_masks`]).
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
/// (its Fourier blocks 0 and 1, built from the centre's and one sector's columns,
/// `SectorColumns`). Every eigenvector is checked against the measured columns.
///
/// Valence 2 (an interior vertex on two faces) gives the position mask only: there the leading
/// eigenvalue after 1 is 1/4 three times over (twice in mode 1, which is real, once in mode 0;
/// every degree), so the first terms after the limit point are three functions decaying alike,
/// whose coefficients span a cone rather than a plane: no tangent masks exist.
pub fn vertex_masks(degree: u32, valence: usize) -> Result<VertexMasks> {
    let internal = |what: &str| {
        Error::Internal(format!(
            "limit masks of degree {degree} at valence {valence}: {what}"
        ))
    };
    let sm = SectorColumns::new(degree, valence)?;
    let (k, p, primal) = (valence, sm.sector_size, sm.primal);
    let blocks: Vec<DMatrix<C64>> = (0..2.min(k))
        .map(|m| fourier_block(k, p, primal, m, |r, c| sm.entry(r, c)))
        .collect();
    let w =
        |e: usize| C64::from_polar(1.0, -2.0 * std::f64::consts::PI * (e % k) as f64 / k as f64);
    // Left eigenvector of block m for eigenvalue `lambda`, spread over the sectors:
    // l(s, a) = w^(-s m) u_a with u^T B_m = lambda u^T (see the derivation in the tests).
    let left = |m: usize, lambda: C64| -> Result<(C64, Vec<C64>)> {
        let bt = blocks[m].transpose();
        let (value, u) = eigenvector(&bt, lambda).ok_or_else(|| internal("no eigenvector"))?;
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
    let residual = |l: &[f64], lambda: f64| sm.residual(l, lambda);

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
    let spectrum = complex_eigenvalues(&blocks[1 % k])
        .ok_or_else(|| internal("the eigenvalue iteration did not converge"))?;
    let (lambda1, sub) = left(1 % k, spectrum[0])?;
    if lambda1.im.abs() > 1e-9 {
        return Err(internal("the subdominant eigenvalue is not real"));
    }
    let lambda1 = lambda1.re;
    let n = neighbourhood_size(degree);
    let minimal = |&(_, i, j): &(usize, usize, usize)| {
        if primal {
            i <= n && j <= n
        } else {
            i < n && j < n
        }
    };
    // Each mask restricted to the minimal neighbourhood; what lies outside must vanish.
    let restrict = |mask: &[f64]| -> Result<Vec<f64>> {
        let mut out = Vec::new();
        for (&m, label) in mask.iter().zip(&sm.labels) {
            if minimal(label) {
                out.push(m);
            } else if m.abs() > 1e-9 {
                return Err(internal("a mask reaches beyond the minimal neighbourhood"));
            }
        }
        Ok(out)
    };
    if k == 2 {
        // Valence 2: mode 1 is real (its eigenvectors have no imaginary part to give a second
        // tangent), and its leading eigenvalue is that of mode 0's second one (1/4 for every
        // degree: the three leading terms after the limit point decay alike), so the limit
        // surface has no tangent plane there in general: the position only.
        return Ok(VertexMasks {
            degree,
            valence,
            lambda1,
            position: restrict(&position)?,
            tangents: [Vec::new(), Vec::new()],
        });
    }
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

    Ok(VertexMasks {
        degree,
        valence,
        lambda1,
        position: restrict(&position)?,
        tangents: [restrict(&t0)?, restrict(&t1)?],
    })
}

/// [`vertex_masks`], computed once per `(degree, valence)` for the whole process.
pub(crate) fn cached_vertex_masks(degree: u32, valence: usize) -> Result<Arc<VertexMasks>> {
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

impl SubdivisionMatrix {
    /// Eigenvalues sorted by decreasing modulus, as (real, imaginary) pairs, from a real Schur
    /// decomposition. Subdivision matrices have large nilpotent parts, on which the QR
    /// iteration stalls at machine precision, so the deflation threshold is relaxed step by step
    /// (to at most 1e-10, which bounds the error of the leading eigenvalues accordingly).
    pub fn eigenvalues(&self) -> Result<Vec<(f64, f64)>> {
        for eps in [1e-13, 1e-12, 1e-11, 1e-10] {
            if let Some(schur) = Schur::try_new(self.matrix.clone(), eps, 20_000) {
                let mut values: Vec<(f64, f64)> = schur
                    .complex_eigenvalues()
                    .iter()
                    .map(|z| (z.re, z.im))
                    .collect();
                values.sort_by(|a, b| b.0.hypot(b.1).total_cmp(&a.0.hypot(a.1)));
                return Ok(values);
            }
        }
        Err(Error::Internal(format!(
            "the eigenvalue iteration did not converge for degree {} valence {}",
            self.degree, self.valence
        )))
    }
}

/// Complex numbers as used by the Fourier blocks.
pub type C64 = Complex<f64>;

/// One diagonal block of the Fourier-transformed subdivision matrix.
#[derive(Debug, Clone)]
pub struct FourierBlock {
    /// Fourier mode `m` (`0..valence`): the block acts on neighbourhood values
    /// `x(s, a) = v(a) w^(s m)`, `w = exp(2 pi i / k)`.
    pub mode: usize,
    /// Labels `(0, i, j)` of the sector-0 items the block's rows and columns stand for (with the
    /// primal centre `(0, 0, 0)` first in mode 0).
    pub labels: Vec<(usize, usize, usize)>,
    /// `B_m = sum_d C_d w^(d m)` with `C_d[a, b] = A[(0, a), (d, b)]`; mode 0 of a primal scheme
    /// adds the centre row and column (the centre row summed over the sectors).
    pub matrix: DMatrix<C64>,
}

/// Eigenvalues of a complex matrix, sorted by decreasing modulus, from a complex Schur
/// decomposition with the deflation threshold relaxed step by step as in
/// [`SubdivisionMatrix::eigenvalues`]. `None` when the iteration does not converge.
pub fn complex_eigenvalues(matrix: &DMatrix<C64>) -> Option<Vec<C64>> {
    if matrix.nrows() == 0 {
        return Some(Vec::new());
    }
    for eps in [1e-14, 1e-13, 1e-12, 1e-11, 1e-10] {
        if let Some(schur) = Schur::try_new(matrix.clone(), eps, 20_000) {
            let t = schur.unpack().1;
            let mut values: Vec<C64> = (0..t.nrows()).map(|i| t[(i, i)]).collect();
            // A 2x2 block left at the very end is not triangularised by the iteration.
            let n = t.nrows();
            if n >= 2 && t[(n - 1, n - 2)].norm() > 0.0 {
                let (a, b, c, d) = (
                    t[(n - 2, n - 2)],
                    t[(n - 2, n - 1)],
                    t[(n - 1, n - 2)],
                    t[(n - 1, n - 1)],
                );
                let half = (a + d) * 0.5;
                let root = ((a - d) * (a - d) * 0.25 + b * c).sqrt();
                values[n - 2] = half + root;
                values[n - 1] = half - root;
            }
            values.sort_by(|a, b| b.norm().total_cmp(&a.norm()));
            return Some(values);
        }
    }
    None
}

/// An eigenvector of `matrix` for the simple eigenvalue near `lambda`, by inverse iteration,
/// normalised to unit length; the eigenvalue is refined by the Rayleigh quotient (whose error is
/// that of the converged residual, far below the Schur iteration's deflation threshold).
pub fn eigenvector(matrix: &DMatrix<C64>, lambda: C64) -> Option<(C64, DVector<C64>)> {
    let n = matrix.nrows();
    let mut value = lambda;
    let mut x = DVector::from_fn(n, |i, _| C64::new(1.0 + 0.1 * i as f64, 0.01 * i as f64));
    x /= C64::from(x.norm());
    for round in 0..3 {
        // A tiny offset keeps the shifted matrix invertible when `value` is exact.
        let shift = value + C64::new(1e-13 * (1.0 + value.norm()), 0.0);
        let shifted = matrix - DMatrix::<C64>::identity(n, n) * shift;
        let lu = shifted.lu();
        for _ in 0..if round == 0 { 4 } else { 2 } {
            x = lu.solve(&x)?;
            let norm = x.norm();
            if !norm.is_finite() || norm == 0.0 {
                return None;
            }
            x /= C64::from(norm);
        }
        value = x.dotc(&(matrix * &x)) / x.dotc(&x);
    }
    let residual = (matrix * &x - &x * value).norm();
    (residual < 1e-9 * (1.0 + matrix.norm())).then_some((value, x))
}

impl SubdivisionMatrix {
    /// Whether the scheme is primal (odd degree: a centre vertex at index 0).
    pub fn is_primal(&self) -> bool {
        self.degree % 2 == 1
    }

    /// Number of items per sector (the size of a Fourier block without the centre).
    pub fn sector_size(&self) -> usize {
        (self.labels.len() - usize::from(self.is_primal())) / self.valence
    }

    /// Index in `labels` of item `a` (`0..sector_size()`) of sector `s`.
    fn index(&self, s: usize, a: usize) -> usize {
        usize::from(self.is_primal()) + (s % self.valence) * self.sector_size() + a
    }

    /// Largest deviation of the matrix from rotational symmetry,
    /// `max |A[(s,a),(t,b)] - A[(0,a),(t-s,b)]|` (and for the centre row and column, their
    /// deviation from being constant over the sectors). Zero up to rounding for the engine's
    /// matrices; the Fourier blocks rely on it.
    pub fn symmetry_defect(&self) -> f64 {
        let (k, p) = (self.valence, self.sector_size());
        let a = &self.matrix;
        let mut defect: f64 = 0.0;
        for s in 0..k {
            for t in 0..k {
                let d = (t + k - s) % k;
                for i in 0..p {
                    for j in 0..p {
                        let x = a[(self.index(s, i), self.index(t, j))];
                        defect = defect.max((x - a[(self.index(0, i), self.index(d, j))]).abs());
                    }
                }
            }
            if self.is_primal() {
                for i in 0..p {
                    defect =
                        defect.max((a[(self.index(s, i), 0)] - a[(self.index(0, i), 0)]).abs());
                    defect =
                        defect.max((a[(0, self.index(s, i))] - a[(0, self.index(0, i))]).abs());
                }
            }
        }
        defect
    }

    /// The `k` diagonal blocks of the Fourier-transformed matrix (see the module documentation),
    /// mode `m` at index `m`.
    pub fn fourier_blocks(&self) -> Vec<FourierBlock> {
        let (k, p, primal) = (self.valence, self.sector_size(), self.is_primal());
        let sector_labels: Vec<_> = (0..p).map(|a| self.labels[self.index(0, a)]).collect();
        (0..k)
            .map(|m| {
                let mut labels = sector_labels.clone();
                if primal && m == 0 {
                    labels.insert(0, (0, 0, 0));
                }
                FourierBlock {
                    mode: m,
                    labels,
                    matrix: fourier_block(k, p, primal, m, |r, c| self.matrix[(r, c)]),
                }
            })
            .collect()
    }

    /// Eigenvalues of each Fourier block (mode `m` at index `m`), sorted by decreasing modulus.
    pub fn block_eigenvalues(&self) -> Result<Vec<Vec<C64>>> {
        self.fourier_blocks()
            .iter()
            .map(|block| {
                complex_eigenvalues(&block.matrix).ok_or_else(|| {
                    Error::Internal(format!(
                        "the eigenvalue iteration did not converge for degree {} valence {} mode {}",
                        self.degree, self.valence, block.mode
                    ))
                })
            })
            .collect()
    }

    /// The spectrum as the union of the blocks' spectra, sorted by decreasing modulus, with the
    /// mode each eigenvalue comes from.
    pub fn eigenvalues_by_blocks(&self) -> Result<Vec<(C64, usize)>> {
        let mut all: Vec<(C64, usize)> = self
            .block_eigenvalues()?
            .into_iter()
            .enumerate()
            .flat_map(|(m, values)| values.into_iter().map(move |z| (z, m)))
            .collect();
        all.sort_by(|a, b| b.0.norm().total_cmp(&a.0.norm()));
        Ok(all)
    }

    /// The paper's checks (see [`Report`]), with the characteristic map refined by `steps`
    /// steps of the engine (4 is a good default: a net of spacing 1/16 on the ring).
    pub fn report(&self, steps: usize) -> Result<Report> {
        let blocks = self.fourier_blocks();
        let spectra = self.block_eigenvalues()?;
        let k = self.valence;
        let dominant = spectra[0][0];
        // lambda0 = 1 simple: the rest of mode 0 and every other mode below 1.
        let others_max = spectra
            .iter()
            .enumerate()
            .flat_map(|(m, v)| v.iter().skip(usize::from(m == 0)))
            .map(|z| z.norm())
            .fold(0.0, f64::max);
        let dominant_simple = (dominant - 1.0).norm() < 1e-9 && others_max < 1.0 - 1e-6;
        let (l1, v1) = eigenvector(&blocks[1].matrix, spectra[1][0]).ok_or_else(|| {
            Error::Internal(format!(
                "no subdominant eigenvector for degree {} valence {k}",
                self.degree
            ))
        })?;
        let l2 = eigenvector(&blocks[k - 1].matrix, spectra[k - 1][0])
            .map_or(spectra[k - 1][0], |e| e.0);
        // The rest of the spectrum: everything but lambda0 and the leading values of modes 1, k-1.
        let mut rest: Vec<(C64, usize)> = spectra
            .iter()
            .enumerate()
            .flat_map(|(m, v)| {
                let skip = usize::from(m == 0 || m == 1 || m == k - 1);
                v.iter().skip(skip).map(move |&z| (z, m))
            })
            .collect();
        rest.sort_by(|a, b| b.0.norm().total_cmp(&a.0.norm()));
        let (third, third_mode) = rest[0];
        let subdominant_real = l1.im.abs() < 1e-9 && l2.im.abs() < 1e-9 && l1.re > 0.0;
        let subdominant_equal = (l1 - l2).norm() < 1e-9;
        let subdominant_simple = spectra[1]
            .get(1)
            .is_none_or(|z| z.norm() < l1.norm() - 1e-6);
        let subdominant_isolated = third.norm() < l1.norm() - 1e-6;
        let map = characteristic_map_from(self, &v1, steps)?;
        let regular = map.jacobian_min > 0.0 || map.jacobian_max < 0.0;
        let sign = if map.jacobian_min > 0.0 { 1 } else { -1 };
        let c1 = dominant_simple
            && subdominant_real
            && subdominant_equal
            && subdominant_simple
            && subdominant_isolated
            && regular
            && map.winding == sign;
        Ok(Report {
            degree: self.degree,
            valence: k,
            dominant,
            dominant_simple,
            subdominant: [l1, l2],
            subdominant_real,
            subdominant_equal,
            subdominant_simple,
            third,
            third_mode,
            subdominant_isolated,
            subdominant_squared: l1.norm_sqr(),
            c2_excluded: third.norm() > l1.norm_sqr() + 1e-9,
            jacobian_min: map.jacobian_min,
            jacobian_max: map.jacobian_max,
            winding: map.winding,
            winding_turns: map.winding_turns,
            regular,
            c1,
            map,
        })
    }
}

/// The paper's checks of §4.3–4.4 for one degree and valence ([`SubdivisionMatrix::report`]).
#[derive(Debug, Clone)]
pub struct Report {
    /// Degree of the scheme.
    pub degree: u32,
    /// Valence.
    pub valence: usize,
    /// `lambda0`, the leading eigenvalue of mode 0 (1 for an affine invariant scheme).
    pub dominant: C64,
    /// `lambda0 = 1` and every other eigenvalue (of every block) has modulus below `1 - 1e-6`.
    pub dominant_simple: bool,
    /// `lambda1, lambda2`: the leading eigenvalues of modes 1 and `k - 1`, refined by inverse
    /// iteration.
    pub subdominant: [C64; 2],
    /// Both are real (imaginary part below 1e-9) and positive.
    pub subdominant_real: bool,
    /// They are equal (to 1e-9).
    pub subdominant_equal: bool,
    /// `lambda1` is a simple eigenvalue of mode 1 (so its Jordan block is trivial).
    pub subdominant_simple: bool,
    /// `lambda3`: the largest remaining eigenvalue (by modulus).
    pub third: C64,
    /// The mode `lambda3` comes from.
    pub third_mode: usize,
    /// `|lambda3| < lambda1` (by more than 1e-6).
    pub subdominant_isolated: bool,
    /// `lambda1^2`.
    pub subdominant_squared: f64,
    /// `|lambda3| > lambda1^2`: the necessary condition for C2 fails (the paper shows this for
    /// valences above 4). For valence 4 the two are equal (the tensor product spectrum).
    pub c2_excluded: bool,
    /// Smallest and largest Jacobian of the characteristic map on the ring (see
    /// [`CharacteristicMap`]).
    pub jacobian_min: f64,
    /// See `jacobian_min`.
    pub jacobian_max: f64,
    /// Winding number of the image of a closed curve in the ring around the origin.
    pub winding: i32,
    /// The same, unrounded (turns).
    pub winding_turns: f64,
    /// The Jacobian has one sign on the ring.
    pub regular: bool,
    /// All of the above: the leading spectrum as required, the map regular and of winding number
    /// equal to the Jacobian's sign (the paper's Theorem 2): C1 at the irregular point. The
    /// Jacobian is that of the refined control net, an approximation (see
    /// [`CharacteristicMap`]), so this is a numerical check, not the paper's interval proof.
    pub c1: bool,
    /// The characteristic map the checks used.
    pub map: CharacteristicMap,
}

impl std::fmt::Display for Report {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let yes = |b: bool| if b { "yes" } else { "no" };
        let [l1, l2] = self.subdominant;
        writeln!(f, "degree {} valence {}", self.degree, self.valence)?;
        writeln!(
            f,
            "lambda0 = {:.9} (simple: {})",
            self.dominant.re,
            yes(self.dominant_simple)
        )?;
        writeln!(
            f,
            "lambda1 = {:.6} (mode 1), lambda2 = {:.6} (mode {}): real {}, equal {}, simple {}",
            l1.re,
            l2.re,
            self.valence - 1,
            yes(self.subdominant_real),
            yes(self.subdominant_equal),
            yes(self.subdominant_simple)
        )?;
        writeln!(
            f,
            "lambda3 = {:.6}{:+.6}i (|lambda3| = {:.6}, mode {}): |lambda3| < lambda1 {}",
            self.third.re,
            self.third.im,
            self.third.norm(),
            self.third_mode,
            yes(self.subdominant_isolated)
        )?;
        writeln!(
            f,
            "characteristic map ({} steps, {}x{} net per sector): Jacobian on the ring in [{:.6}, {:.6}], winding number {} ({:.6} turns)",
            self.map.steps,
            self.map.rows,
            self.map.columns,
            self.jacobian_min,
            self.jacobian_max,
            self.winding,
            self.winding_turns
        )?;
        writeln!(f, "C1: {}", yes(self.c1))?;
        write!(
            f,
            "C2: {} (|lambda3| = {:.6} {} lambda1^2 = {:.6})",
            if self.c2_excluded {
                "no"
            } else {
                "not excluded by this test"
            },
            self.third.norm(),
            if self.c2_excluded { ">" } else { "<=" },
            self.subdominant_squared
        )
    }
}

/// A net refined by the engine around the irregular point, per sector a grid of
/// `rows x columns` values (row `r`, column `c` at `r * columns + c`), `r` along the sector's
/// first edge (`i`), `c` along its second (`j`).
///
/// Grid positions, in units of the level-1 grid (the level the subdivision matrix acts on),
/// spacing `h = 2^-steps`: primal schemes: vertex `(r, c)` at `(r h, c h)`, `(0, 0)` the centre,
/// row 0 the next sector's first edge (shared); dual schemes: face `(i, j)` at
/// `((i + 1/2) h, (j + 1/2) h)` with row `r = i + 1`, row 0 (`i = -1`) taken from the next
/// sector, so that the cells between rows cover the whole sector.
#[derive(Debug, Clone)]
pub struct RefinedNet {
    /// Engine steps after level 1.
    pub steps: usize,
    /// Grid spacing `2^-steps` (level-1 units).
    pub spacing: f64,
    /// Rows per sector.
    pub rows: usize,
    /// Columns per sector.
    pub columns: usize,
    /// `(u, v)` sector coordinates of each grid position (the same for every sector).
    pub params: Vec<[f64; 2]>,
    /// `values[channel][sector][r * columns + c]`.
    pub values: Vec<Vec<Vec<f64>>>,
}

/// Runs `steps` steps of the engine starting at level 1 of a polar cage of valence `valence`,
/// from `channels` sets of values on the neighbourhood of the subdivision matrix (labels and
/// ordering of [`subdivision_matrix`]; every other level-1 value is zero), and reads the refined
/// values up to `extent` (level-1 units) from the centre in each sector.
///
/// With the complete neighbourhood given, the refined values are exact up to `1 + N/2^(steps-1)`
/// level-1 units from the centre (the invariant neighbourhood grows like `N + 2^j`); beyond that
/// they see the zeros outside it. A unit impulse (a basis function) is exact everywhere.
pub fn refine(
    degree: u32,
    valence: usize,
    channels: &[Vec<f64>],
    steps: usize,
    extent: f64,
) -> Result<RefinedNet> {
    if valence < 3 {
        return Err(Error::InvalidInput(format!("valence {valence} is below 3")));
    }
    if !(extent.is_finite() && extent >= 0.0) {
        return Err(Error::InvalidInput(format!(
            "extent {extent} must be finite and at least 0"
        )));
    }
    let n = neighbourhood_size(degree);
    let primal = degree % 2 == 1;
    // Enough rings (level 0) for the data (N + 1 level-1 rings) and the read-out, plus margin.
    let rings = ((extent.max((n + 1) as f64) / 2.0).ceil() as usize).saturating_add(2);
    let cage = polar_cage(valence, rings)?;
    let plan = Refinement::new(
        &cage,
        &Options {
            degree,
            levels: (steps + 1) as u32,
            ..Options::default()
        },
    )?;
    let levels = plan.try_levels()?;
    let level1 = &levels[1];
    let first = level1.corners_of_vertex(0)[0] as usize;
    let items = complete_neighbourhood(level1, first, degree)?;
    let size = if primal {
        level1.num_vertices
    } else {
        level1.num_faces()
    };
    let last = &levels[steps + 1];
    let first_last = first * 4usize.pow(steps as u32);
    // The cage has rings enough for the grid read out: a boundary met is an internal error.
    let boundary = || {
        Error::Internal(format!(
            "the polar cage of valence {valence} must have no boundary within {extent} level-1 \
             units of its centre"
        ))
    };
    let grid = SectorGrid::new(last, first_last).ok_or_else(boundary)?;
    let frame = |s, i, j| grid.frame(s, i, j).ok_or_else(boundary);
    let spacing = 0.5f64.powi(steps as i32);
    let m = (extent / spacing).ceil() as usize;
    let (rows, columns) = if primal { (m + 1, m + 1) } else { (m + 1, m) };
    let mut params = Vec::with_capacity(rows * columns);
    let mut at = vec![Vec::with_capacity(rows * columns); valence];
    for r in 0..rows {
        for c in 0..columns {
            if primal {
                params.push([r as f64 * spacing, c as f64 * spacing]);
            } else {
                params.push([(r as f64 - 0.5) * spacing, (c as f64 + 0.5) * spacing]);
            }
            for (s, at) in at.iter_mut().enumerate() {
                let item = if primal {
                    last.corner_verts[frame(s, r, c)?] as usize
                } else if r == 0 {
                    // Face (s, -1, c) is face (s + 1, c, 0).
                    last.face_of(frame((s + 1) % valence, c, 0)?)
                } else {
                    last.face_of(frame(s, r - 1, c)?)
                };
                at.push(item);
            }
        }
    }
    let values = channels
        .iter()
        .map(|channel| {
            let mut data = vec![0.0; size];
            for (&(_, item), &x) in items.iter().zip(channel) {
                data[item] = x;
            }
            for j in 1..=steps {
                data = step_scalar(&plan, j, &data)?;
            }
            Ok(at
                .iter()
                .map(|at| at.iter().map(|&i| data[i]).collect())
                .collect())
        })
        .collect::<Result<_>>()?;
    Ok(RefinedNet {
        steps,
        spacing,
        rows,
        columns,
        params,
        values,
    })
}

/// The characteristic map of a scheme at one valence: the control net of the subdominant
/// eigenvectors (mode 1: the point of item `(s, a)` is `v(a) w^s` as a complex number, i.e. the
/// pair of the real eigenvectors of `lambda1 = lambda2`), scaled and rotated so that the first
/// level-1 point of sector 0 (`(0, 1, 0)` primal, `(0, 0, 0)` dual) lies at distance one on
/// sector 0's first edge (primal) or bisector (dual), and refined by the engine.
///
/// Regularity is checked on the ring `1/2 <= max(|u|, |v|) <= 1` (level-1 units) of every
/// sector, whose copies under the map's scaling `Phi(y / 2) = lambda1 Phi(y)` cover a punctured
/// neighbourhood of the centre. The Jacobian is approximated on the refined net: each grid cell is
/// mapped bilinearly from its four control points, and the Jacobian `det d(x, y) / d(u, v)` of
/// that bilinear map is taken at the cell's corners (where a bilinear map's Jacobian has its
/// extremes). This converges to the true Jacobian as the net is refined (first order in the
/// spacing), which is a numerical check rather than the paper's guaranteed bounds. The winding
/// number is that of the polygon through the net points at `max(u, v) = 3/4`, all sectors
/// (from the engine's values in each sector, not from symmetry).
#[derive(Debug, Clone)]
pub struct CharacteristicMap {
    /// Degree.
    pub degree: u32,
    /// Valence.
    pub valence: usize,
    /// The subdominant eigenvalue.
    pub lambda: f64,
    /// Engine steps after level 1.
    pub steps: usize,
    /// Grid spacing (level-1 units).
    pub spacing: f64,
    /// Rows of the per-sector grid.
    pub rows: usize,
    /// Columns of the per-sector grid.
    pub columns: usize,
    /// `(u, v)` of each grid position ([`RefinedNet`]).
    pub params: Vec<[f64; 2]>,
    /// `points[sector][r * columns + c]`: the map's control points.
    pub points: Vec<Vec<[f64; 2]>>,
    /// Per cell `(r, c)` of sector 0 (index `r * (columns - 1) + c`), the smallest and largest
    /// corner Jacobian; cells outside the ring are included (the ring is `in_ring`).
    pub cell_jacobian: Vec<[f64; 2]>,
    /// Whether each cell of `cell_jacobian` lies in the ring (its centre does).
    pub in_ring: Vec<bool>,
    /// Smallest Jacobian on the ring, over all sectors.
    pub jacobian_min: f64,
    /// Largest Jacobian on the ring, over all sectors.
    pub jacobian_max: f64,
    /// Winding number of the image of the curve `max(u, v) = 3/4` around the origin.
    pub winding: i32,
    /// The same, unrounded.
    pub winding_turns: f64,
}

/// The characteristic map of `degree` at `valence`, refined by `steps` engine steps.
pub fn characteristic_map(degree: u32, valence: usize, steps: usize) -> Result<CharacteristicMap> {
    let matrix = subdivision_matrix(degree, valence)?;
    let blocks = matrix.fourier_blocks();
    let lambda = complex_eigenvalues(&blocks[1].matrix)
        .ok_or_else(|| Error::Internal("the eigenvalue iteration did not converge".into()))?[0];
    let (_, v) = eigenvector(&blocks[1].matrix, lambda)
        .ok_or_else(|| Error::Internal("no subdominant eigenvector".into()))?;
    characteristic_map_from(&matrix, &v, steps)
}

fn characteristic_map_from(
    matrix: &SubdivisionMatrix,
    v: &DVector<C64>,
    steps: usize,
) -> Result<CharacteristicMap> {
    let (k, p, primal) = (matrix.valence, matrix.sector_size(), matrix.is_primal());
    let b1 = &matrix.fourier_blocks()[1].matrix;
    let lambda = (v.dotc(&(b1 * v)) / v.dotc(v)).re;
    // Normalise: the first point of sector 0 at distance one, on the first edge (primal: item
    // (0, 1, 0) is the first of the sector) or the bisector (dual: item (0, 0, 0)).
    let angle = if primal {
        0.0
    } else {
        std::f64::consts::PI / k as f64
    };
    let scale = C64::from_polar(1.0, angle) / v[0];
    let w = |s: usize| C64::from_polar(1.0, 2.0 * std::f64::consts::PI * s as f64 / k as f64);
    let mut re = vec![0.0; matrix.labels.len()];
    let mut im = vec![0.0; matrix.labels.len()];
    for s in 0..k {
        for a in 0..p {
            let z = v[a] * scale * w(s);
            re[matrix.index(s, a)] = z.re;
            im[matrix.index(s, a)] = z.im;
        }
    }
    let net = refine(matrix.degree, k, &[re, im], steps, 1.0 + 1e-9)?;
    let (rows, columns, h) = (net.rows, net.columns, net.spacing);
    let points: Vec<Vec<[f64; 2]>> = (0..k)
        .map(|s| {
            net.values[0][s]
                .iter()
                .zip(&net.values[1][s])
                .map(|(&x, &y)| [x, y])
                .collect()
        })
        .collect();
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        ((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])) / (h * h)
    };
    let cells = |pts: &Vec<[f64; 2]>| -> Vec<[f64; 2]> {
        let mut out = Vec::with_capacity((rows - 1) * (columns - 1));
        for r in 0..rows - 1 {
            for c in 0..columns - 1 {
                let q = |dr: usize, dc: usize| pts[(r + dr) * columns + c + dc];
                let js = [
                    cross(q(0, 0), q(1, 0), q(0, 1)),
                    cross(q(1, 0), q(1, 1), q(0, 0)),
                    cross(q(1, 1), q(0, 1), q(1, 0)),
                    cross(q(0, 1), q(0, 0), q(1, 1)),
                ];
                out.push([
                    js.iter().copied().fold(f64::INFINITY, f64::min),
                    js.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                ]);
            }
        }
        out
    };
    let mut in_ring = Vec::with_capacity((rows - 1) * (columns - 1));
    for r in 0..rows - 1 {
        for c in 0..columns - 1 {
            let [u0, v0] = net.params[r * columns + c];
            let (u, v) = (u0 + h / 2.0, v0 + h / 2.0);
            let rho = u.abs().max(v.abs());
            in_ring.push((0.5..=1.0).contains(&rho));
        }
    }
    let mut jacobian_min = f64::INFINITY;
    let mut jacobian_max = f64::NEG_INFINITY;
    let mut cell_jacobian = Vec::new();
    for (s, pts) in points.iter().enumerate() {
        let js = cells(pts);
        for (j, &inside) in js.iter().zip(&in_ring) {
            if inside {
                jacobian_min = jacobian_min.min(j[0]);
                jacobian_max = jacobian_max.max(j[1]);
            }
        }
        if s == 0 {
            cell_jacobian = js;
        }
    }
    // The closed curve max(u, v) = 3/4: in each sector, up the row r = R, then back along the
    // column c = R; the next sector continues where this one ends.
    let ring = (0.75 / h).round() as usize;
    let (r0, c0) = if primal {
        (ring, ring)
    } else {
        (ring + 1, ring)
    };
    let mut curve = Vec::new();
    for pts in &points {
        for c in 0..=c0 {
            curve.push(pts[r0 * columns + c]);
        }
        let lowest = 1; // primal: row 0 is the next sector's edge; dual: row 0 is the next sector
        for r in (lowest..r0).rev() {
            curve.push(pts[r * columns + c0]);
        }
    }
    let mut turns = 0.0;
    for (i, a) in curve.iter().enumerate() {
        let b = curve[(i + 1) % curve.len()];
        let za = C64::new(a[0], a[1]);
        let zb = C64::new(b[0], b[1]);
        turns += (zb / za).arg();
    }
    let winding_turns = turns / (2.0 * std::f64::consts::PI);
    Ok(CharacteristicMap {
        degree: matrix.degree,
        valence: k,
        lambda,
        steps,
        spacing: h,
        rows,
        columns,
        params: net.params,
        points,
        cell_jacobian,
        in_ring,
        jacobian_min,
        jacobian_max,
        winding: winding_turns.round() as i32,
        winding_turns,
    })
}

/// The basis function of the level-1 item `label` (the centre `(0, 0, 0)` of a primal scheme, a
/// face of the k-gon `(0, 0, 0)` of a dual one, or any other label of [`subdivision_matrix`]):
/// a unit impulse refined by `steps` engine steps, read out over its whole support.
pub fn basis_function(
    degree: u32,
    valence: usize,
    label: (usize, usize, usize),
    steps: usize,
) -> Result<RefinedNet> {
    let matrix_labels = {
        // The labels without building the matrix: the same neighbourhood walk.
        let n = neighbourhood_size(degree);
        let mut labels = Vec::new();
        if degree.is_multiple_of(2) {
            for s in 0..valence {
                for i in 0..=n {
                    for j in 0..=n {
                        labels.push((s, i, j));
                    }
                }
            }
        } else {
            labels.push((0, 0, 0));
            for s in 0..valence {
                for i in 1..=n + 1 {
                    for j in 0..=n + 1 {
                        labels.push((s, i, j));
                    }
                }
            }
        }
        labels
    };
    let Some(index) = matrix_labels.iter().position(|&l| l == label) else {
        return Err(Error::InvalidInput(format!(
            "no item {label:?} in the neighbourhood"
        )));
    };
    let mut impulse = vec![0.0; matrix_labels.len()];
    impulse[index] = 1.0;
    // The support of a level-1 basis function reaches about N + 2 level-1 rings out.
    let extent = (neighbourhood_size(degree) + 2) as f64;
    refine(degree, valence, &[impulse], steps, extent)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The limit masks' Fourier blocks from the centre's and one sector's columns equal those
    /// of the whole matrix up to rounding (the sums run over rotated copies of the same
    /// entries: a different order, so not bit for bit; the limits move by ~1e-15 relative).
    #[test]
    fn sector_columns_give_the_whole_matrix_blocks() {
        for degree in 2..=9u32 {
            for valence in [3, 5, 7] {
                let whole = subdivision_matrix(degree, valence).unwrap();
                let sector = SectorColumns::new(degree, valence).unwrap();
                assert_eq!(sector.labels, whole.labels);
                let (k, p) = (valence, whole.sector_size());
                for (m, block) in whole.fourier_blocks().iter().take(2).enumerate() {
                    let b = fourier_block(k, p, whole.is_primal(), m, |r, c| sector.entry(r, c));
                    let defect = (&b - &block.matrix)
                        .iter()
                        .map(|z| z.norm())
                        .fold(0.0, f64::max);
                    assert!(
                        defect < 1e-13,
                        "degree {degree} valence {valence} mode {m}: {defect}"
                    );
                }
            }
        }
    }
}
