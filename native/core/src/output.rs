//! Output meshes: the drawing mesh (`M_L` itself) or the true dual mesh of `M_L`, with edges,
//! corner edges, the cage face of every face and the cage edge of every edge.
//!
//! The dual mesh has one face per *fan* of each vertex of `M_L` (the faces around the vertex
//! that are joined across manifold edges; a vertex has one fan, a non-manifold vertex one per
//! sheet), its corners the points of the fan's faces, closed where the fan opens (a boundary
//! or non-manifold edge: both are infinitely sharp curve edges) by the 1-D points of those
//! curve edges. The sheets of a non-manifold edge share its 1-D points, so their dual faces meet
//! there as their drawing meshes meet along the curve.
//!
//! Holes: a face of the drawing mesh is left out when its cage face is a hole; a face of the
//! dual mesh when some face of its fan is (its corners would be points inside the hole), so the
//! dual mesh never reaches into a hole, as the drawing mesh does not. Both then leave out the
//! vertices only left-out faces use, and keep the others in their order.

use std::sync::OnceLock;

use crate::error::{Error, Result};
use crate::memory;
use crate::options::OutputKind;
use crate::parallel::gather_hinted;
use crate::refinement::Refinement;
use crate::scalar::{Scalar, Value};
use crate::scheme::decrement;
use crate::step::Final;
use crate::topology::{Level, NONE};

/// An output mesh that is not `M_L` itself (the dual mesh, or the drawing mesh without its
/// holes), as a polygon level plus where its data comes from.
#[derive(Debug, Default)]
struct PolygonMesh {
    /// Its polygons, edges and adjacency.
    level: Level,
    /// True for the dual mesh, whose points are the face points of `M_L`, then the 1-D points
    /// of `boundary_points`; false for the drawing mesh without its holes.
    dual: bool,
    /// Indices (among the last step's curve edges) of the curve edges where fans open (boundary
    /// and non-manifold edges) whose 1-D points follow the face points among the dual's points.
    boundary_points: Vec<u32>,
    /// For each corner, the corner of `M_L` whose face-varying value it takes.
    corner_source: Vec<u32>,
    /// Cage face of each face.
    face_origin: Vec<u32>,
    /// With holes: the point (a vertex of `M_L`, or a point of the dual mesh) of each output
    /// vertex (none at all when every face is left out); `None` when every point is one.
    vertex_source: Option<Vec<u32>>,
}

/// Output topology that is not a table of the last level itself.
#[derive(Debug, Default)]
pub(crate) struct OutputMesh {
    /// Face offsets of the drawing mesh, built on first use.
    face_offsets: OnceLock<Vec<u32>>,
    /// Cage face of each face of the drawing mesh, built on first use.
    face_origin: OnceLock<Vec<u32>>,
    /// Cage edge of each output edge (`NONE` inside a cage face), built on first use.
    edge_origin: OnceLock<Vec<u32>>,
    /// The dual mesh, when asked for, or the drawing mesh without its holes.
    polygons: Option<PolygonMesh>,
}

impl OutputMesh {
    /// Builds the output topology of a refinement (the drawing mesh's own tables wait for their
    /// first use: evaluation does not need them).
    pub(crate) fn build(refinement: &Refinement) -> Result<OutputMesh> {
        let holes = !refinement.features().holes.is_empty();
        // Without a step there is no dual data: the dual output of 0 levels is the cage.
        if refinement.options().output == OutputKind::Dual && refinement.levels_as_built().len() > 1
        {
            let origin = face_origin(refinement)?;
            let mut dual = dual_mesh(refinement, &origin)?;
            if holes {
                dual = dual_without_holes(refinement, dual, &origin)?;
            }
            return Ok(OutputMesh {
                face_origin: OnceLock::from(origin),
                polygons: Some(dual),
                ..OutputMesh::default()
            });
        }
        if holes {
            return without_holes(refinement);
        }
        Ok(OutputMesh::default())
    }

    /// The dual mesh, when it is the output.
    fn dual(&self) -> Option<&PolygonMesh> {
        self.polygons.as_ref().filter(|p| p.dual)
    }

    /// Number of output vertices.
    pub(crate) fn num_vertices(&self, refinement: &Refinement) -> usize {
        match &self.polygons {
            Some(d) => d.level.num_vertices,
            None => refinement.last_level().num_vertices,
        }
    }

    /// Number of output faces.
    pub(crate) fn num_faces(&self, refinement: &Refinement) -> usize {
        match &self.polygons {
            Some(d) => d.level.num_faces(),
            None => refinement.last_level().num_faces(),
        }
    }

    /// The output mesh as a level; `with_edges` completes the drawing mesh's edge tables.
    fn level<'a>(&'a self, refinement: &'a Refinement, with_edges: bool) -> &'a Level {
        match &self.polygons {
            Some(d) => &d.level,
            None => {
                if with_edges {
                    // The accessors' contract (`Plan::complete_output`): a refused allocation
                    // completing the last level's tables panics here.
                    refinement.levels();
                }
                refinement.last_level()
            }
        }
    }

    /// Builds the tables that wait for their first use (face offsets, cage faces, the last
    /// level's edges), so that a refused allocation is an error here rather than a panic in an
    /// accessor.
    pub(crate) fn complete(&self, refinement: &Refinement) -> Result<()> {
        if self.polygons.is_none() {
            lazy(&self.face_offsets, || drawing_face_offsets(refinement))?;
            lazy(&self.face_origin, || face_origin(refinement))?;
        }
        refinement.complete_levels()
    }

    /// Offsets of each output face's vertices in [`OutputMesh::face_vertices`] (faces + 1).
    pub(crate) fn face_offsets<'a>(&'a self, refinement: &'a Refinement) -> &'a [u32] {
        match &self.polygons {
            Some(d) => &d.level.face_offsets,
            None => lazy(&self.face_offsets, || drawing_face_offsets(refinement))
                .unwrap_or_else(|e| panic!("output face offsets: {e}")),
        }
    }

    /// Vertex indices of the output faces, face after face, counter-clockwise like the cage.
    pub(crate) fn face_vertices<'a>(&'a self, refinement: &'a Refinement) -> &'a [u32] {
        &self.level(refinement, false).corner_verts
    }

    /// The cage face each output face comes from.
    pub(crate) fn face_origin<'a>(&'a self, refinement: &'a Refinement) -> &'a [u32] {
        match &self.polygons {
            Some(d) => &d.face_origin,
            None => lazy(&self.face_origin, || face_origin(refinement))
                .unwrap_or_else(|e| panic!("output face origins: {e}")),
        }
    }

    /// The edges of the output mesh.
    pub(crate) fn edges<'a>(&'a self, refinement: &'a Refinement) -> &'a [[u32; 2]] {
        self.level(refinement, true).edge_verts()
    }

    /// For each entry of [`OutputMesh::face_vertices`], the edge to the next corner of its face.
    pub(crate) fn corner_edges<'a>(&'a self, refinement: &'a Refinement) -> &'a [u32] {
        self.level(refinement, true).corner_edges()
    }

    /// The cage edge (an edge of `M_0`) each output edge lies on, [`NONE`] for an edge inside a
    /// cage face. Drawing mesh: the halves of edge `e` are edges `2e` and `2e + 1` of the next
    /// level ([`Level::refine`]), every other edge is inside a face. Dual mesh: only the edges
    /// that close a fan where it opens (between the boundary points of two halves of one cage
    /// edge) lie on a cage edge; every other dual edge crosses the edges of `M_L`.
    /// Built on first use; a refused allocation is an error.
    pub(crate) fn edge_origin<'a>(&'a self, refinement: &'a Refinement) -> Result<&'a [u32]> {
        lazy(&self.edge_origin, || self.edge_origin_table(refinement))
    }

    /// The table of [`OutputMesh::edge_origin`].
    fn edge_origin_table(&self, refinement: &Refinement) -> Result<Vec<u32>> {
        let levels = refinement.try_levels()?;
        let last = refinement.last_level();
        let origin = |e: u32| primal_edge_origin(levels, e);
        match &self.polygons {
            None => gather_hinted(last.num_edges(), |e| origin(e as u32)),
            Some(d) if !d.dual => {
                gather_hinted(d.level.num_edges(), |e| origin(self.level_edge(last, e)))
            }
            Some(d) => {
                let curves = refinement.last_network("the dual output's edge origins")?;
                let num_faces = last.num_faces() as u32;
                let on_cage = |p: u32| {
                    let p = d.vertex_source.as_ref().map_or(p, |s| s[p as usize]);
                    p.checked_sub(num_faces).map(|i| {
                        origin(curves.edges()[d.boundary_points[i as usize] as usize].edge)
                    })
                };
                let edges = d.level.edge_verts();
                gather_hinted(edges.len(), |e| {
                    let [a, b] = edges[e];
                    match (on_cage(a), on_cage(b)) {
                        (Some(x), Some(y)) if x == y => x,
                        _ => NONE,
                    }
                })
            }
        }
    }

    /// The edge of `M_L` (`last`, its edge tables complete) that edge `e` of the drawing mesh
    /// is: itself, or, when holes are left out, the edge leaving the `M_L` corner of one of its
    /// corners.
    fn level_edge(&self, last: &Level, e: usize) -> u32 {
        match &self.polygons {
            Some(d) if !d.dual => {
                // `Level` makes each edge from the corners that leave along it.
                let c = d.level.edge_slots(e).next().expect("an edge has a corner");
                last.corner_edges()[d.corner_source[c as usize] as usize]
            }
            _ => e as u32,
        }
    }

    /// The sharpness each output edge keeps at the last level (what one more level would use):
    /// the classic Catmull-Clark rules' own per-level table on the drawing mesh (uniform or
    /// Chaikin creasing), otherwise its cage edge's sharpness lowered once per level
    /// ([`decrement`]); 0 for an edge inside a cage face. Boundary edges are infinitely sharp.
    pub(crate) fn edge_sharpness(&self, refinement: &Refinement) -> Result<Vec<f32>> {
        let depth = refinement.levels_as_built().len() - 1;
        let origin = self.edge_origin(refinement)?;
        let primal = self.dual().is_none();
        match refinement.sharpness(depth) {
            Some(level) if primal => {
                let last = refinement.last_level();
                gather_hinted(origin.len(), |e| {
                    level.edge(self.level_edge(last, e) as usize)
                })
            }
            _ => {
                let cage = &refinement.features().edge_sharpness;
                gather_hinted(origin.len(), |e| match origin[e] {
                    NONE => 0.0,
                    o => (0..depth).fold(cage[o as usize], |s, _| decrement(s)),
                })
            }
        }
    }

    /// Turns the values of the last level into output vertex values.
    pub(crate) fn finish<T: Scalar, const N: usize>(
        &self,
        result: Final<T, N>,
    ) -> Result<Vec<Value<T, N>>> {
        let points = match result {
            Final::Primal(points) => points,
            Final::Dual {
                mut faces,
                curve_edges,
            } => {
                let dual = self.dual().ok_or_else(|| {
                    Error::Internal(
                        "dual data needs the dual output mesh, and the plan has none".into(),
                    )
                })?;
                memory::reserve(&mut faces, dual.boundary_points.len())?;
                faces.extend(
                    dual.boundary_points
                        .iter()
                        .map(|&i| curve_edges[i as usize]),
                );
                faces
            }
        };
        self.vertex_values(points, 1)
    }

    /// Turns values at the points of the output mesh (the vertices of `M_L`, or the dual's
    /// points; `channels` interleaved per point, or one item per point) into values at the
    /// output vertices, which leave out the points that only holes use.
    pub(crate) fn vertex_values<V: Copy>(&self, values: Vec<V>, channels: usize) -> Result<Vec<V>> {
        match &self.polygons {
            Some(PolygonMesh {
                vertex_source: Some(source),
                ..
            }) => {
                let mut out = memory::with_capacity(source.len() * channels)?;
                out.extend(source.iter().flat_map(|&v| {
                    values[v as usize * channels..(v as usize + 1) * channels]
                        .iter()
                        .copied()
                }));
                Ok(out)
            }
            _ => Ok(values),
        }
    }

    /// For each output corner, the corner of `M_L` whose face-varying value it takes; `None`
    /// when the output corners are `M_L`'s.
    pub(crate) fn corner_sources(&self) -> Option<&[u32]> {
        self.polygons.as_ref().map(|p| p.corner_source.as_slice())
    }

    /// Turns face-varying values at the corners of `M_L` (`channels` interleaved per corner:
    /// UVs, limit normals) into values at the output corners.
    pub(crate) fn face_varying<T: Scalar>(
        &self,
        values: Vec<T>,
        channels: usize,
    ) -> Result<Vec<T>> {
        match &self.polygons {
            None => Ok(values),
            Some(d) => {
                let mut out = memory::with_capacity(d.corner_source.len() * channels)?;
                out.extend(d.corner_source.iter().flat_map(|&c| {
                    values[c as usize * channels..(c as usize + 1) * channels]
                        .iter()
                        .copied()
                }));
                Ok(out)
            }
        }
    }
}

/// The drawing mesh without the faces whose cage face is a hole.
fn without_holes(refinement: &Refinement) -> Result<OutputMesh> {
    let origin = face_origin(refinement)?;
    let last = refinement.last_level();
    let drawn = keep_faces(
        last,
        |c| c as u32,
        |f| origin[f],
        |f| !is_hole(refinement, origin[f]),
    )?;
    Ok(OutputMesh {
        polygons: Some(drawn),
        ..OutputMesh::default()
    })
}

/// The dual mesh without the faces whose fan has a face from a hole.
fn dual_without_holes(
    refinement: &Refinement,
    dual: PolygonMesh,
    origin: &[u32],
) -> Result<PolygonMesh> {
    let last = refinement.last_level();
    let from_hole = |c: u32| is_hole(refinement, origin[last.face_of(c as usize)]);
    let mut drawn = keep_faces(
        &dual.level,
        |c| dual.corner_source[c],
        |f| dual.face_origin[f],
        |f| {
            !dual
                .level
                .face_corners(f)
                .any(|c| from_hole(dual.corner_source[c]))
        },
    )?;
    drawn.dual = true;
    drawn.boundary_points = dual.boundary_points;
    Ok(drawn)
}

/// True if cage face `f` is a hole.
fn is_hole(refinement: &Refinement, f: u32) -> bool {
    refinement.features().holes.binary_search(&f).is_ok()
}

/// The faces of the polygon mesh `level` for which `keep` holds, with the `M_L` corner of each
/// corner (`corner_source`) and the cage face of each face (`origin`), without the points only
/// the other faces use (the rest numbered in their order: `vertex_source`).
fn keep_faces(
    level: &Level,
    corner_source: impl Fn(usize) -> u32,
    origin: impl Fn(usize) -> u32,
    keep: impl Fn(usize) -> bool,
) -> Result<PolygonMesh> {
    let mut kept: Vec<u32> = memory::with_capacity(level.num_faces())?;
    kept.extend((0..level.num_faces() as u32).filter(|&f| keep(f as usize)));
    let mut used = memory::filled(level.num_vertices, NONE)?;
    for &f in &kept {
        for c in level.face_corners(f as usize) {
            used[level.corner_verts[c] as usize] = 0;
        }
    }
    let mut vertex_source = memory::with_capacity(level.num_vertices)?;
    for (v, slot) in used.iter_mut().enumerate() {
        if *slot == 0 {
            *slot = vertex_source.len() as u32;
            vertex_source.push(v as u32);
        }
    }
    let mut offsets = memory::with_capacity(kept.len() + 1)?;
    offsets.push(0u32);
    let mut verts = memory::with_capacity(level.num_corners())?;
    let mut sources = memory::with_capacity(level.num_corners())?;
    for &f in &kept {
        for c in level.face_corners(f as usize) {
            verts.push(used[level.corner_verts[c] as usize]);
            sources.push(corner_source(c));
        }
        offsets.push(verts.len() as u32);
    }
    let face_origin = memory::collect(kept.iter().map(|&f| origin(f as usize)))?;
    Ok(PolygonMesh {
        level: Level::from_polygons(vertex_source.len(), offsets, verts)?,
        corner_source: sources,
        face_origin,
        vertex_source: Some(vertex_source),
        ..PolygonMesh::default()
    })
}

/// `table`, built by `build` unless it is already.
fn lazy(table: &OnceLock<Vec<u32>>, build: impl FnOnce() -> Result<Vec<u32>>) -> Result<&[u32]> {
    if let Some(table) = table.get() {
        return Ok(table);
    }
    let built = build()?;
    // Two threads building at once build the same table; one is kept.
    Ok(table.get_or_init(|| built))
}

/// Face offsets of the drawing mesh `M_L`.
fn drawing_face_offsets(refinement: &Refinement) -> Result<Vec<u32>> {
    let last = refinement.last_level();
    if last.is_quads() {
        gather_hinted(last.num_faces() + 1, |f| 4 * f as u32)
    } else {
        memory::collect(last.face_offsets.iter().copied())
    }
}

/// Face f of M_L is corner f of M_{L-1}, inside face f/4 of M_{L-1} (for L-1 >= 1), down to a
/// corner of the cage.
fn face_origin(refinement: &Refinement) -> Result<Vec<u32>> {
    let levels = refinement.levels_as_built();
    let last = refinement.last_level();
    let depth = levels.len() - 1;
    if depth == 0 {
        memory::collect(0..last.num_faces() as u32)
    } else {
        let shift = 2 * (depth - 1);
        let cage = &levels[0];
        gather_hinted(last.num_faces(), |f| cage.corner_faces[f >> shift])
    }
}

/// The edge of `M_0` that edge `e` of the last of `levels` lies on, [`NONE`] inside a face.
fn primal_edge_origin(levels: &[Level], mut e: u32) -> u32 {
    for parent in levels[..levels.len() - 1].iter().rev() {
        if e as usize >= 2 * parent.num_edges() {
            return NONE;
        }
        e /= 2;
    }
    e
}

/// The dual of `M_L`: the faces of each fan around each vertex, walked from face to face
/// across manifold edges and reversed so that the dual faces keep the orientation of the
/// surface; a fan that opens at boundary or non-manifold edges is closed by their 1-D points.
fn dual_mesh(refinement: &Refinement, face_origin: &[u32]) -> Result<PolygonMesh> {
    refinement.try_levels()?;
    let last = refinement.last_level();
    let curves = refinement.last_network("the dual mesh")?;
    let num_faces = last.num_faces() as u32;
    // No face across (`Level::opposite` is `None`): a fan opens there. Boundary and
    // non-manifold edges are infinitely sharp, so they are curve edges of every step.
    let opens = |e: u32| last.is_boundary_edge(e as usize) || last.is_non_manifold_edge(e as usize);
    let mut boundary_points: Vec<u32> = memory::with_capacity(curves.edges().len())?;
    boundary_points.extend(
        (0..curves.edges().len() as u32).filter(|&i| opens(curves.edges()[i as usize].edge)),
    );
    let point_of_edge = |e: u32| -> Result<u32> {
        let at = boundary_points
            .binary_search_by_key(&e, |&i| curves.edges()[i as usize].edge)
            .map_err(|_| {
                Error::Internal(format!(
                    "boundary or non-manifold edge {e} of the last level must be a curve edge \
                     of the last step"
                ))
            })?;
        Ok(num_faces + at as u32)
    };
    // A vertex has one dual face per fan: at most its corners, one per vertex mostly.
    let mut offsets = memory::with_capacity(last.num_vertices + 1)?;
    offsets.push(0u32);
    let mut verts = memory::with_capacity(last.num_corners() + 2 * boundary_points.len())?;
    let mut sources = memory::with_capacity(verts.capacity())?;
    let mut origin = memory::with_capacity(last.num_vertices)?;
    let mut visited = memory::zeroed::<bool>(last.num_corners())?;
    let mut centre = memory::with_capacity(last.num_vertices)?;
    for v in 0..last.num_vertices {
        let corners = last.corners_of_vertex(v);
        // Fans that open (at a boundary or non-manifold edge) come first, from the corner
        // after the opening; closed fans start anywhere.
        let incoming = |c: usize| last.corner_edges()[last.prev(c)];
        let starts = (corners.iter().copied()).filter(|&c| opens(incoming(c as usize)));
        let closed = corners.iter().copied();
        for start in starts.chain(closed) {
            if visited[start as usize] {
                continue;
            }
            let mut fan = Vec::new();
            let mut c = start as usize;
            loop {
                visited[c] = true;
                fan.push(c as u32);
                let Some(other) = last.opposite(last.corner_edges()[c] as usize, c) else {
                    break;
                };
                c = last.next(other);
                if visited[c] {
                    break;
                }
            }
            // The loop pushes `start` before it can break.
            let end = *fan.last().expect("a fan has a corner") as usize;
            if opens(last.corner_edges()[end]) {
                verts.push(point_of_edge(last.corner_edges()[end])?);
                sources.push(end as u32);
            }
            for &c in fan.iter().rev() {
                verts.push(c >> 2);
                sources.push(c);
            }
            if opens(incoming(fan[0] as usize)) {
                verts.push(point_of_edge(incoming(fan[0] as usize))?);
                sources.push(fan[0]);
            }
            offsets.push(verts.len() as u32);
            origin.push(face_origin[fan[0] as usize >> 2]);
            centre.push(v);
        }
    }
    let num_points = num_faces as usize + boundary_points.len();
    if let Some(f) = offsets.windows(2).position(|w| w[1] - w[0] < 3) {
        let v = centre[f];
        return Err(Error::InvalidInput(format!(
            "the dual output needs every vertex on at least 3 faces or a boundary; vertex {v} of the last level is not (the cage has a vertex of valence 2)"
        )));
    }
    let level = Level::from_polygons(num_points, offsets, verts)?;
    Ok(PolygonMesh {
        level,
        dual: true,
        boundary_points,
        corner_source: sources,
        face_origin: origin,
        vertex_source: None,
    })
}
