//! Refined topology, one complete mesh per level in flat structure-of-arrays tables (the idea of
//! OpenSubdiv's `Vtr::Level`): `M_0` is built from the cage (and checked for manifold edges and
//! consistent orientation); `M_{j+1}` is `M_j` split Catmull-Clark style, its vertices the old
//! vertices, then one per edge, then one per face, its faces one quad per *corner* of `M_j`.
//!
//! Every table of `M_{j+1}` is a gather from `M_j`'s tables, computed in parallel; nothing here
//! depends on the order in which threads run. The last level of a plan is built with its faces
//! only (as OpenSubdiv's `fullTopologyInLastLevel = false`): evaluation never reads its edges,
//! which [`Level::complete_from`] adds, in the same numbering, when something asks for them.

use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::OnceLock;

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::mesh::Cage;
use crate::parallel::{
    fill_csr, gather_hinted, prefix_offsets, with_capacity_hinted, zeroed_hinted, CHUNK,
};

/// Marks a missing entry (the second face of a boundary edge).
pub(crate) const NONE: u32 = u32::MAX;

/// The edges of a level and their incidences.
#[derive(Debug, Clone, Default)]
pub(crate) struct Edges {
    /// Edge from each corner to the next corner of its face.
    pub(crate) corner_edges: Vec<u32>,
    /// The two vertices of each edge.
    pub(crate) verts: Vec<[u32; 2]>,
    /// The corners whose outgoing edge is this edge, one per incident face; `NONE` on a boundary.
    pub(crate) corners: Vec<[u32; 2]>,
}

/// One level of refinement: a polygon mesh as flat index tables.
///
/// A *corner* is a (vertex, face) incidence; corners are numbered face after face, so the
/// corners of face `f` are `face_offsets[f]..face_offsets[f + 1]` (or `4f..4f + 4` on quad levels).
#[derive(Debug, Clone, Default)]
pub struct Level {
    /// Number of vertices.
    pub(crate) num_vertices: usize,
    /// Face offsets into the corner tables (length faces + 1); empty on quad levels.
    pub(crate) face_offsets: Vec<u32>,
    /// Face of each corner; empty on quad levels (where it is `corner / 4`).
    pub(crate) corner_faces: Vec<u32>,
    /// Vertex of each corner.
    pub(crate) corner_verts: Vec<u32>,
    /// Number of edges (known before the edge tables are).
    num_edges: usize,
    /// The edge tables; left empty by [`Level::refine_faces`] until [`Level::complete_from`].
    edges: OnceLock<Edges>,
    /// Offsets of each vertex's corners in `vert_corners` (length vertices + 1). This table and
    /// `vert_corners` are empty on the last level of a plan whose output is the drawing mesh
    /// (see [`Level::refine_faces`]).
    pub(crate) vert_corner_offsets: Vec<u32>,
    /// The corners at each vertex: in increasing order on the cage level and for old vertices
    /// and face points of refined levels; an edge point lists, for each of its edge's corner
    /// slots in turn, the two child corners of that slot (evaluation sums in this order, and
    /// the adaptive partial levels reproduce it).
    pub(crate) vert_corners: Vec<u32>,
    /// `(vert_corner_offsets, vert_corners)` built on first use by [`Level::corners_of_vertex`]
    /// when the tables above were left out.
    lazy_vertex_corners: OnceLock<(Vec<u32>, Vec<u32>)>,
}

impl Level {
    /// Number of vertices.
    #[inline]
    pub fn num_vertices(&self) -> usize {
        self.num_vertices
    }

    /// Vertex of each corner (corners are numbered face after face).
    #[inline]
    pub fn corner_verts(&self) -> &[u32] {
        &self.corner_verts
    }

    /// Marks a missing corner in [`Level::edge_corners`] (the second face of a boundary edge).
    pub const NONE: u32 = NONE;

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
        self.num_edges
    }

    /// The edge tables. Panics on the faces-only last level of a plan before
    /// [`Level::complete_from`] (`Plan::levels` completes it; only evaluation sees it bare).
    #[inline]
    pub(crate) fn edges(&self) -> &Edges {
        self.edges
            .get()
            .expect("edge tables of a faces-only level are built by Level::complete_from")
    }

    /// Edge from each corner to the next corner of its face.
    #[inline]
    pub fn corner_edges(&self) -> &[u32] {
        &self.edges().corner_edges
    }

    /// The two vertices of each edge.
    #[inline]
    pub fn edge_verts(&self) -> &[[u32; 2]] {
        &self.edges().verts
    }

    /// The corners whose outgoing edge is each edge, one per incident face; `NONE` on a
    /// boundary.
    #[inline]
    pub fn edge_corners(&self) -> &[[u32; 2]] {
        &self.edges().corners
    }

    /// True when the edge tables are built (always, except on the last level of a plan before
    /// [`Level::complete_from`]).
    #[cfg(test)]
    pub(crate) fn has_edges(&self) -> bool {
        self.edges.get().is_some()
    }

    /// Completes a level built by `parent.refine_faces()`: its edge tables (numbered exactly as
    /// [`Level::refine`] numbers them) and its vertex -> corner table (as
    /// [`Level::index_vertex_corners_from`]); nothing that is there is built again.
    pub(crate) fn complete_from(&self, parent: &Level) {
        self.add_edges_from(parent);
        self.index_vertex_corners_from(parent);
    }

    /// The edge tables of [`Level::complete_from`] alone.
    fn add_edges_from(&self, parent: &Level) {
        self.edges.get_or_init(|| parent.child_edges());
    }

    /// Builds, in parallel from the parent, the vertex -> corner table that
    /// [`Level::corners_of_vertex`] would build on first use on a level made by
    /// `parent.refine_faces()` (the same table; nothing if it is there).
    pub(crate) fn index_vertex_corners_from(&self, parent: &Level) {
        if self.vert_corner_offsets.is_empty() {
            self.lazy_vertex_corners
                .get_or_init(|| parent.child_vertex_corners(self.num_vertices, true));
        }
    }

    /// A quad level from its tables (the adaptive partial levels).
    pub(crate) fn from_quad_tables(
        num_vertices: usize,
        corner_verts: Vec<u32>,
        edges: Edges,
        vert_corner_offsets: Vec<u32>,
        vert_corners: Vec<u32>,
    ) -> Level {
        Level {
            num_vertices,
            corner_verts,
            num_edges: edges.verts.len(),
            edges: OnceLock::from(edges),
            vert_corner_offsets,
            vert_corners,
            ..Level::default()
        }
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

    /// The corners at vertex `v` (from a table built on first use, in increasing order of
    /// corner, if the level was refined without its vertex -> corner table).
    #[inline]
    pub fn corners_of_vertex(&self, v: usize) -> &[u32] {
        let (offsets, corners) = self.vertex_corner_table();
        &corners[offsets[v] as usize..offsets[v + 1] as usize]
    }

    /// The vertex -> corner table as CSR `(offsets, corners)` (what [`Level::corners_of_vertex`]
    /// reads, for passes that look it up once instead of once per vertex).
    #[inline]
    pub(crate) fn vertex_corner_table(&self) -> (&[u32], &[u32]) {
        if self.vert_corner_offsets.is_empty() {
            let (o, c) = self
                .lazy_vertex_corners
                .get_or_init(|| vertex_corners(self.num_vertices, &self.corner_verts));
            (o, c)
        } else {
            (&self.vert_corner_offsets, &self.vert_corners)
        }
    }

    /// True if edge `e` has a single face.
    #[inline]
    pub fn is_boundary_edge(&self, e: usize) -> bool {
        self.edge_corners()[e][1] == NONE
    }

    /// The child edge of `e` (at the next level) that contains the endpoint `v` of `e`.
    #[inline]
    pub(crate) fn child_half(&self, e: u32, v: u32) -> u32 {
        2 * e + (self.edge_verts()[e as usize][0] != v) as u32
    }

    /// The corner across edge `e` from corner `c` (the other face's corner whose outgoing edge
    /// is `e`); `None` on a boundary.
    #[inline]
    pub(crate) fn opposite(&self, e: usize, c: usize) -> Option<usize> {
        let [a, b] = self.edge_corners()[e];
        let other = if a as usize == c { b } else { a };
        (other != NONE).then_some(other as usize)
    }

    /// The corner at the same vertex in the next face around it, across the incoming edge of
    /// `c`; `None` at a boundary.
    #[inline]
    pub(crate) fn next_around_vertex(&self, c: usize) -> Option<usize> {
        let p = self.prev(c);
        self.opposite(self.corner_edges()[p] as usize, p)
    }

    /// The edges at vertex `v`: the outgoing edge of each of its corners, and the incoming edge
    /// of a corner when that edge is on the boundary (so that every edge comes once).
    #[inline]
    pub(crate) fn vertex_edges(&self, v: usize) -> impl Iterator<Item = u32> + '_ {
        self.corners_of_vertex(v).iter().flat_map(move |&c| {
            let c = c as usize;
            let incoming = self.corner_edges()[self.prev(c)];
            let extra = self.is_boundary_edge(incoming as usize).then_some(incoming);
            std::iter::once(self.corner_edges()[c]).chain(extra)
        })
    }

    /// The other end of edge `e` from its end `v`.
    #[inline]
    pub(crate) fn other_end(&self, e: u32, v: usize) -> usize {
        let [a, b] = self.edge_verts()[e as usize];
        if a as usize == v {
            b as usize
        } else {
            a as usize
        }
    }

    /// The other ends of the first two edges at `v` (in [`Level::vertex_edges`] order) for
    /// which `sharp` holds (`v` itself in place of missing ones): a crease vertex's neighbours
    /// along its crease.
    #[inline]
    pub(crate) fn sharp_neighbours(&self, v: usize, sharp: impl Fn(u32) -> bool) -> [usize; 2] {
        let mut ends = [v; 2];
        let mut found = 0;
        for e in self.vertex_edges(v) {
            if found < 2 && sharp(e) {
                ends[found] = self.other_end(e, v);
                found += 1;
            }
        }
        ends
    }

    /// Builds a level from polygons (all vertices used), finding its edges. Fails with the
    /// corners involved if an edge has more than two faces or two faces traverse it the same way
    /// (the first such edge in edge order).
    ///
    /// Edges are numbered by their (smaller, larger) vertex pair; each edge's corners are its
    /// halves in increasing order. Every vertex finds the edges to larger vertices among its
    /// own corners, so the work is parallel over vertices and needs no global sort.
    pub(crate) fn from_polygons(
        num_vertices: usize,
        face_offsets: Vec<u32>,
        corner_verts: Vec<u32>,
    ) -> std::result::Result<Level, EdgeProblem> {
        let mut corner_faces = zeroed_hinted::<u32>(corner_verts.len());
        fill_csr(&face_offsets, &mut corner_faces, |f, out| {
            out.fill(f as u32)
        });
        let (vert_corner_offsets, vert_corners) = vertex_corners(num_vertices, &corner_verts);
        let mut level = Level {
            num_vertices,
            face_offsets,
            corner_faces,
            corner_verts,
            vert_corner_offsets,
            vert_corners,
            ..Level::default()
        };
        let edges = level.find_edges()?;
        level.num_edges = edges.verts.len();
        level.edges = OnceLock::from(edges);
        Ok(level)
    }

    /// Calls `f` with the halves (corners) of the edges from `a` to vertices `b >= a`, as
    /// `(b, corner)` in increasing order: the corners at `a` whose next vertex is `b`, and the
    /// corners at `b` whose next vertex is `a` (the predecessors of corners at `a`).
    fn owned_halves<R>(&self, a: usize, f: impl FnOnce(&[(u32, u32)]) -> R) -> R {
        const STACK: usize = 64;
        let corners = self.corners_of_vertex(a);
        let (mut stack, mut heap) = ([(0u32, 0u32); STACK], Vec::new());
        let buf: &mut [(u32, u32)] = if 2 * corners.len() <= STACK {
            &mut stack
        } else {
            heap.resize(2 * corners.len(), (0, 0));
            &mut heap
        };
        let a = a as u32;
        let mut n = 0;
        for &c in corners {
            let (prev, next) = (self.prev(c as usize), self.next(c as usize));
            let out_end = self.corner_verts[next];
            if out_end >= a {
                buf[n] = (out_end, c);
                n += 1;
            }
            let in_end = self.corner_verts[prev];
            if in_end > a {
                buf[n] = (in_end, prev as u32);
                n += 1;
            }
        }
        let halves = &mut buf[..n];
        halves.sort_unstable();
        f(halves)
    }

    /// The edge tables of a polygon level (see [`Level::from_polygons`]).
    fn find_edges(&self) -> std::result::Result<Edges, EdgeProblem> {
        // The halves of one edge (sorted by corner): more than two, or two the same way round.
        let edge_problem = |group: &[(u32, u32)]| {
            let c0 = group[0].1 as usize;
            if group.len() > 2 {
                return Some(EdgeProblem::NonManifold {
                    corner: c0,
                    faces: group.len(),
                });
            }
            let c1 = group.get(1).map(|h| h.1 as usize)?;
            (self.corner_verts[c0] == self.corner_verts[c1])
                .then_some(EdgeProblem::Orientation { corners: [c0, c1] })
        };
        let bad = AtomicBool::new(false);
        let offsets = prefix_offsets(self.num_vertices, |a| {
            self.owned_halves(a, |halves| {
                let mut count = 0;
                for group in halves.chunk_by(|x, y| x.0 == y.0) {
                    if edge_problem(group).is_some() {
                        bad.store(true, Ordering::Relaxed);
                    }
                    count += 1;
                }
                count
            })
        });
        if bad.into_inner() {
            let first = (0..self.num_vertices)
                .into_par_iter()
                .find_map_first(|a| {
                    self.owned_halves(a, |halves| {
                        halves.chunk_by(|x, y| x.0 == y.0).find_map(edge_problem)
                    })
                })
                .expect("a vertex with a problem edge");
            return Err(first);
        }
        let num_edges = offsets[self.num_vertices] as usize;
        let mut corners = zeroed_hinted::<[u32; 2]>(num_edges);
        // Every corner is the half of exactly one edge, so each slot is stored once.
        let corner_edges: Vec<AtomicU32> = gather_hinted(self.num_corners(), |_| AtomicU32::new(0));
        fill_csr(&offsets, &mut corners, |a, out| {
            self.owned_halves(a, |halves| {
                let first = offsets[a];
                for (k, (slot, group)) in out
                    .iter_mut()
                    .zip(halves.chunk_by(|x, y| x.0 == y.0))
                    .enumerate()
                {
                    *slot = [group[0].1, group.get(1).map_or(NONE, |h| h.1)];
                    for h in group {
                        corner_edges[h.1 as usize].store(first + k as u32, Ordering::Relaxed);
                    }
                }
            })
        });
        let verts = gather_hinted(num_edges, |e| {
            let c = corners[e][0] as usize;
            [self.corner_verts[c], self.corner_verts[self.next(c)]]
        });
        Ok(Edges {
            corner_edges: corner_edges
                .into_iter()
                .map(AtomicU32::into_inner)
                .collect(),
            verts,
            corners,
        })
    }

    /// Builds the first level from a cage, with `corner_verts` renumbered so that every vertex
    /// is used; errors name the cage's own vertex ids and faces.
    pub(crate) fn from_cage(
        cage: &Cage,
        num_vertices: usize,
        corner_verts: Vec<u32>,
    ) -> Result<Level> {
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
    pub(crate) fn refine(&self) -> Level {
        let child = self.refine_faces();
        child.add_edges_from(self);
        let (offsets, vert_corners) = self.child_vertex_corners(child.num_vertices, false);
        Level {
            vert_corner_offsets: offsets,
            vert_corners,
            ..child
        }
    }

    /// As [`Level::refine`], the faces only: the edge tables wait for
    /// [`Level::complete_from`], the vertex -> corner table for [`Level::corners_of_vertex`]
    /// (in increasing order of corner). This is the last level of a plan, which evaluation
    /// reads only through its faces and vertex count.
    pub(crate) fn refine_faces(&self) -> Level {
        let nv = self.num_vertices as u32;
        let ne = self.num_edges() as u32;
        let corner_edges = self.corner_edges();
        let corner_verts = gather_hinted(self.num_corners(), |c| {
            [
                self.corner_verts[c],
                nv + corner_edges[c],
                nv + ne + self.face_of(c) as u32,
                nv + corner_edges[self.prev(c)],
            ]
        });
        Level {
            num_vertices: self.num_vertices + self.num_edges() + self.num_faces(),
            corner_verts: corner_verts.into_flattened(),
            num_edges: 2 * self.num_edges() + self.num_corners(),
            ..Level::default()
        }
    }

    /// The edge tables of this level's child (see [`Level::refine`] for their numbering).
    fn child_edges(&self) -> Edges {
        let nv = self.num_vertices as u32;
        let ne = self.num_edges() as u32;
        let nc = self.num_corners();
        let Edges {
            corner_edges,
            verts: edge_verts,
            corners: edge_corners,
        } = self.edges();
        let quad_edges = gather_hinted(nc, |c| {
            let v = self.corner_verts[c];
            let p = self.prev(c);
            [
                self.child_half(corner_edges[c], v),
                2 * ne + c as u32,
                2 * ne + p as u32,
                self.child_half(corner_edges[p], v),
            ]
        });

        // Edges: the two halves of every old edge, then one interior edge per old corner.
        let total_edges = 2 * ne as usize + nc;
        let mut verts: Vec<[u32; 2]> = with_capacity_hinted(total_edges);
        let mut corners: Vec<[u32; 2]> = with_capacity_hinted(total_edges);
        (0..total_edges)
            .into_par_iter()
            .with_min_len(CHUNK)
            .map(|i| {
                if i < 2 * ne as usize {
                    let (e, k) = (i >> 1, i & 1);
                    let [a, b] = edge_verts[e];
                    let mid = nv + e as u32;
                    let ends = if k == 0 { [a, mid] } else { [mid, b] };
                    let mut slots = [NONE; 2];
                    for (slot, &c) in edge_corners[e].iter().enumerate() {
                        if c != NONE {
                            let c = c as usize;
                            // The corner leaving `a` starts half 0 and ends half 1.
                            slots[slot] = if (self.corner_verts[c] == a) == (k == 0) {
                                4 * c as u32
                            } else {
                                4 * self.next(c) as u32 + 3
                            };
                        }
                    }
                    (ends, slots)
                } else {
                    let c = i - 2 * ne as usize;
                    (
                        [nv + corner_edges[c], nv + ne + self.face_of(c) as u32],
                        [4 * c as u32 + 1, 4 * self.next(c) as u32 + 2],
                    )
                }
            })
            .unzip_into_vecs(&mut verts, &mut corners);
        Edges {
            corner_edges: quad_edges.into_flattened(),
            verts,
            corners,
        }
    }

    /// Vertex -> corners of the child level: an old vertex keeps one corner per old corner, an
    /// edge point has two per incident face, a face point one per corner of its face; in
    /// increasing order of corner when `increasing` (the order of [`Level::corners_of_vertex`]'s
    /// table built on first use).
    fn child_vertex_corners(&self, new_vertices: usize, increasing: bool) -> (Vec<u32>, Vec<u32>) {
        let (nv, ne) = (self.num_vertices, self.num_edges());
        let offsets = prefix_offsets(new_vertices, |w| {
            if w < nv {
                self.corners_of_vertex(w).len() as u32
            } else if w < nv + ne {
                if self.is_boundary_edge(w - nv) {
                    2
                } else {
                    4
                }
            } else {
                self.face_corners(w - nv - ne).len() as u32
            }
        });
        let mut vert_corners = zeroed_hinted::<u32>(4 * self.num_corners());
        fill_csr(&offsets, &mut vert_corners, |w, out| {
            if w < nv {
                for (o, &c) in out.iter_mut().zip(self.corners_of_vertex(w)) {
                    *o = 4 * c;
                }
            } else if w < nv + ne {
                let mut k = 0;
                for &c in &self.edge_corners()[w - nv] {
                    if c != NONE {
                        out[k] = 4 * c + 1;
                        out[k + 1] = 4 * self.next(c as usize) as u32 + 3;
                        k += 2;
                    }
                }
            } else {
                for (o, c) in out.iter_mut().zip(self.face_corners(w - nv - ne)) {
                    *o = 4 * c as u32 + 2;
                }
            }
            if increasing {
                out.sort_unstable();
            }
        });
        (offsets, vert_corners)
    }
}

/// Vertex -> corners by counting sort (corners in increasing order).
fn vertex_corners(num_vertices: usize, corner_verts: &[u32]) -> (Vec<u32>, Vec<u32>) {
    let mut offsets = vec![0u32; num_vertices + 1];
    for &v in corner_verts {
        offsets[v as usize + 1] += 1;
    }
    for v in 0..num_vertices {
        offsets[v + 1] += offsets[v];
    }
    let mut fill = offsets.clone();
    let mut vert_corners = vec![0u32; corner_verts.len()];
    for (c, &v) in corner_verts.iter().enumerate() {
        vert_corners[fill[v as usize] as usize] = c as u32;
        fill[v as usize] += 1;
    }
    (offsets, vert_corners)
}

/// Why a set of polygons is not an oriented 2-manifold along its edges.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum EdgeProblem {
    /// The edge leaving `corner` has `faces` faces.
    NonManifold { corner: usize, faces: usize },
    /// The two corners traverse their shared edge in the same direction.
    Orientation { corners: [usize; 2] },
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Edges the straightforward way: every half keyed by its (smaller, larger) vertex pair,
    /// sorted, equal keys grouped; the first problem in key order is the error.
    fn edges_by_sorting(level: &Level) -> std::result::Result<Edges, EdgeProblem> {
        let mut halves: Vec<(u64, u32)> = (0..level.num_corners())
            .map(|c| {
                let (a, b) = (level.corner_verts[c], level.corner_verts[level.next(c)]);
                (((a.min(b) as u64) << 32) | a.max(b) as u64, c as u32)
            })
            .collect();
        halves.sort_unstable();
        let mut edges = Edges {
            corner_edges: vec![NONE; level.num_corners()],
            ..Edges::default()
        };
        for group in halves.chunk_by(|x, y| x.0 == y.0) {
            let c0 = group[0].1 as usize;
            if group.len() > 2 {
                return Err(EdgeProblem::NonManifold {
                    corner: c0,
                    faces: group.len(),
                });
            }
            let c1 = group.get(1).map_or(NONE, |h| h.1);
            if c1 != NONE && level.corner_verts[c1 as usize] == level.corner_verts[c0] {
                return Err(EdgeProblem::Orientation {
                    corners: [c0, c1 as usize],
                });
            }
            for h in group {
                edges.corner_edges[h.1 as usize] = edges.verts.len() as u32;
            }
            let ends = [level.corner_verts[c0], level.corner_verts[level.next(c0)]];
            edges.verts.push(ends);
            edges.corners.push([c0 as u32, c1]);
        }
        Ok(edges)
    }

    fn same_edges(a: &Edges, b: &Edges) -> bool {
        a.corner_edges == b.corner_edges && a.verts == b.verts && a.corners == b.corners
    }

    /// Faces of 3 to 6 distinct vertices out of `vertices`, sometimes taken from a closed or open
    /// grid (manifold), sometimes random (often non-manifold or inconsistently oriented).
    fn polygons() -> impl Strategy<Value = (usize, Vec<u32>, Vec<u32>)> {
        (4usize..40, 1usize..30, any::<u64>()).prop_map(|(vertices, faces, seed)| {
            let mut state = seed | 1;
            let mut next = move |n: usize| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state % n as u64) as u32
            };
            let mut offsets = vec![0u32];
            let mut verts = Vec::new();
            if seed % 2 == 0 {
                // A (w x h) grid of quads, wrapped in one direction when seed % 4 == 0.
                let (w, h) = (2 + next(5) as usize, 2 + next(5) as usize);
                let wrap = seed % 4 == 0;
                let cols = if wrap { w } else { w + 1 };
                let id = |i: usize, j: usize| (j * cols + i % cols) as u32;
                for j in 0..h {
                    for i in 0..w {
                        verts.extend([id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
                        offsets.push(verts.len() as u32);
                    }
                }
                let used = cols * (h + 1);
                return (used, offsets, verts);
            }
            for _ in 0..faces {
                let size = 3 + next(4) as usize;
                let start = verts.len();
                while verts.len() - start < size.min(vertices) {
                    let v = next(vertices);
                    if !verts[start..].contains(&v) {
                        verts.push(v);
                    }
                }
                offsets.push(verts.len() as u32);
            }
            // Renumber so that every vertex is used.
            let mut map = vec![NONE; vertices];
            let mut used = 0;
            for v in &mut verts {
                if map[*v as usize] == NONE {
                    map[*v as usize] = used;
                    used += 1;
                }
                *v = map[*v as usize];
            }
            (used as usize, offsets, verts)
        })
    }

    proptest! {
        /// The per-vertex edge finder numbers edges, orders their corners and reports the first
        /// problem exactly as sorting all halves does.
        #[test]
        fn edges_match_sorting((vertices, offsets, verts) in polygons()) {
            let bare = Level {
                num_vertices: vertices,
                corner_faces: (0..offsets.len() - 1)
                    .flat_map(|f| {
                        std::iter::repeat_n(f as u32, (offsets[f + 1] - offsets[f]) as usize)
                    })
                    .collect(),
                face_offsets: offsets.clone(),
                corner_verts: verts.clone(),
                ..Level::default()
            };
            let expected = edges_by_sorting(&bare);
            match (Level::from_polygons(vertices, offsets, verts), expected) {
                (Ok(level), Ok(edges)) => {
                    prop_assert!(same_edges(level.edges(), &edges));
                    // A faces-only child completed later equals the full refinement.
                    let (full, faces_only) = (level.refine(), level.refine_faces());
                    prop_assert!(!faces_only.has_edges());
                    faces_only.complete_from(&level);
                    // The vertex -> corner table built from the parent equals the counting sort.
                    let indexed = level.refine_faces();
                    indexed.index_vertex_corners_from(&level);
                    let sorted = vertex_corners(full.num_vertices, &full.corner_verts);
                    for v in 0..full.num_vertices {
                        let expected = &sorted.1[sorted.0[v] as usize..sorted.0[v + 1] as usize];
                        prop_assert_eq!(indexed.corners_of_vertex(v), expected);
                        prop_assert_eq!(faces_only.corners_of_vertex(v), expected);
                    }
                    prop_assert_eq!(&faces_only.corner_verts, &full.corner_verts);
                    prop_assert_eq!(faces_only.num_edges(), full.num_edges());
                    prop_assert!(same_edges(faces_only.edges(), full.edges()));
                    let grand = full.refine();
                    prop_assert_eq!(grand.num_edges(), grand.edge_verts().len());
                }
                (Err(found), Err(problem)) => prop_assert_eq!(found, problem),
                (found, expected) => prop_assert!(
                    false,
                    "found {:?}, expected {:?}",
                    found.map(|_| ()),
                    expected.map(|_| ())
                ),
            }
        }
    }
}
