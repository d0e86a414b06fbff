//! Analysis of the schemes (the paper's §4), computed from the engine itself: the subdivision
//! matrix of the invariant neighbourhood of an irregular vertex (odd degrees) or face (even
//! degrees) of valence k, obtained by running unit impulses through one step of a plan, and its
//! eigenvalues.
//!
//! Ordering of the neighbourhood (the paper's Fig. 16). Let `N = degree / 2` (even degrees) or
//! `(degree - 1) / 2` (odd). The neighbourhood is split into `k` sectors `s = 0..k`, counter-
//! clockwise around the centre; within a sector, grid positions `(i, j)` count steps along the
//! sector's first edge (`i`) and its second edge (`j`).
//! - Even degrees (dual data, one value per face): faces `(s, i, j)`, `0 <= i, j <= N`, at index
//!   `s (N+1)^2 + i (N+1) + j`; face `(s, 0, 0)` touches the centre vertex (the k-gon of the dual).
//! - Odd degrees (primal data, one value per vertex): the centre at index 0, then vertices
//!   `(s, i, j)`, `1 <= i <= N+1`, `0 <= j <= N+1`, at `1 + s (N+1)(N+2) + (i-1)(N+2) + j`.

use nalgebra::{DMatrix, Schur};

use crate::error::{Error, Result};
use crate::mesh::Cage;
use crate::plan::{Options, Plan};
use crate::topology::{Level, NONE};

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
    (if degree % 2 == 0 {
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
    let mut faces = Vec::with_capacity(4 * valence * r * r);
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
    Cage::from_indices(1 + valence * r * (r + 1), &vec![4; valence * r * r], &faces)
}

/// Walks the quad grid around vertex `centre` of a quad level: `frames(s, i, j)` is the corner
/// at grid vertex `(i, j)` of the face `(i, j)` of sector `s`, oriented so that its next corner
/// is `(i+1, j)` and its previous `(i, j+1)`.
struct SectorGrid<'a> {
    level: &'a Level,
    starts: Vec<usize>,
}

impl<'a> SectorGrid<'a> {
    /// Sectors counter-clockwise from `first`, a corner at the centre.
    fn new(level: &'a Level, first: usize) -> SectorGrid<'a> {
        let mut starts = vec![first];
        loop {
            let last = *starts.last().expect("a sector");
            // The next sector lies across the incoming edge of this sector's corner.
            let next = other_corner(
                level,
                level.corner_edges[level.prev(last)] as usize,
                level.prev(last),
            );
            if next == first {
                break;
            }
            starts.push(next);
        }
        SectorGrid { level, starts }
    }

    fn frame(&self, s: usize, i: usize, j: usize) -> usize {
        let l = self.level;
        let mut o = self.starts[s];
        for _ in 0..i {
            let n = l.next(o);
            o = l.next(other_corner(l, l.corner_edges[n] as usize, n));
        }
        for _ in 0..j {
            let n2 = l.next(l.next(o));
            o = other_corner(l, l.corner_edges[n2] as usize, n2);
        }
        o
    }
}

/// The corner on the other side of edge `e` from corner `c`.
fn other_corner(level: &Level, e: usize, c: usize) -> usize {
    let [a, b] = level.edge_corners[e];
    let other = if a as usize == c { b } else { a };
    assert!(
        other != NONE,
        "the analysis cage is large enough to have no boundary nearby"
    );
    other as usize
}

/// Labels and level indices of the neighbourhood around vertex 0 of `level`, whose first corner
/// at the centre is `first`.
fn neighbourhood(level: &Level, first: usize, degree: u32) -> Vec<((usize, usize, usize), usize)> {
    let n = neighbourhood_size(degree);
    let grid = SectorGrid::new(level, first);
    let mut items = Vec::new();
    if degree % 2 == 0 {
        for s in 0..grid.starts.len() {
            for i in 0..=n {
                for j in 0..=n {
                    items.push(((s, i, j), level.face_of(grid.frame(s, i, j))));
                }
            }
        }
    } else {
        items.push(((0, 0, 0), level.corner_verts[first] as usize));
        for s in 0..grid.starts.len() {
            for i in 1..=n + 1 {
                for j in 0..=n + 1 {
                    items.push(((s, i, j), level.corner_verts[grid.frame(s, i, j)] as usize));
                }
            }
        }
    }
    items
}

/// The subdivision matrix of degree `degree` around an irregular vertex or face of valence
/// `valence`, built by running unit impulses through one step of the engine (level 1 to 2 of
/// a polar cage, far from its boundary).
pub fn subdivision_matrix(degree: u32, valence: usize) -> Result<SubdivisionMatrix> {
    if valence < 3 {
        return Err(Error::InvalidInput(format!("valence {valence} is below 3")));
    }
    let n = neighbourhood_size(degree);
    let cage = polar_cage(valence, n + 3)?;
    let plan = Plan::new(
        &cage,
        &Options {
            degree,
            levels: 2,
            ..Options::default()
        },
    )?;
    let (coarse, fine) = (&plan.levels()[1], &plan.levels()[2]);
    // The centre keeps id 0 at every level; its child corners are 4c for its coarse corners c.
    let first = coarse.corners_of_vertex(0)[0] as usize;
    let columns = neighbourhood(coarse, first, degree);
    let rows = neighbourhood(fine, 4 * first, degree);
    let size = if degree % 2 == 0 {
        coarse.num_faces()
    } else {
        coarse.num_vertices
    };
    let mut matrix = DMatrix::zeros(rows.len(), columns.len());
    let mut impulse = vec![0.0; size];
    for (col, &(_, item)) in columns.iter().enumerate() {
        impulse[item] = 1.0;
        let out = plan.step_scalar(1, &impulse);
        impulse[item] = 0.0;
        for (row, &(_, at)) in rows.iter().enumerate() {
            matrix[(row, col)] = out[at];
        }
    }
    Ok(SubdivisionMatrix {
        degree,
        valence,
        labels: rows.into_iter().map(|r| r.0).collect(),
        matrix,
    })
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
