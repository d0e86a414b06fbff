//! Refined topology, one complete mesh per level in flat structure-of-arrays tables (the idea of
//! OpenSubdiv's `Vtr::Level`): `M_0` is built from the cage; `M_{j+1}` is `M_j` split
//! Catmull-Clark style, its vertices the old vertices, then one per edge, then one per face, its
//! faces one quad per *corner* of `M_j`.
//!
//! Any polygon soup is a level (as OpenSubdiv's `completeTopologyFromFaceVertices`): an edge is
//! shared by every face that uses its vertex pair, in either direction, so it may have any
//! number of faces; a face running along a vertex pair twice gets a second edge for it, and a
//! degenerate `(v, v)` side is an edge of its own per occurrence. Edges that are not an ordinary
//! manifold edge (k != 1, 2 faces, two faces running the same way, degenerate, repeated) and
//! their ends are *non-manifold*, and so is a vertex whose faces are not one fan; the tags are
//! inherited by the children (halves, edge points, old vertices). Every face keeps its own side.
//!
//! Every table of `M_{j+1}` is a gather from `M_j`'s tables, computed in parallel; nothing here
//! depends on the order in which threads run. The last level of a plan is built with its faces
//! only (as OpenSubdiv's `fullTopologyInLastLevel = false`): evaluation never reads its edges,
//! which [`Level::complete_from`] adds, in the same numbering, when something asks for them.

use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::OnceLock;

use rayon::prelude::*;

use crate::error::Result;
use crate::memory;
use crate::mesh::{offsets_of_quads, Cage};
use crate::parallel::{
    csr_chunks, fill_csr, gather_hinted, prefix_offsets, with_capacity_hinted, zeroed_hinted, CHUNK,
};

/// Per vertex, CSR offsets of the edge halves it owns, and the halves as `(other end, corner)`
/// ([`Level::halves_by_owner`]).
type OwnedHalves = (Vec<u32>, Vec<(u32, u32)>);

/// Marks a missing entry (the second face of a boundary edge).
pub(crate) const NONE: u32 = u32::MAX;

/// The edges of a level and their incidences.
#[derive(Debug, Clone, Default)]
pub(crate) struct Edges {
    /// Edge from each corner to the next corner of its face.
    pub(crate) corner_edges: Vec<u32>,
    /// The two vertices of each edge.
    pub(crate) verts: Vec<[u32; 2]>,
    /// The first two corners whose outgoing edge is this edge (its first two *slots*, one per
    /// use by a face); `NONE` in the second on a boundary.
    pub(crate) corners: Vec<[u32; 2]>,
    /// `(edge, corner)`: the third and further slots of the edges with more than two faces,
    /// sorted by edge (empty on a manifold level).
    pub(crate) more: Vec<(u32, u32)>,
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
    /// The non-manifold edges, sorted (empty on a manifold level).
    pub(crate) nm_edges: Vec<u32>,
    /// The non-manifold vertices, sorted (empty on a manifold level).
    pub(crate) nm_vertices: Vec<u32>,
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

    /// True when every face is a quad whose corners are `4 f..4 f + 4`: a level stored as quads
    /// ([`Level::is_quads`]), or a cage of quads, which is stored with its face offsets as any
    /// cage (one pass over them: ask once per pass, not per face).
    pub(crate) fn all_quads(&self) -> bool {
        self.is_quads() || offsets_of_quads(&self.face_offsets)
    }

    /// True when every face is a quad ([`Level::all_quads`]) and no edge has more than two faces
    /// (no fins): the levels whose child tables are built face by face and edge by edge.
    fn quads_without_fins(&self) -> bool {
        self.edges().more.is_empty() && self.all_quads()
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
    pub(crate) fn complete_from(&self, parent: &Level) -> Result<()> {
        self.add_edges_from(parent)?;
        self.index_vertex_corners_from(parent)
    }

    /// The edge tables of [`Level::complete_from`] alone.
    fn add_edges_from(&self, parent: &Level) -> Result<()> {
        if self.edges.get().is_none() {
            // Two threads completing at once build the same tables; one is kept.
            let _ = self.edges.set(parent.child_edges()?);
        }
        Ok(())
    }

    /// Builds, in parallel from the parent, the vertex -> corner table that
    /// [`Level::corners_of_vertex`] would build on first use on a level made by
    /// `parent.refine_faces()` (the same table; nothing if it is there).
    pub(crate) fn index_vertex_corners_from(&self, parent: &Level) -> Result<()> {
        if self.vert_corner_offsets.is_empty() && self.lazy_vertex_corners.get().is_none() {
            let table = parent.child_vertex_corners(self.num_vertices, true)?;
            let _ = self.lazy_vertex_corners.set(table);
        }
        Ok(())
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

    /// Marks in `marked` the faces within `rings` vertex rings of the faces of `frontier`
    /// (marked already): each ring adds the faces sharing a vertex with the last one.
    pub(crate) fn grow_face_rings(
        &self,
        marked: &mut [bool],
        mut frontier: Vec<usize>,
        rings: usize,
    ) {
        // Decided once: adaptive grows the rings of every partial level (quads) this way.
        let quads = self.is_quads();
        for _ in 0..rings {
            let mut next = Vec::new();
            for &f in &frontier {
                let corners = if quads {
                    4 * f..4 * f + 4
                } else {
                    self.face_corners(f)
                };
                for c in corners {
                    for &d in self.corners_of_vertex(self.corner_verts[c] as usize) {
                        let g = if quads {
                            d as usize >> 2
                        } else {
                            self.face_of(d as usize)
                        };
                        if !marked[g] {
                            marked[g] = true;
                            next.push(g);
                        }
                    }
                }
            }
            frontier = next;
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
            quad_next(corner)
        } else {
            let r = self.face_corners(self.corner_faces[corner] as usize);
            if corner + 1 == r.end {
                r.start
            } else {
                corner + 1
            }
        }
    }

    /// [`Level::next`], with no lookup when `quads` (every face a quad, [`Level::all_quads`]:
    /// a cage of quads keeps its face tables, so [`Level::is_quads`] does not tell).
    #[inline(always)]
    fn next_of(&self, quads: bool, corner: usize) -> usize {
        if quads {
            quad_next(corner)
        } else {
            self.next(corner)
        }
    }

    /// [`Level::prev`], with no lookup when `quads` (as [`Level::next_of`]).
    #[inline(always)]
    fn prev_of(&self, quads: bool, corner: usize) -> usize {
        if quads {
            quad_prev(corner)
        } else {
            self.prev(corner)
        }
    }

    /// [`Level::face_of`], with no lookup when `quads` (as [`Level::next_of`]).
    #[inline(always)]
    fn face_of_in(&self, quads: bool, corner: usize) -> usize {
        if quads {
            corner >> 2
        } else {
            self.corner_faces[corner] as usize
        }
    }

    /// The previous corner around the face of `corner`.
    #[inline]
    pub fn prev(&self, corner: usize) -> usize {
        if self.is_quads() {
            quad_prev(corner)
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
            // Only levels built without the table get here, and on every request's path the
            // table is already built, fallibly: a plan's last level is completed by
            // `Refinement::complete_levels` (the binding's `complete_output`, the limits)
            // before anything reads it, and a step reads only coarse levels, which have it.
            // So the panic below is for a refused allocation on a path that skipped that.
            let (o, c) = self.lazy_vertex_corners.get_or_init(|| {
                vertex_corners(self.num_vertices, &self.corner_verts)
                    .unwrap_or_else(|e| panic!("vertex -> corner table: {e}"))
            });
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

    /// The child edge of `e` (at the next level) that contains the endpoint `v` of `e` (for a
    /// degenerate edge `(v, v)`, the half leaving `v`).
    #[inline]
    pub(crate) fn child_half(&self, e: u32, v: u32) -> u32 {
        2 * e + (self.edge_verts()[e as usize][0] != v) as u32
    }

    /// As [`Level::child_half`], for the degenerate edge the half arriving at `v`.
    #[inline]
    fn child_half_arriving(&self, e: u32, v: u32) -> u32 {
        2 * e + (self.edge_verts()[e as usize][1] == v) as u32
    }

    /// True if the level has non-manifold edges or vertices.
    #[inline]
    pub fn is_non_manifold(&self) -> bool {
        !self.nm_vertices.is_empty()
    }

    /// True if edge `e` is non-manifold (see the module documentation).
    #[inline]
    pub fn is_non_manifold_edge(&self, e: usize) -> bool {
        !self.nm_edges.is_empty() && self.nm_edges.binary_search(&(e as u32)).is_ok()
    }

    /// True if vertex `v` is non-manifold (see the module documentation).
    #[inline]
    pub fn is_non_manifold_vertex(&self, v: usize) -> bool {
        !self.nm_vertices.is_empty() && self.nm_vertices.binary_search(&(v as u32)).is_ok()
    }

    /// The corners of every slot of edge `e`: one per use by a face, in increasing order.
    #[inline]
    pub(crate) fn edge_slots(&self, e: usize) -> impl Iterator<Item = u32> + '_ {
        let edges = self.edges();
        let more = if edges.more.is_empty() {
            &edges.more[..0]
        } else {
            let from = edges.more.partition_point(|m| (m.0 as usize) < e);
            let to = from + edges.more[from..].partition_point(|m| m.0 as usize == e);
            &edges.more[from..to]
        };
        (edges.corners[e].into_iter().filter(|&c| c != NONE)).chain(more.iter().map(|m| m.1))
    }

    /// Number of faces of edge `e` (uses of it).
    #[inline]
    pub(crate) fn edge_valence(&self, e: usize) -> usize {
        if self.edges().more.is_empty() {
            1 + !self.is_boundary_edge(e) as usize
        } else {
            self.edge_slots(e).count()
        }
    }

    /// The corner across edge `e` from corner `c` (the other face's corner whose outgoing edge
    /// is `e`); `None` on a boundary and on a non-manifold edge (no unique face across).
    #[inline]
    pub(crate) fn opposite(&self, e: usize, c: usize) -> Option<usize> {
        if self.is_non_manifold_edge(e) {
            return None;
        }
        let [a, b] = self.edge_corners()[e];
        let other = if a as usize == c { b } else { a };
        (other != NONE).then_some(other as usize)
    }

    /// Per corner, the corner across its outgoing edge in the neighbouring face
    /// ([`Level::opposite`]), `NONE` at a boundary or a non-manifold edge: one load per step of
    /// the neighbourhood walks (limit stencils, regular windows).
    pub(crate) fn twin_corners(&self) -> Result<Vec<u32>> {
        self.twin_table(NONE, self.num_corners())
    }

    /// [`Level::twin_corners`] in a table of `len` entries (at least one per corner), `absent`
    /// where a corner has no twin and past the corners (the regular windows' dead face). Written
    /// edge by edge, the two corners of each at once: a sequential scatter of 6M instructions
    /// for the 983k corners of the 4k sphere's level 3, where a parallel gather of each corner's
    /// pair took 28M.
    pub(crate) fn twin_table(&self, absent: u32, len: usize) -> Result<Vec<u32>> {
        let mut twins = memory::filled(len.max(self.num_corners()), absent)?;
        let non_manifold = !self.nm_edges.is_empty();
        for (e, &[a, b]) in self.edge_corners().iter().enumerate() {
            if b != NONE && a != NONE && !(non_manifold && self.is_non_manifold_edge(e)) {
                twins[a as usize] = b;
                twins[b as usize] = a;
            }
        }
        Ok(twins)
    }

    /// The corner at the same vertex in the next face around it, across the incoming edge of
    /// `c`; `None` at a boundary.
    #[inline]
    pub(crate) fn next_around_vertex(&self, c: usize) -> Option<usize> {
        let p = self.prev(c);
        self.opposite(self.corner_edges()[p] as usize, p)
    }

    /// The edges at vertex `v`, each once: the outgoing edge of each of its corners, and the
    /// incoming edge of a corner when that edge is on the boundary; at a non-manifold vertex
    /// the outgoing and incoming edges of its corners in that order, repeats left out.
    #[inline]
    pub(crate) fn vertex_edges(&self, v: usize) -> impl Iterator<Item = u32> + '_ {
        let nm = self.is_non_manifold_vertex(v).then(|| {
            let mut edges: Vec<u32> = Vec::new();
            for &c in self.corners_of_vertex(v) {
                let c = c as usize;
                for e in [self.corner_edges()[c], self.corner_edges()[self.prev(c)]] {
                    if !edges.contains(&e) {
                        edges.push(e);
                    }
                }
            }
            edges
        });
        let manifold = nm.is_none().then(|| {
            self.corners_of_vertex(v).iter().flat_map(move |&c| {
                let c = c as usize;
                let incoming = self.corner_edges()[self.prev(c)];
                let extra = self.is_boundary_edge(incoming as usize).then_some(incoming);
                std::iter::once(self.corner_edges()[c]).chain(extra)
            })
        });
        manifold
            .into_iter()
            .flatten()
            .chain(nm.into_iter().flatten())
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

    /// Builds a level from polygons (all vertices used), finding its edges and tagging what is
    /// non-manifold (see the module documentation).
    ///
    /// Edges are numbered by their (smaller, larger) vertex pair (then by instance); each edge's
    /// slots are its halves in increasing order of corner. The halves are grouped by their
    /// smaller vertex in one counting sort over the corners ([`Level::halves_by_owner`]), so
    /// each vertex then finds its edges in parallel, and no global sort is needed.
    pub(crate) fn from_polygons(
        num_vertices: usize,
        face_offsets: Vec<u32>,
        corner_verts: Vec<u32>,
    ) -> Result<Level> {
        let mut corner_faces = zeroed_hinted::<u32>(corner_verts.len())?;
        fill_csr(&face_offsets, &mut corner_faces, |f, out| {
            out.fill(f as u32)
        });
        let (vert_corner_offsets, vert_corners) = vertex_corners(num_vertices, &corner_verts)?;
        let mut level = Level {
            num_vertices,
            face_offsets,
            corner_faces,
            corner_verts,
            vert_corner_offsets,
            vert_corners,
            ..Level::default()
        };
        // A cage of quads walks its faces with no lookups (asked once, as `all_quads` scans).
        let quads = level.all_quads();
        let (edges, nm_edges) = level.find_edges(quads)?;
        level.num_edges = edges.verts.len();
        level.edges = OnceLock::from(edges);
        level.nm_edges = nm_edges;
        level.nm_vertices = level.find_non_manifold_vertices(quads)?;
        Ok(level)
    }

    /// Every corner's half of its edge, grouped by the edge's smaller vertex (its owner) as
    /// `(larger vertex, corner)` in increasing order: CSR offsets per vertex and the halves. A
    /// counting sort by owner keeps the corners of an owner in increasing order, so only the
    /// few halves of each vertex are sorted, by other end.
    fn halves_by_owner(&self, quads: bool) -> Result<OwnedHalves> {
        let ends = if quads {
            // Face by face, the corners' next ones known.
            let (faces, _) = self.corner_verts.as_chunks::<4>();
            let ends = gather_hinted(faces.len(), |f| {
                let v = faces[f];
                std::array::from_fn::<_, 4, _>(|k| {
                    let (a, b) = (v[k], v[(k + 1) & 3]);
                    (a.min(b), a.max(b))
                })
            })?;
            ends.into_flattened()
        } else {
            gather_hinted(self.num_corners(), |c| {
                let (a, b) = (self.corner_verts[c], self.corner_verts[self.next(c)]);
                (a.min(b), a.max(b))
            })?
        };
        // The counting sort of [`vertex_corners`] by owner, writing each half with its other
        // end as it goes (through `vertex_corners` and a gather of the pairs: +0.45M
        // instructions, 2.5 %, of a fresh averaging 3 at level 2 on the callgrind driver).
        let mut offsets = memory::zeroed::<u32>(self.num_vertices + 1)?;
        for &(a, _) in &ends {
            offsets[a as usize + 1] += 1;
        }
        for v in 0..self.num_vertices {
            offsets[v + 1] += offsets[v];
        }
        let mut at = memory::collect(offsets[..self.num_vertices].iter().copied())?;
        let mut halves = zeroed_hinted::<(u32, u32)>(ends.len())?;
        for (c, &(a, b)) in ends.iter().enumerate() {
            halves[at[a as usize] as usize] = (b, c as u32);
            at[a as usize] += 1;
        }
        fill_csr(&offsets, &mut halves, |_, own| {
            if own.len() == 2 {
                if own[1].0 < own[0].0 {
                    own.swap(0, 1);
                }
            } else if own.len() > 2 {
                own.sort_unstable();
            }
        });
        Ok((offsets, halves))
    }

    /// The edges made of the halves of one vertex pair (`group`, sorted by corner): one edge
    /// with every half, except that a degenerate pair `(a, a)` is an edge per half and a face
    /// using the pair `i + 1` times has its `i`-th use in the `i`-th edge. Calls `edge` with
    /// the slots of each edge in turn and whether it is non-manifold.
    fn edges_of_pair(&self, a: u32, group: &[(u32, u32)], mut edge: impl FnMut(&[u32], bool)) {
        // The ordinary cases first: one or two faces, distinct, running opposite ways.
        if group[0].0 != a && group.len() <= 2 {
            let c0 = group[0].1 as usize;
            match group.get(1) {
                None => edge(&[c0 as u32], false),
                Some(&(_, c1)) => {
                    let c1 = c1 as usize;
                    if self.face_of(c0) == self.face_of(c1) {
                        edge(&[c0 as u32], true);
                        edge(&[c1 as u32], true);
                    } else {
                        let same_way = self.corner_verts[c0] == self.corner_verts[c1];
                        edge(&[c0 as u32, c1 as u32], same_way);
                    }
                }
            }
            return;
        }
        if group[0].0 == a {
            for h in group {
                edge(&[h.1], true);
            }
            return;
        }
        // Per face (its halves are contiguous: a face's corners are), its i-th half goes to
        // instance i.
        let mut instances: Vec<Vec<u32>> = Vec::new();
        for face in group.chunk_by(|x, y| self.face_of(x.1 as usize) == self.face_of(y.1 as usize))
        {
            for (i, h) in face.iter().enumerate() {
                if instances.len() == i {
                    instances.push(Vec::new());
                }
                instances[i].push(h.1);
            }
        }
        let nm = instances.len() > 1 || group.len() > 2 || {
            let (c0, c1) = (group[0].1 as usize, group[1].1 as usize);
            self.corner_verts[c0] == self.corner_verts[c1]
        };
        for slots in &instances {
            edge(slots, nm);
        }
    }

    /// The slots of the edge of a vertex pair's halves (`group`, as in [`Level::edges_of_pair`])
    /// when it is an ordinary manifold edge, as most are (not degenerate; one face, or two
    /// distinct faces running opposite ways), the second slot `NONE` on a boundary; `None`
    /// when [`Level::edges_of_pair`] must sort the group out. `quads` as [`Level::all_quads`].
    #[inline(always)]
    fn ordinary_edge(&self, quads: bool, a: u32, group: &[(u32, u32)]) -> Option<[u32; 2]> {
        match *group {
            [(b, c0)] if b != a => Some([c0, NONE]),
            [(b, c0), (_, c1)] if b != a => {
                let (c0, c1) = (c0 as usize, c1 as usize);
                let faces_differ = self.face_of_in(quads, c0) != self.face_of_in(quads, c1);
                let opposite_ways = self.corner_verts[c0] != self.corner_verts[c1];
                (faces_differ && opposite_ways).then_some([c0 as u32, c1 as u32])
            }
            _ => None,
        }
    }

    /// The edge tables of a polygon level (see [`Level::from_polygons`]) and its non-manifold
    /// edges.
    fn find_edges(&self, quads: bool) -> Result<(Edges, Vec<u32>)> {
        let (owned, halves) = self.halves_by_owner(quads)?;
        let halves_of = |a: usize| &halves[owned[a] as usize..owned[a + 1] as usize];
        let unusual = AtomicBool::new(false);
        let offsets = prefix_offsets(self.num_vertices, |a| {
            let mut count = 0;
            for group in halves_of(a).chunk_by(|x, y| x.0 == y.0) {
                if self.ordinary_edge(quads, a as u32, group).is_some() {
                    count += 1;
                    continue;
                }
                self.edges_of_pair(a as u32, group, |slots, nm| {
                    if nm || slots.len() > 2 {
                        unusual.store(true, Ordering::Relaxed);
                    }
                    count += 1;
                });
            }
            count
        })?;
        let num_edges = offsets[self.num_vertices] as usize;
        let mut corners = zeroed_hinted::<[u32; 2]>(num_edges)?;
        // Every corner is the half of exactly one edge, so each slot is stored once.
        let corner_edges: Vec<AtomicU32> =
            gather_hinted(self.num_corners(), |_| AtomicU32::new(0))?;
        fill_csr(&offsets, &mut corners, |a, out| {
            let mut k = 0;
            let e = |k: usize| offsets[a] + k as u32;
            for group in halves_of(a).chunk_by(|x, y| x.0 == y.0) {
                if let Some([c0, c1]) = self.ordinary_edge(quads, a as u32, group) {
                    out[k] = [c0, c1];
                    corner_edges[c0 as usize].store(e(k), Ordering::Relaxed);
                    if c1 != NONE {
                        corner_edges[c1 as usize].store(e(k), Ordering::Relaxed);
                    }
                    k += 1;
                    continue;
                }
                self.edges_of_pair(a as u32, group, |slots, _| {
                    out[k] = [slots[0], slots.get(1).copied().unwrap_or(NONE)];
                    for &c in slots {
                        corner_edges[c as usize].store(e(k), Ordering::Relaxed);
                    }
                    k += 1;
                });
            }
        });
        // The extra slots and the non-manifold edges, only on a level that has some.
        let (mut more, mut nm_edges) = (Vec::new(), Vec::new());
        if unusual.into_inner() {
            for (a, &first) in offsets[..self.num_vertices].iter().enumerate() {
                let mut e = first;
                for group in halves_of(a).chunk_by(|x, y| x.0 == y.0) {
                    self.edges_of_pair(a as u32, group, |slots, nm| {
                        more.extend(slots.iter().skip(2).map(|&c| (e, c)));
                        if nm {
                            nm_edges.push(e);
                        }
                        e += 1;
                    });
                }
            }
        }
        let verts = gather_hinted(num_edges, |e| {
            let c = corners[e][0] as usize;
            [
                self.corner_verts[c],
                self.corner_verts[self.next_of(quads, c)],
            ]
        })?;
        let edges = Edges {
            corner_edges: memory::collect(corner_edges.into_iter().map(AtomicU32::into_inner))?,
            verts,
            corners,
            more,
        };
        Ok((edges, nm_edges))
    }

    /// The vertices of a polygon level that are non-manifold: the ends of non-manifold edges,
    /// vertices a face uses twice, and vertices whose faces are not one fan (OpenSubdiv's
    /// `orderVertexFacesAndEdges` failing: a bowtie, open or closed).
    fn find_non_manifold_vertices(&self, quads: bool) -> Result<Vec<u32>> {
        let mut on_nm_edge = memory::zeroed::<bool>(self.num_vertices)?;
        for &e in &self.nm_edges {
            for v in self.edge_verts()[e as usize] {
                on_nm_edge[v as usize] = true;
            }
        }
        Ok((0..self.num_vertices as u32)
            .into_par_iter()
            .with_min_len(CHUNK)
            .filter(|&v| on_nm_edge[v as usize] || !self.is_one_fan(v as usize, quads))
            .collect::<Vec<u32>>())
    }

    /// True if the faces at `v` (whose edges are all manifold) form one fan, open or closed.
    /// `quads` when every face is a quad ([`Level::all_quads`]).
    fn is_one_fan(&self, v: usize, quads: bool) -> bool {
        let corners = self.corners_of_vertex(v);
        let n = corners.len();
        if corners
            .windows(2)
            .any(|w| self.face_of_in(quads, w[0] as usize) == self.face_of_in(quads, w[1] as usize))
        {
            return false;
        }
        let edges = self.edges();
        // The corner across edge `e` from `c` ([`Level::opposite`] with no search of the
        // non-manifold edges: none is at `v`).
        let across = |e: u32, c: usize| {
            let [a, b] = edges.corners[e as usize];
            let other = if a as usize == c { b } else { a };
            (other != NONE).then_some(other as usize)
        };
        // [`Level::next_around_vertex`] through `across`.
        let next_around = |c: usize| {
            let p = self.prev_of(quads, c);
            across(edges.corner_edges[p], p)
        };
        let start = corners[0] as usize;
        let mut seen = 1;
        let mut c = start;
        while let Some(next) = next_around(c) {
            if next == start {
                return seen == n;
            }
            seen += 1;
            c = next;
            if seen > n {
                return false;
            }
        }
        let mut c = start;
        while let Some(back) = across(edges.corner_edges[c], c).map(|d| self.next_of(quads, d)) {
            seen += 1;
            c = back;
            if seen > n {
                return false;
            }
        }
        seen == n
    }

    /// Builds the first level from a cage, with `corner_verts` renumbered so that every vertex
    /// is used.
    pub(crate) fn from_cage(
        cage: &Cage,
        num_vertices: usize,
        corner_verts: Vec<u32>,
    ) -> Result<Level> {
        let offsets = memory::collect(cage.face_offsets().iter().copied())?;
        Level::from_polygons(num_vertices, offsets, corner_verts)
    }

    /// Splits this level once: the quad of corner `c = (v, f)` is
    /// `v, edge(c), face(f), edge(prev(c))`, and the new vertices are numbered old vertices,
    /// then edge points (`V + e`), then face points (`V + E + f`).
    ///
    /// Child edges: `2e` and `2e + 1` are the halves of edge `e` (containing its first and second
    /// vertex), `2E + c` joins the edge point of `c`'s outgoing edge to the face point.
    pub(crate) fn refine(&self) -> Result<Level> {
        // The child's faces, edge tables and vertex -> corner table each read only this level:
        // made side by side, so that a small level (the adaptive partial levels, whose passes
        // are too short to share out one by one) still keeps two threads busy.
        let new_vertices = self.num_vertices + self.num_edges() + self.num_faces();
        let (child, (edges, corners)) = rayon::join(
            || self.refine_faces(),
            || {
                rayon::join(
                    || self.child_edges(),
                    || self.child_vertex_corners(new_vertices, false),
                )
            },
        );
        let (offsets, vert_corners) = corners?;
        Ok(Level {
            edges: OnceLock::from(edges?),
            vert_corner_offsets: offsets,
            vert_corners,
            ..child?
        })
    }

    /// As [`Level::refine`], the faces only: the edge tables wait for
    /// [`Level::complete_from`], the vertex -> corner table for [`Level::corners_of_vertex`]
    /// (in increasing order of corner). This is the last level of a plan, which evaluation
    /// reads only through its faces and vertex count.
    pub(crate) fn refine_faces(&self) -> Result<Level> {
        let nv = self.num_vertices as u32;
        let ne = self.num_edges() as u32;
        let corner_edges = self.corner_edges();
        let corner_verts = if self.all_quads() {
            // Face by face, no lookups of faces or neighbouring corners (a third of the
            // instructions).
            let (quads, _) = self.corner_verts.as_chunks::<4>();
            let (edge_quads, _) = corner_edges.as_chunks::<4>();
            let children = gather_hinted(quads.len(), |f| {
                let (v, e) = (quads[f], edge_quads[f]);
                let face_point = nv + ne + f as u32;
                std::array::from_fn::<[u32; 4], 4, _>(|k| {
                    [v[k], nv + e[k], face_point, nv + e[(k + 3) & 3]]
                })
            })?;
            children.into_flattened()
        } else {
            gather_hinted(self.num_corners(), |c| {
                [
                    self.corner_verts[c],
                    nv + corner_edges[c],
                    nv + ne + self.face_of(c) as u32,
                    nv + corner_edges[self.prev(c)],
                ]
            })?
        };
        // Tags: old vertices keep theirs, a non-manifold edge's point and halves are tagged.
        let nm_vertices = (self.nm_vertices.iter().copied())
            .chain(self.nm_edges.iter().map(|&e| nv + e))
            .collect();
        let nm_edges = self
            .nm_edges
            .iter()
            .flat_map(|&e| [2 * e, 2 * e + 1])
            .collect();
        Ok(Level {
            num_vertices: self.num_vertices + self.num_edges() + self.num_faces(),
            corner_verts: corner_verts.into_flattened(),
            num_edges: 2 * self.num_edges() + self.num_corners(),
            nm_vertices,
            nm_edges,
            ..Level::default()
        })
    }

    /// The child slot of the slot `c` of an edge whose first vertex is `first`, in its half
    /// `k`: the corner leaving the first vertex starts half 0 and ends half 1.
    #[inline(always)]
    fn half_slot(&self, first: u32, k: usize, c: u32) -> u32 {
        let c = c as usize;
        if (self.corner_verts[c] == first) == (k == 0) {
            4 * c as u32
        } else {
            4 * self.next(c) as u32 + 3
        }
    }

    /// The edge tables of this level's child (see [`Level::refine`] for their numbering).
    fn child_edges(&self) -> Result<Edges> {
        if self.quads_without_fins() {
            self.child_edges_of_quads()
        } else {
            self.child_edges_of_polygons()
        }
    }

    /// [`Level::child_edges`] of a level of quads whose edges have at most two faces, face by
    /// face and edge by edge in two sections (the same tables: the halves of each edge, then
    /// one interior edge per corner): rayon's `unzip_into_vecs` over one index range was about
    /// 80 instructions an edge, most of a level's edge tables.
    fn child_edges_of_quads(&self) -> Result<Edges> {
        let nv = self.num_vertices as u32;
        let ne = self.num_edges() as u32;
        let nc = self.num_corners();
        let Edges {
            corner_edges,
            verts: edge_verts,
            corners: edge_corners,
            ..
        } = self.edges();
        let (quads, _) = self.corner_verts.as_chunks::<4>();
        let (edge_quads, _) = corner_edges.as_chunks::<4>();
        let quad_edges = gather_hinted(quads.len(), |f| {
            let (v, e) = (quads[f], edge_quads[f]);
            // The half of each corner's outgoing edge at the corner; the other half of the
            // previous corner's is the incoming edge's half at the corner (for a degenerate
            // edge too: the half leaving, then the half arriving).
            let half: [u32; 4] =
                std::array::from_fn(|k| 2 * e[k] + (edge_verts[e[k] as usize][0] != v[k]) as u32);
            let c = 2 * ne + 4 * f as u32;
            std::array::from_fn::<[u32; 4], 4, _>(|k| {
                let p = (k + 3) & 3;
                [half[k], c + k as u32, c + p as u32, half[p] ^ 1]
            })
        })?;
        let total_edges = 2 * ne as usize + nc;
        let mut verts = zeroed_hinted::<[u32; 2]>(total_edges)?;
        let mut corners = zeroed_hinted::<[u32; 2]>(total_edges)?;
        let (half_verts, inner_verts) = verts.split_at_mut(2 * ne as usize);
        let (half_corners, inner_corners) = corners.split_at_mut(2 * ne as usize);
        // Halves: the corner leaving the edge's first vertex starts half 0 and ends half 1.
        let slots = |first: u32, c: u32| {
            let c = c as usize;
            let (start, end) = (4 * c as u32, 4 * quad_next(c) as u32 + 3);
            if self.corner_verts[c] == first {
                [start, end]
            } else {
                [end, start]
            }
        };
        // Both halves of an edge as one row, in step with the edge's rows.
        let (half_verts, _) = half_verts.as_chunks_mut::<2>();
        let (half_corners, _) = half_corners.as_chunks_mut::<2>();
        half_verts
            .par_chunks_mut(CHUNK)
            .zip(half_corners.par_chunks_mut(CHUNK))
            .zip(edge_verts.par_chunks(CHUNK))
            .zip(edge_corners.par_chunks(CHUNK))
            .enumerate()
            .for_each(|(chunk, (((hv, hc), verts), corners))| {
                let start = chunk * CHUNK;
                let rows = verts.iter().zip(corners);
                for (i, ((hv, hc), (&[a, b], &[c0, c1]))) in
                    hv.iter_mut().zip(hc).zip(rows).enumerate()
                {
                    let mid = nv + (start + i) as u32;
                    let s0 = slots(a, c0);
                    let s1 = if c1 == NONE { [NONE; 2] } else { slots(a, c1) };
                    *hv = [[a, mid], [mid, b]];
                    *hc = [[s0[0], s1[0]], [s0[1], s1[1]]];
                }
            });
        // Interior edges: from the edge point of a corner's outgoing edge to the face point,
        // face by face (the next corner of the k-th is the `(k + 1) % 4`-th, no arithmetic).
        let (inner_verts, _) = inner_verts.as_chunks_mut::<4>();
        let (inner_corners, _) = inner_corners.as_chunks_mut::<4>();
        inner_verts
            .par_chunks_mut(CHUNK)
            .zip(inner_corners.par_chunks_mut(CHUNK))
            .zip(edge_quads.par_chunks(CHUNK))
            .enumerate()
            .for_each(|(chunk, ((iv, ic), rows))| {
                let start = chunk * CHUNK;
                for (i, ((iv, ic), e)) in iv.iter_mut().zip(ic).zip(rows).enumerate() {
                    let f = (start + i) as u32;
                    let face_point = nv + ne + f;
                    *iv = std::array::from_fn(|k| [nv + e[k], face_point]);
                    *ic = std::array::from_fn(|k| {
                        [
                            16 * f + 4 * k as u32 + 1,
                            16 * f + 4 * ((k as u32 + 1) & 3) + 2,
                        ]
                    });
                }
            });
        Ok(Edges {
            corner_edges: quad_edges.into_flattened().into_flattened(),
            verts,
            corners,
            more: Vec::new(),
        })
    }

    /// [`Level::child_edges`] of any level.
    fn child_edges_of_polygons(&self) -> Result<Edges> {
        let nv = self.num_vertices as u32;
        let ne = self.num_edges() as u32;
        let nc = self.num_corners();
        let Edges {
            corner_edges,
            verts: edge_verts,
            corners: edge_corners,
            more,
        } = self.edges();
        let quad_edges = gather_hinted(nc, |c| {
            let v = self.corner_verts[c];
            let p = self.prev(c);
            [
                self.child_half(corner_edges[c], v),
                2 * ne + c as u32,
                2 * ne + p as u32,
                self.child_half_arriving(corner_edges[p], v),
            ]
        })?;

        // Edges: the two halves of every old edge, then one interior edge per old corner.
        let total_edges = 2 * ne as usize + nc;
        let mut verts: Vec<[u32; 2]> = with_capacity_hinted(total_edges)?;
        let mut corners: Vec<[u32; 2]> = with_capacity_hinted(total_edges)?;
        (0..total_edges)
            .into_par_iter()
            .with_min_len(CHUNK)
            .map(|i| {
                if i < 2 * ne as usize {
                    let (e, k) = (i >> 1, i & 1);
                    let [a, b] = edge_verts[e];
                    let mid = nv + e as u32;
                    let ends = if k == 0 { [a, mid] } else { [mid, b] };
                    // The first slot is always there.
                    let [c0, c1] = edge_corners[e];
                    let second = if c1 == NONE {
                        NONE
                    } else {
                        self.half_slot(a, k, c1)
                    };
                    let slots = [self.half_slot(a, k, c0), second];
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
        let mut child_more: Vec<(u32, u32)> = (more.iter())
            .flat_map(|&(e, c)| {
                let e = e as usize;
                [0, 1].map(|k| ((2 * e + k) as u32, self.half_slot(edge_verts[e][0], k, c)))
            })
            .collect();
        child_more.sort_by_key(|m| m.0);
        Ok(Edges {
            corner_edges: quad_edges.into_flattened(),
            verts,
            corners,
            more: child_more,
        })
    }

    /// Vertex -> corners of the child level: an old vertex keeps one corner per old corner, an
    /// edge point has two per incident face, a face point one per corner of its face; in
    /// increasing order of corner when `increasing` (the order of [`Level::corners_of_vertex`]'s
    /// table built on first use).
    fn child_vertex_corners(
        &self,
        new_vertices: usize,
        increasing: bool,
    ) -> Result<(Vec<u32>, Vec<u32>)> {
        if self.quads_without_fins() {
            self.child_vertex_corners_of_quads(increasing)
        } else {
            self.child_vertex_corners_of_polygons(new_vertices, increasing)
        }
    }

    /// [`Level::child_vertex_corners`] of any level, vertex by vertex.
    fn child_vertex_corners_of_polygons(
        &self,
        new_vertices: usize,
        increasing: bool,
    ) -> Result<(Vec<u32>, Vec<u32>)> {
        let (nv, ne) = (self.num_vertices, self.num_edges());
        // Where each edge's extra slots start in `more` (a search per edge would cost more than
        // the rest of the table on a non-manifold level); empty on a manifold level.
        let more = &self.edges().more;
        let manifold = more.is_empty();
        let mut more_at: Vec<u32> = Vec::new();
        if !manifold {
            more_at = memory::zeroed(ne + 1)?;
            for &(e, _) in more {
                more_at[e as usize + 1] += 1;
            }
            for e in 0..ne {
                more_at[e + 1] += more_at[e];
            }
        }
        let extra = |e: usize| {
            if more_at.is_empty() {
                &more[..0]
            } else {
                &more[more_at[e] as usize..more_at[e + 1] as usize]
            }
        };
        let offsets = prefix_offsets(new_vertices, |w| {
            if w < nv {
                self.corners_of_vertex(w).len() as u32
            } else if w < nv + ne {
                let [_, c1] = self.edge_corners()[w - nv];
                let extra = if manifold {
                    0
                } else {
                    extra(w - nv).len() as u32
                };
                2 * (1 + u32::from(c1 != NONE) + extra)
            } else {
                self.face_corners(w - nv - ne).len() as u32
            }
        })?;
        let mut vert_corners = zeroed_hinted::<u32>(4 * self.num_corners())?;
        fill_csr(&offsets, &mut vert_corners, |w, out| {
            if w < nv {
                for (o, &c) in out.iter_mut().zip(self.corners_of_vertex(w)) {
                    *o = 4 * c;
                }
            } else if w < nv + ne {
                // The slots in `edge_slots` order: the first two (the second maybe missing),
                // then the extra ones, written out (the slot iterator does not inline).
                let [c0, c1] = self.edge_corners()[w - nv];
                out[0] = 4 * c0 + 1;
                out[1] = 4 * self.next(c0 as usize) as u32 + 3;
                if c1 != NONE {
                    out[2] = 4 * c1 + 1;
                    out[3] = 4 * self.next(c1 as usize) as u32 + 3;
                }
                if !manifold {
                    let mut k = if c1 != NONE { 4 } else { 2 };
                    for &(_, c) in extra(w - nv) {
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
        Ok((offsets, vert_corners))
    }

    /// [`Level::child_vertex_corners`] of a level of quads whose edges have at most two faces
    /// (every level after the first, mostly), section by section: the old vertices' offsets
    /// are this level's, then two entries per slot of each edge, four per face. Only the
    /// lists that are out of order are sorted (an old vertex that was an edge point here; an
    /// edge point's two pairs by a network of compares): a sort per vertex was three quarters
    /// of the table (fresh averaging 4, level 3: 39.5M instructions for the last level's).
    fn child_vertex_corners_of_quads(&self, increasing: bool) -> Result<(Vec<u32>, Vec<u32>)> {
        let (nv, nc) = (self.num_vertices, self.num_corners());
        let nf = nc / 4;
        let (parent_offsets, parent_corners) = self.vertex_corner_table();
        let edge_corners = self.edge_corners();
        let mut offsets = with_capacity_hinted::<u32>(nv + edge_corners.len() + nf + 1)?;
        offsets.extend_from_slice(parent_offsets);
        // Every corner is at one vertex and is one slot of one edge (two child corners each).
        // A closed level's edge offsets step by four (a count of the boundary edges is one
        // vectorised pass; the running sum is not).
        let boundary = edge_corners.iter().filter(|&&[_, c1]| c1 == NONE).count();
        let mut at = nc as u32;
        if boundary == 0 {
            offsets.extend((1..=edge_corners.len() as u32).map(|e| at + 4 * e));
            at += 4 * edge_corners.len() as u32;
        } else {
            offsets.extend(edge_corners.iter().map(|&[_, c1]| {
                at += if c1 == NONE { 2 } else { 4 };
                at
            }));
        }
        offsets.extend((1..=nf as u32).map(|f| at + 4 * f));
        let mut vert_corners = zeroed_hinted::<u32>(4 * nc)?;
        let (old, rest) = vert_corners.split_at_mut(nc);
        let (edge_points, face_points) = rest.split_at_mut(2 * nc);
        // An old vertex's corners are its corners here, times four (the offsets are the same),
        // so the section is one map; the lists out of order are then sorted vertex by vertex.
        old.par_chunks_mut(CHUNK)
            .zip(parent_corners.par_chunks(CHUNK))
            .for_each(|(out, from)| {
                for (o, &c) in out.iter_mut().zip(from) {
                    *o = 4 * c;
                }
            });
        if increasing {
            sort_lists(&offsets[..=nv], old);
        }
        // The two child corners of slot c, and the same in increasing order: they are in c's
        // face, `4 next(c) + 3` first when `next(c)` wraps round to the face's first corner.
        let pair = |c: u32| [4 * c + 1, 4 * quad_next(c as usize) as u32 + 3];
        let sorted_pair = |c: u32| {
            // `next(c)` wraps round to `c - 3` (child corner `4 c - 9`) from the fourth corner.
            let wrap = u32::from(c & 3 == 3);
            [4 * c + 1 - 10 * wrap, 4 * c + 7 - 6 * wrap]
        };
        // An edge's four child corners in increasing order: the two slots are in two faces
        // (a face using an edge twice has two edges), so the earlier face's pair comes first.
        let sorted_four = |c0: u32, c1: u32| {
            if c0 >> 2 == c1 >> 2 {
                let ([a, b], [c, d]) = (pair(c0), pair(c1));
                let mut four = [a, b, c, d];
                sort4(&mut four);
                four
            } else {
                let ([a, b], [c, d]) = (sorted_pair(c0.min(c1)), sorted_pair(c0.max(c1)));
                [a, b, c, d]
            }
        };
        if at as usize == nc + 4 * edge_corners.len() {
            // No boundary: four entries per edge, written in fixed rows.
            edge_points
                .par_chunks_mut(4 * CHUNK)
                .zip(edge_corners.par_chunks(CHUNK))
                .for_each(|(out, rows)| {
                    for (out, &[c0, c1]) in out.chunks_exact_mut(4).zip(rows) {
                        let four = if increasing {
                            sorted_four(c0, c1)
                        } else {
                            let ([a, b], [c, d]) = (pair(c0), pair(c1));
                            [a, b, c, d]
                        };
                        out.copy_from_slice(&four);
                    }
                });
        } else {
            fill_csr(
                &offsets[nv..=nv + edge_corners.len()],
                edge_points,
                |e, out| {
                    let [c0, c1] = edge_corners[e];
                    if c1 == NONE {
                        if let Ok(out) = <&mut [u32; 2]>::try_from(out) {
                            *out = if increasing {
                                sorted_pair(c0)
                            } else {
                                pair(c0)
                            };
                        }
                    } else if let Ok(out) = <&mut [u32; 4]>::try_from(out) {
                        *out = if increasing {
                            sorted_four(c0, c1)
                        } else {
                            let ([a, b], [c, d]) = (pair(c0), pair(c1));
                            [a, b, c, d]
                        };
                    }
                },
            );
        }
        // A face point's corners are its face's, in order: child corner `4 c + 2` of corner c.
        face_points
            .par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(chunk, out)| {
                // A counter of its own, in 32 bits, which vectorises.
                let mut child = 4 * (chunk * CHUNK) as u32 + 2;
                for o in out {
                    *o = child;
                    child += 4;
                }
            });
        Ok((offsets, vert_corners))
    }
}

/// Sorts the lists of a CSR table that are out of order (each list short: [`sort_short`]), in
/// the fixed chunks of [`fill_csr`], each list read through its two offsets once.
fn sort_lists(offsets: &[u32], data: &mut [u32]) {
    csr_chunks(offsets, data)
        .into_par_iter()
        .for_each(|(start, end, piece)| {
            let mut rest = piece;
            for pair in offsets[start..=end].windows(2) {
                let (list, tail) = rest.split_at_mut((pair[1] - pair[0]) as usize);
                rest = tail;
                if let Ok(four) = <&mut [u32; 4]>::try_from(&mut *list) {
                    if !(four[0] <= four[1] && four[1] <= four[2] && four[2] <= four[3]) {
                        sort4(four);
                    }
                } else if !list.is_sorted() {
                    sort_short(list);
                }
            }
        });
}

/// Sorts a short list by insertion (the lists out of order in a vertex -> corner table are an
/// old edge point's, four entries on a manifold level), a long one by `sort_unstable`.
fn sort_short(list: &mut [u32]) {
    if list.len() > 8 {
        list.sort_unstable();
        return;
    }
    for i in 1..list.len() {
        let x = list[i];
        let mut j = i;
        while j > 0 && list[j - 1] > x {
            list[j] = list[j - 1];
            j -= 1;
        }
        list[j] = x;
    }
}

/// Sorts four values with a network of five compare-exchanges.
#[inline(always)]
fn sort4(v: &mut [u32; 4]) {
    for (i, j) in [(0, 1), (2, 3), (0, 2), (1, 3), (1, 2)] {
        let (lo, hi) = (v[i].min(v[j]), v[i].max(v[j]));
        (v[i], v[j]) = (lo, hi);
    }
}

/// Vertex -> corners by counting sort (corners in increasing order).
fn vertex_corners(num_vertices: usize, corner_verts: &[u32]) -> Result<(Vec<u32>, Vec<u32>)> {
    let mut offsets = memory::zeroed::<u32>(num_vertices + 1)?;
    for &v in corner_verts {
        offsets[v as usize + 1] += 1;
    }
    for v in 0..num_vertices {
        offsets[v + 1] += offsets[v];
    }
    let mut fill = memory::collect(offsets.iter().copied())?;
    let mut vert_corners = memory::zeroed::<u32>(corner_verts.len())?;
    for (c, &v) in corner_verts.iter().enumerate() {
        vert_corners[fill[v as usize] as usize] = c as u32;
        fill[v as usize] += 1;
    }
    Ok((offsets, vert_corners))
}

/// The next corner around a quad of a quad level (its four corners are `4f..4f + 4`), with no
/// lookup: [`Level::next`] there, for the passes that know their level is all quads.
#[inline(always)]
pub(crate) fn quad_next(corner: usize) -> usize {
    (corner & !3) | ((corner + 1) & 3)
}

/// The previous corner around a quad of a quad level ([`quad_next`]).
#[inline(always)]
pub(crate) fn quad_prev(corner: usize) -> usize {
    (corner & !3) | ((corner + 3) & 3)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Edges the straightforward way: every half keyed by its (smaller, larger) vertex pair,
    /// sorted, equal keys grouped, then split as OpenSubdiv does (a degenerate half alone, the
    /// i-th use of the pair by one face in the i-th edge); also the non-manifold edges.
    fn edges_by_sorting(level: &Level) -> (Edges, Vec<u32>) {
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
        let mut nm_edges = Vec::new();
        for group in halves.chunk_by(|x, y| x.0 == y.0) {
            let degenerate = group[0].0 >> 32 == group[0].0 & 0xffff_ffff;
            let mut instances: Vec<Vec<u32>> = Vec::new();
            let mut uses: Vec<(usize, usize)> = Vec::new();
            for h in group {
                let f = level.face_of(h.1 as usize);
                let i = if degenerate {
                    instances.len()
                } else {
                    let n = uses.iter().filter(|u| u.0 == f).count();
                    uses.push((f, n));
                    n
                };
                if instances.len() == i {
                    instances.push(Vec::new());
                }
                instances[i].push(h.1);
            }
            let same_way = group.len() == 2
                && level.corner_verts[group[0].1 as usize]
                    == level.corner_verts[group[1].1 as usize];
            let nm = degenerate || instances.len() > 1 || group.len() > 2 || same_way;
            for slots in instances {
                let e = edges.verts.len() as u32;
                for &c in &slots {
                    edges.corner_edges[c as usize] = e;
                }
                let c0 = slots[0] as usize;
                edges
                    .verts
                    .push([level.corner_verts[c0], level.corner_verts[level.next(c0)]]);
                edges
                    .corners
                    .push([slots[0], slots.get(1).copied().unwrap_or(NONE)]);
                edges.more.extend(slots.iter().skip(2).map(|&c| (e, c)));
                if nm {
                    nm_edges.push(e);
                }
            }
        }
        (edges, nm_edges)
    }

    /// Every corner is a slot of its outgoing edge, exactly once, and the edge runs between the
    /// corner's vertex and the next one.
    fn slots_consistent(level: &Level) -> bool {
        let mut count = vec![0usize; level.num_corners()];
        for e in 0..level.num_edges() {
            for c in level.edge_slots(e) {
                let c = c as usize;
                count[c] += 1;
                let ends = [level.corner_verts[c], level.corner_verts[level.next(c)]];
                let [a, b] = level.edge_verts()[e];
                if level.corner_edges()[c] as usize != e || !(ends == [a, b] || ends == [b, a]) {
                    return false;
                }
            }
        }
        count.iter().all(|&n| n == 1)
    }

    fn same_edges(a: &Edges, b: &Edges) -> bool {
        a.corner_edges == b.corner_edges
            && a.verts == b.verts
            && a.corners == b.corners
            && a.more == b.more
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
                // A (w x h) grid of quads, wrapped in one direction when seed % 4 == 0 and
                // closed (a torus: no boundary) when seed % 8 == 0.
                let (w, h) = (2 + next(5) as usize, 2 + next(5) as usize);
                let (wrap, closed) = (seed % 4 == 0, seed % 8 == 0);
                let cols = if wrap { w } else { w + 1 };
                let rows = if closed { h } else { h + 1 };
                let id = |i: usize, j: usize| ((j % rows) * cols + i % cols) as u32;
                for j in 0..h {
                    for i in 0..w {
                        verts.extend([id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
                        offsets.push(verts.len() as u32);
                    }
                }
                return (cols * rows, offsets, verts);
            }
            for _ in 0..faces {
                let size = 3 + next(4) as usize;
                let start = verts.len();
                while verts.len() - start < size.min(vertices) {
                    let v = next(vertices);
                    // Sometimes a face repeats a vertex (as dirty input does).
                    if seed % 3 == 0 || !verts[start..].contains(&v) {
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
            let (expected, nm_edges) = edges_by_sorting(&bare);
            let level = Level::from_polygons(vertices, offsets, verts).unwrap();
            prop_assert!(same_edges(level.edges(), &expected));
            prop_assert_eq!(&level.nm_edges, &nm_edges);
            prop_assert!(slots_consistent(&level));
            // A faces-only child completed later equals the full refinement.
            let (full, faces_only) = (level.refine().unwrap(), level.refine_faces().unwrap());
            prop_assert!(!faces_only.has_edges());
            faces_only.complete_from(&level).unwrap();
            // The vertex -> corner table built from the parent equals the counting sort.
            let indexed = level.refine_faces().unwrap();
            indexed.index_vertex_corners_from(&level).unwrap();
            let sorted = vertex_corners(full.num_vertices, &full.corner_verts).unwrap();
            for v in 0..full.num_vertices {
                let expected = &sorted.1[sorted.0[v] as usize..sorted.0[v + 1] as usize];
                let mut listed = full.corners_of_vertex(v).to_vec();
                listed.sort_unstable();
                prop_assert_eq!(&listed[..], expected);
                prop_assert_eq!(indexed.corners_of_vertex(v), expected);
                prop_assert_eq!(faces_only.corners_of_vertex(v), expected);
            }
            prop_assert_eq!(&faces_only.corner_verts, &full.corner_verts);
            prop_assert_eq!(faces_only.num_edges(), full.num_edges());
            prop_assert!(same_edges(faces_only.edges(), full.edges()));
            prop_assert!(slots_consistent(&full));
            let grand = full.refine().unwrap();
            prop_assert_eq!(grand.num_edges(), grand.edge_verts().len());
            prop_assert!(slots_consistent(&grand));
            prop_assert_eq!(level.is_non_manifold(), grand.is_non_manifold());
            // The table of a quad level's child, section by section, equals the one built
            // vertex by vertex.
            for parent in [&level, &full, &grand] {
                if parent.quads_without_fins() {
                    let n = parent.num_vertices + parent.num_edges() + parent.num_faces();
                    for increasing in [false, true] {
                        let fast = parent.child_vertex_corners_of_quads(increasing).unwrap();
                        let slow = parent.child_vertex_corners_of_polygons(n, increasing).unwrap();
                        prop_assert_eq!(fast, slow);
                    }
                    let (fast, slow) = (
                        parent.child_edges_of_quads().unwrap(),
                        parent.child_edges_of_polygons().unwrap(),
                    );
                    prop_assert!(same_edges(&fast, &slow));
                }
            }
        }
    }
}
