//! Refined topology, one complete mesh per level in flat structure-of-arrays tables (the idea of
//! OpenSubdiv's `Vtr::Level`): `M_0` is built from the cage (and checked for manifold edges and
//! consistent orientation); `M_{j+1}` is `M_j` split Catmull-Clark style, its vertices the old
//! vertices, then one per edge, then one per face, its faces one quad per *corner* of `M_j`.
//!
//! Every table of `M_{j+1}` is a gather from `M_j`'s tables, computed in parallel; nothing here
//! depends on the order in which threads run.

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::mesh::Cage;

/// Marks a missing entry (the second face of a boundary edge).
pub const NONE: u32 = u32::MAX;

/// Items per parallel task in the gathers (large enough to amortise scheduling).
pub(crate) const CHUNK: usize = 1 << 12;

/// One level of refinement: a polygon mesh as flat index tables.
///
/// A *corner* is a (vertex, face) incidence; corners are numbered face after face, so the
/// corners of face `f` are `face_offsets[f]..face_offsets[f + 1]` (or `4f..4f + 4` on quad levels).
#[derive(Debug, Clone, Default)]
pub struct Level {
    /// Number of vertices.
    pub num_vertices: usize,
    /// Face offsets into the corner tables (length faces + 1); empty on quad levels.
    pub face_offsets: Vec<u32>,
    /// Face of each corner; empty on quad levels (where it is `corner / 4`).
    pub corner_faces: Vec<u32>,
    /// Vertex of each corner.
    pub corner_verts: Vec<u32>,
    /// Edge from each corner to the next corner of its face.
    pub corner_edges: Vec<u32>,
    /// The two vertices of each edge.
    pub edge_verts: Vec<[u32; 2]>,
    /// The corners whose outgoing edge is this edge, one per incident face; `NONE` on a boundary.
    pub edge_corners: Vec<[u32; 2]>,
    /// Offsets of each vertex's corners in `vert_corners` (length vertices + 1).
    pub vert_corner_offsets: Vec<u32>,
    /// The corners at each vertex, in increasing order of corner.
    pub vert_corners: Vec<u32>,
}

impl Level {
    /// True when every face is a quad (every level after the first).
    #[inline]
    pub fn is_quads(&self) -> bool {
        self.face_offsets.is_empty()
    }

    /// Number of faces.
    pub fn num_faces(&self) -> usize {
        if self.is_quads() {
            self.corner_verts.len() / 4
        } else {
            self.face_offsets.len() - 1
        }
    }

    /// Number of corners (face-vertex incidences).
    #[inline]
    pub fn num_corners(&self) -> usize {
        self.corner_verts.len()
    }

    /// Number of edges.
    #[inline]
    pub fn num_edges(&self) -> usize {
        self.edge_verts.len()
    }

    /// The face a corner belongs to.
    #[inline]
    pub fn face_of(&self, corner: usize) -> usize {
        if self.is_quads() {
            corner >> 2
        } else {
            self.corner_faces[corner] as usize
        }
    }

    /// The corners of face `f`.
    #[inline]
    pub fn face_corners(&self, f: usize) -> std::ops::Range<usize> {
        if self.is_quads() {
            4 * f..4 * f + 4
        } else {
            self.face_offsets[f] as usize..self.face_offsets[f + 1] as usize
        }
    }

    /// The next corner around the face of `corner`.
    #[inline]
    pub fn next(&self, corner: usize) -> usize {
        if self.is_quads() {
            (corner & !3) | ((corner + 1) & 3)
        } else {
            let r = self.face_corners(self.corner_faces[corner] as usize);
            if corner + 1 == r.end {
                r.start
            } else {
                corner + 1
            }
        }
    }

    /// The previous corner around the face of `corner`.
    #[inline]
    pub fn prev(&self, corner: usize) -> usize {
        if self.is_quads() {
            (corner & !3) | ((corner + 3) & 3)
        } else {
            let r = self.face_corners(self.corner_faces[corner] as usize);
            if corner == r.start {
                r.end - 1
            } else {
                corner - 1
            }
        }
    }

    /// The corners at vertex `v`.
    #[inline]
    pub fn corners_of_vertex(&self, v: usize) -> &[u32] {
        &self.vert_corners
            [self.vert_corner_offsets[v] as usize..self.vert_corner_offsets[v + 1] as usize]
    }

    /// True if edge `e` has a single face.
    #[inline]
    pub fn is_boundary_edge(&self, e: usize) -> bool {
        self.edge_corners[e][1] == NONE
    }

    /// The child edge of `e` (at the next level) that contains the endpoint `v` of `e`.
    #[inline]
    fn child_half(&self, e: u32, v: u32) -> u32 {
        2 * e + (self.edge_verts[e as usize][0] != v) as u32
    }

    /// Builds a level from polygons (all vertices used), finding its edges. Fails with the
    /// corners involved if an edge has more than two faces or two faces traverse it the same way.
    pub fn from_polygons(
        num_vertices: usize,
        face_offsets: Vec<u32>,
        corner_verts: Vec<u32>,
    ) -> std::result::Result<Level, EdgeProblem> {
        let num_faces = face_offsets.len() - 1;
        let num_corners = corner_verts.len();
        let mut corner_faces = vec![0u32; num_corners];
        for f in 0..num_faces {
            corner_faces[face_offsets[f] as usize..face_offsets[f + 1] as usize].fill(f as u32);
        }
        let mut level = Level {
            num_vertices,
            face_offsets,
            corner_faces,
            corner_verts,
            ..Level::default()
        };

        // Half-edges sorted by their undirected key, so that equal edges are adjacent and edge
        // ids come out in a fixed order.
        let mut halves: Vec<(u64, u32)> = (0..num_corners)
            .into_par_iter()
            .map(|c| {
                let a = level.corner_verts[c];
                let b = level.corner_verts[level.next(c)];
                (((a.min(b) as u64) << 32) | a.max(b) as u64, c as u32)
            })
            .collect();
        halves.par_sort_unstable();

        let mut corner_edges = vec![0u32; num_corners];
        let mut edge_verts = Vec::with_capacity(num_corners / 2 + 1);
        let mut edge_corners = Vec::with_capacity(num_corners / 2 + 1);
        let mut i = 0;
        while i < halves.len() {
            let mut j = i + 1;
            while j < halves.len() && halves[j].0 == halves[i].0 {
                j += 1;
            }
            let c0 = halves[i].1 as usize;
            if j - i > 2 {
                return Err(EdgeProblem::NonManifold {
                    corner: c0,
                    faces: j - i,
                });
            }
            let mut slots = [c0 as u32, NONE];
            if j - i == 2 {
                let c1 = halves[i + 1].1 as usize;
                if level.corner_verts[c1] == level.corner_verts[c0] {
                    return Err(EdgeProblem::Orientation { corners: [c0, c1] });
                }
                slots[1] = c1 as u32;
            }
            let e = edge_verts.len() as u32;
            for &(_, c) in &halves[i..j] {
                corner_edges[c as usize] = e;
            }
            edge_verts.push([level.corner_verts[c0], level.corner_verts[level.next(c0)]]);
            edge_corners.push(slots);
            i = j;
        }
        level.corner_edges = corner_edges;
        level.edge_verts = edge_verts;
        level.edge_corners = edge_corners;

        // Vertex -> corners by counting sort (corners in increasing order).
        let mut offsets = vec![0u32; num_vertices + 1];
        for &v in &level.corner_verts {
            offsets[v as usize + 1] += 1;
        }
        for v in 0..num_vertices {
            offsets[v + 1] += offsets[v];
        }
        let mut fill = offsets.clone();
        let mut vert_corners = vec![0u32; num_corners];
        for (c, &v) in level.corner_verts.iter().enumerate() {
            vert_corners[fill[v as usize] as usize] = c as u32;
            fill[v as usize] += 1;
        }
        level.vert_corner_offsets = offsets;
        level.vert_corners = vert_corners;
        Ok(level)
    }

    /// Builds the first level from a cage, with `corner_verts` renumbered so that every vertex
    /// is used; errors name the cage's own vertex ids and faces.
    pub fn from_cage(cage: &Cage, num_vertices: usize, corner_verts: Vec<u32>) -> Result<Level> {
        let offsets = cage.face_offsets().to_vec();
        let verts = cage.face_vertices();
        let face_of = |c: usize| offsets.partition_point(|&o| o as usize <= c) - 1;
        let next = |c: usize| {
            let f = face_of(c);
            if c + 1 == offsets[f + 1] as usize {
                offsets[f] as usize
            } else {
                c + 1
            }
        };
        Level::from_polygons(num_vertices, offsets.clone(), corner_verts).map_err(|problem| {
            match problem {
                EdgeProblem::NonManifold { corner, faces } => Error::NonManifoldEdge {
                    a: verts[corner] as usize,
                    b: verts[next(corner)] as usize,
                    faces,
                },
                EdgeProblem::Orientation { corners: [c0, c1] } => Error::InconsistentOrientation {
                    a: verts[c0] as usize,
                    b: verts[next(c0)] as usize,
                    face_a: face_of(c0),
                    face_b: face_of(c1),
                },
            }
        })
    }

    /// Splits this level once: the quad of corner `c = (v, f)` is
    /// `v, edge(c), face(f), edge(prev(c))`, and the new vertices are numbered old vertices,
    /// then edge points (`V + e`), then face points (`V + E + f`).
    ///
    /// Child edges: `2e` and `2e + 1` are the halves of edge `e` (containing its first and second
    /// vertex), `2E + c` joins the edge point of `c`'s outgoing edge to the face point.
    pub fn refine(&self) -> Level {
        let nv = self.num_vertices as u32;
        let ne = self.num_edges() as u32;
        let nc = self.num_corners();
        let new_vertices = self.num_vertices + self.num_edges() + self.num_faces();

        let mut corner_verts = vec![0u32; 4 * nc];
        let mut corner_edges = vec![0u32; 4 * nc];
        corner_verts
            .par_chunks_mut(4 * CHUNK)
            .zip(corner_edges.par_chunks_mut(4 * CHUNK))
            .enumerate()
            .for_each(|(chunk, (verts, edges))| {
                let base = chunk * CHUNK;
                for (i, (qv, qe)) in verts
                    .chunks_exact_mut(4)
                    .zip(edges.chunks_exact_mut(4))
                    .enumerate()
                {
                    let c = base + i;
                    let v = self.corner_verts[c];
                    let p = self.prev(c);
                    let e_next = self.corner_edges[c];
                    let e_prev = self.corner_edges[p];
                    let f = self.face_of(c) as u32;
                    qv.copy_from_slice(&[v, nv + e_next, nv + ne + f, nv + e_prev]);
                    qe.copy_from_slice(&[
                        self.child_half(e_next, v),
                        2 * ne + c as u32,
                        2 * ne + p as u32,
                        self.child_half(e_prev, v),
                    ]);
                }
            });

        // Edges: the two halves of every old edge, then one interior edge per old corner.
        let total_edges = 2 * ne as usize + nc;
        let mut edge_verts = vec![[0u32; 2]; total_edges];
        let mut edge_corners = vec![[NONE; 2]; total_edges];
        {
            let (half_verts, inner_verts) = edge_verts.split_at_mut(2 * ne as usize);
            let (half_corners, inner_corners) = edge_corners.split_at_mut(2 * ne as usize);
            half_verts
                .par_chunks_mut(2 * CHUNK)
                .zip(half_corners.par_chunks_mut(2 * CHUNK))
                .enumerate()
                .for_each(|(chunk, (hv, hc))| {
                    for (i, (v2, c2)) in hv
                        .chunks_exact_mut(2)
                        .zip(hc.chunks_exact_mut(2))
                        .enumerate()
                    {
                        let e = chunk * CHUNK + i;
                        let [a, b] = self.edge_verts[e];
                        let mid = nv + e as u32;
                        v2[0] = [a, mid];
                        v2[1] = [mid, b];
                        for (slot, &c) in self.edge_corners[e].iter().enumerate() {
                            if c == NONE {
                                continue;
                            }
                            let c = c as usize;
                            let leaving = 4 * c as u32;
                            let arriving = 4 * self.next(c) as u32 + 3;
                            if self.corner_verts[c] == a {
                                c2[0][slot] = leaving;
                                c2[1][slot] = arriving;
                            } else {
                                c2[1][slot] = leaving;
                                c2[0][slot] = arriving;
                            }
                        }
                    }
                });
            inner_verts
                .par_chunks_mut(CHUNK)
                .zip(inner_corners.par_chunks_mut(CHUNK))
                .enumerate()
                .for_each(|(chunk, (iv, ic))| {
                    for (i, (v2, c2)) in iv.iter_mut().zip(ic.iter_mut()).enumerate() {
                        let c = chunk * CHUNK + i;
                        *v2 = [nv + self.corner_edges[c], nv + ne + self.face_of(c) as u32];
                        *c2 = [4 * c as u32 + 1, 4 * self.next(c) as u32 + 2];
                    }
                });
        }

        // Vertex -> corners: an old vertex keeps one corner per old corner, an edge point has
        // two per incident face, a face point one per corner of its face.
        let count = |w: usize| -> u32 {
            if w < self.num_vertices {
                self.corners_of_vertex(w).len() as u32
            } else if w < self.num_vertices + ne as usize {
                let e = w - self.num_vertices;
                if self.is_boundary_edge(e) {
                    2
                } else {
                    4
                }
            } else {
                self.face_corners(w - self.num_vertices - ne as usize).len() as u32
            }
        };
        let mut offsets = vec![0u32; new_vertices + 1];
        offsets[1..]
            .par_iter_mut()
            .enumerate()
            .for_each(|(w, o)| *o = count(w));
        for w in 0..new_vertices {
            offsets[w + 1] += offsets[w];
        }
        let mut vert_corners = vec![0u32; 4 * nc];
        fill_csr(&offsets, &mut vert_corners, |w, out| {
            if w < self.num_vertices {
                for (o, &c) in out.iter_mut().zip(self.corners_of_vertex(w)) {
                    *o = 4 * c;
                }
            } else if w < self.num_vertices + ne as usize {
                let e = w - self.num_vertices;
                let mut k = 0;
                for &c in &self.edge_corners[e] {
                    if c != NONE {
                        out[k] = 4 * c + 1;
                        out[k + 1] = 4 * self.next(c as usize) as u32 + 3;
                        k += 2;
                    }
                }
            } else {
                let f = w - self.num_vertices - ne as usize;
                for (o, c) in out.iter_mut().zip(self.face_corners(f)) {
                    *o = 4 * c as u32 + 2;
                }
            }
        });

        Level {
            num_vertices: new_vertices,
            face_offsets: Vec::new(),
            corner_faces: Vec::new(),
            corner_verts,
            corner_edges,
            edge_verts,
            edge_corners,
            vert_corner_offsets: offsets,
            vert_corners,
        }
    }
}

/// Why a set of polygons is not an oriented 2-manifold along its edges.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EdgeProblem {
    /// The edge leaving `corner` has `faces` faces.
    NonManifold { corner: usize, faces: usize },
    /// The two corners traverse their shared edge in the same direction.
    Orientation { corners: [usize; 2] },
}

/// Fills a CSR table in parallel: `fill(item, slice)` writes the entries of `item`, whose slice
/// is `offsets[item]..offsets[item + 1]`. Items are split into fixed chunks, so the result does
/// not depend on the thread count.
pub(crate) fn fill_csr<T: Send>(
    offsets: &[u32],
    data: &mut [T],
    fill: impl Fn(usize, &mut [T]) + Sync,
) {
    let items = offsets.len() - 1;
    let mut pieces = Vec::with_capacity(items / CHUNK + 1);
    let mut rest = data;
    let mut start = 0;
    while start < items {
        let end = (start + CHUNK).min(items);
        let (piece, tail) = rest.split_at_mut((offsets[end] - offsets[start]) as usize);
        pieces.push((start, end, piece));
        rest = tail;
        start = end;
    }
    pieces.into_par_iter().for_each(|(start, end, piece)| {
        let base = offsets[start] as usize;
        for item in start..end {
            let range = offsets[item] as usize - base..offsets[item + 1] as usize - base;
            fill(item, &mut piece[range]);
        }
    });
}
