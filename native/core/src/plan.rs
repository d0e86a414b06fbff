//! The plan: the crate's one type for uniform subdivision. It owns the refinement of a cage
//! ([`Refinement`]: levels, curve networks, sharpness) and, on top of it, the caches of the
//! layers that read it: the output mesh ([`OutputMesh`]), the evaluation buffers ([`Scratch`])
//! and the limit stencils ([`LimitCache`]). Built once, it evaluates any number of point sets (a
//! deforming mesh re-evaluates without topology work). Every method here delegates to the
//! module that owns the work; none of those modules knows the plan.

use std::borrow::Cow;

use crate::curves::CurveNetwork;
use crate::error::{Error, Result};
use crate::evaluate;
use crate::face_varying::{self, FaceVaryingCache, FaceVaryingMode, SharedValues, Topology};
use crate::limit::{self, LimitCache};
use crate::mesh::{check_values, Cage};
use crate::options::{NormalDomain, Options};
use crate::output::OutputMesh;
use crate::parallel::in_pool;
use crate::refinement::Refinement;
use crate::scalar::Scalar;
use crate::step::Scratch;
use crate::topology::Level;

/// Everything that depends only on topology and options, and the caches of its evaluations;
/// see the module documentation.
#[derive(Debug)]
pub struct Plan {
    refinement: Refinement,
    output: OutputMesh,
    scratch: Scratch,
    limit: LimitCache,
    face_varying: FaceVaryingCache,
}

impl Plan {
    /// Builds the plan: validates the cage topology and the options, checks the memory budget,
    /// then refines the topology level by level, lays out the curve networks and the output
    /// mesh.
    pub fn new(cage: &Cage, options: &Options) -> Result<Plan> {
        in_pool(|| {
            let refinement = Refinement::new(cage, options)?;
            let output = OutputMesh::build(&refinement)?;
            Ok(Plan {
                refinement,
                output,
                scratch: Scratch::default(),
                limit: LimitCache::default(),
                face_varying: FaceVaryingCache::default(),
            })
        })
    }

    /// The options the plan was built with.
    pub fn options(&self) -> &Options {
        self.refinement.options()
    }

    /// Number of vertices of the cage, isolated ones included (the length `evaluate` expects).
    pub fn num_input_vertices(&self) -> usize {
        self.refinement.num_input_vertices()
    }

    /// Cage vertices that no face uses; they are dropped from the result.
    pub fn isolated_vertices(&self) -> &[u32] {
        self.refinement.isolated_vertices()
    }

    /// The refined levels `M_0..M_L` (vertex `v` of `M_0` is the `v`-th cage vertex that some
    /// face uses), every table built (the last level's edge and vertex -> corner tables are
    /// added on the first call).
    pub fn levels(&self) -> &[Level] {
        self.refinement.levels()
    }

    /// The curve network of each step `M_j -> M_{j+1}`: which vertices and edges of `M_{j+1}`
    /// lie on boundaries and creases that are still sharp, and which are corners.
    pub fn curve_networks(&self) -> &[CurveNetwork] {
        self.refinement.curve_networks()
    }

    /// Number of output vertices.
    pub fn num_output_vertices(&self) -> usize {
        self.output.num_vertices(&self.refinement)
    }

    /// Number of output faces.
    pub fn num_output_faces(&self) -> usize {
        self.output.num_faces(&self.refinement)
    }

    /// Offsets of each output face's vertices in [`Plan::output_face_vertices`] (faces + 1).
    pub fn output_face_offsets(&self) -> &[u32] {
        self.output.face_offsets(&self.refinement)
    }

    /// Vertex indices of the output faces, face after face, counter-clockwise like the cage.
    pub fn output_face_vertices(&self) -> &[u32] {
        self.output.face_vertices(&self.refinement)
    }

    /// The cage face each output face comes from (for materials, shading, face attributes).
    pub fn output_face_origin(&self) -> &[u32] {
        self.output.face_origin(&self.refinement)
    }

    /// The edges of the output mesh.
    pub fn output_edges(&self) -> &[[u32; 2]] {
        self.output.edges(&self.refinement)
    }

    /// The cage edge (index into [`Plan::cage_edges`]) each output edge lies on, [`Level::NONE`]
    /// for an edge inside a cage face (for edge attributes: creases, sharp edges, seams). The
    /// halves of a cage edge on the drawing mesh; on the dual mesh only the boundary edges
    /// between two boundary points of one cage edge (the others cross the surface's edges).
    /// Built on first use (and kept); a refused allocation is [`crate::Error::OutOfMemory`].
    pub fn output_edge_origin(&self) -> Result<&[u32]> {
        self.output.edge_origin(&self.refinement)
    }

    /// The sharpness each output edge keeps at the last level (OpenSubdiv's convention, 10
    /// infinitely sharp): what one more level of refinement would use, so that a surface
    /// written with it and subdivided again continues this one. Classic Catmull-Clark on the
    /// drawing mesh: its per-level table (uniform or Chaikin creasing); otherwise the cage
    /// edge's sharpness lowered by one per level. 0 inside cage faces; boundary edges 10.
    pub fn output_edge_sharpness(&self) -> Result<Vec<f32>> {
        self.output.edge_sharpness(&self.refinement)
    }

    /// The edges of the cage (of `M_0`) as pairs of cage vertices (the user's numbering, smaller
    /// first), ordered by pair.
    pub fn cage_edges(&self) -> Vec<[u32; 2]> {
        let level = self.refinement.cage_level();
        level
            .edge_verts()
            .iter()
            .map(|&[a, b]| {
                let (a, b) = (
                    self.refinement.cage_vertex(a),
                    self.refinement.cage_vertex(b),
                );
                [a.min(b), a.max(b)]
            })
            .collect()
    }

    /// For each entry of [`Plan::output_face_vertices`], the edge to the next corner of its face.
    pub fn output_corner_edges(&self) -> &[u32] {
        self.output.corner_edges(&self.refinement)
    }

    /// Builds the output mesh's tables that wait for their first use (face offsets, cage faces,
    /// the last level's edges). The accessors below build them too, but panic if memory runs
    /// out there; call this first to get [`crate::Error::OutOfMemory`] instead.
    pub fn complete_output(&self) -> Result<()> {
        in_pool(|| self.output.complete(&self.refinement))
    }

    /// Evaluates per-vertex values of the cage (`channels` interleaved values per cage vertex,
    /// in the user's numbering) and returns the values at the output vertices, interleaved.
    pub fn evaluate<T: Scalar>(&self, values: &[T], channels: usize) -> Result<Vec<T>> {
        check_values(values, channels, self.num_input_vertices())?;
        evaluate::evaluate(
            &self.refinement,
            &self.scratch,
            &self.output,
            values,
            channels,
        )
    }

    /// Evaluates face-varying values (one per corner of the cage, e.g. UVs; `channels`
    /// interleaved per corner) in `mode` and returns one value per corner of the output faces
    /// (in the order of [`Plan::output_face_vertices`]). The corners of one cage vertex with
    /// equal values (every channel) are one face-varying vertex, so a seam is where they differ.
    /// [`FaceVaryingMode::All`] refines the face-varying mesh bilinearly (linear per face); the
    /// other modes subdivide the values with the plan's own scheme on it (built on first use
    /// for each topology and mode, and kept in the plan). `limit`: the values on their limit surface (the masks of
    /// [`Plan::limit_positions`]).
    pub fn evaluate_face_varying<T: Scalar>(
        &self,
        values: &[T],
        channels: usize,
        mode: FaceVaryingMode,
        limit: bool,
    ) -> Result<Vec<T>> {
        self.face_varying_per_corner(values, channels, None, mode, limit)
    }

    /// [`Plan::evaluate_face_varying`] with the values given OpenSubdiv's way: `values`
    /// (`channels` interleaved per value) and one index into them per cage corner (`indices`,
    /// the face-varying index buffer, e.g. OBJ's `vt` indices or USD's primvar indices). The
    /// indices are the face-varying topology: corners of one cage vertex with the same index
    /// share one value, corners with different indices stay apart even where the values are
    /// equal (OpenSubdiv's rule).
    pub fn evaluate_face_varying_indexed<T: Scalar>(
        &self,
        values: &[T],
        channels: usize,
        indices: &[u32],
        mode: FaceVaryingMode,
        limit: bool,
    ) -> Result<Vec<T>> {
        self.face_varying_per_corner(values, channels, Some(indices), mode, limit)
    }

    /// Face-varying values as [`Plan::evaluate_face_varying`] (`indices`: `None`) or
    /// [`Plan::evaluate_face_varying_indexed`] (`Some`) take them, returned in the indexed form
    /// of OpenSubdiv, USD's indexed primvars and OBJ's shared `vt` lines: one value per vertex
    /// of the refined face-varying mesh that the output uses, and the index of each output
    /// corner ([`SharedValues`]; [`SharedValues::per_corner`] gives the per-corner values).
    /// The indices are kept in the plan, so a cached call writes one value per face-varying
    /// vertex, about a quarter of the per-corner values on a quad mesh. Expanded per corner,
    /// the values are those of the per-corner calls, bitwise.
    pub fn evaluate_face_varying_shared<T: Scalar>(
        &self,
        values: &[T],
        channels: usize,
        indices: Option<&[u32]>,
        mode: FaceVaryingMode,
        limit: bool,
    ) -> Result<SharedValues<T>> {
        let (values, topology) = self.face_varying_input(values, channels, indices)?;
        face_varying::evaluate_shared(
            &self.refinement,
            &self.output,
            &self.face_varying,
            &values,
            channels,
            topology,
            mode,
            limit,
        )
    }

    /// [`Plan::evaluate_face_varying`] (`indices`: `None`) and
    /// [`Plan::evaluate_face_varying_indexed`].
    fn face_varying_per_corner<T: Scalar>(
        &self,
        values: &[T],
        channels: usize,
        indices: Option<&[u32]>,
        mode: FaceVaryingMode,
        limit: bool,
    ) -> Result<Vec<T>> {
        let (values, topology) = self.face_varying_input(values, channels, indices)?;
        face_varying::evaluate(
            &self.refinement,
            &self.output,
            &self.face_varying,
            &values,
            channels,
            topology,
            mode,
            limit,
        )
    }

    /// Checks face-varying input (per cage corner, or indexed by `indices`) and gives the
    /// values per cage corner with their face-varying topology.
    fn face_varying_input<'a, T: Scalar>(
        &self,
        values: &'a [T],
        channels: usize,
        indices: Option<&'a [u32]>,
    ) -> Result<(Cow<'a, [T]>, Topology<'a>)> {
        let corners = self.refinement.cage_level().num_corners();
        let Some(indices) = indices else {
            check_values(values, channels, corners)?;
            return Ok((Cow::Borrowed(values), Topology::ByValue));
        };
        if indices.len() != corners {
            return Err(Error::InvalidInput(format!(
                "{} face-varying indices for a cage of {corners} face corners",
                indices.len()
            )));
        }
        check_values(values, channels, values.len() / channels.max(1))?;
        let per_corner = face_varying::per_corner_values(values, channels, indices)?;
        Ok((Cow::Owned(per_corner), Topology::Indexed(indices)))
    }

    /// Frees the working buffers that evaluations and limits keep in the plan for the next ones
    /// (a few arrays of the last level's size); the next call allocates them again. The limit's
    /// stencils stay.
    pub fn release_buffers(&self) {
        self.scratch.clear();
        self.limit.release_buffers();
        self.face_varying.release_buffers();
    }

    /// Limit positions at the output vertices (the drawing mesh's), for any per-vertex data of
    /// the cage (`channels` interleaved values per cage vertex, as [`Plan::evaluate`]). Old
    /// vertices keep their ids, so the first values are the limits at the cage vertices (those
    /// that some face drawn uses, when the cage has holes). Averaging rules: every degree
    /// ([`crate::analysis`]'s eigenvector masks, the curves' B-splines); classic rules:
    /// degree 3 (OpenSubdiv's limit masks).
    pub fn limit_positions<T: Scalar>(&self, values: &[T], channels: usize) -> Result<Vec<T>> {
        check_values(values, channels, self.num_input_vertices())?;
        in_pool(|| {
            let at_level = limit::positions(
                &self.refinement,
                &self.scratch,
                &self.limit,
                values,
                channels,
            )?;
            self.output.vertex_values(at_level, channels)
        })
    }

    /// Limit positions (3 channels) and unit limit normals of the surface of `points` (3 per
    /// cage vertex): one normal per output face corner (in the order of
    /// [`Plan::output_face_vertices`]), the same for every corner of a smooth vertex and one
    /// per side at curve vertices and corners (split normals). Degenerate geometry gives zero
    /// vectors. Averaging rules only.
    pub fn limit_surface<T: Scalar>(&self, points: &[T]) -> Result<(Vec<T>, Vec<T>)> {
        self.limit_surface_with(points, NormalDomain::Corner)
    }

    /// [`Plan::limit_surface`] with the normals per output corner or per output vertex
    /// ([`NormalDomain`]; per vertex a quarter of the bytes on a quad mesh, where writing the
    /// corners' normals is a large part of the call).
    pub fn limit_surface_with<T: Scalar>(
        &self,
        points: &[T],
        normals: NormalDomain,
    ) -> Result<(Vec<T>, Vec<T>)> {
        check_values(points, 3, self.num_input_vertices())?;
        // In the pool, as an evaluation: the limit runs many short parallel loops (its partial
        // levels' passes), each of which, started from outside, is handed to the pool and
        // waited for ([`in_pool`]).
        in_pool(|| {
            let (positions, values) = limit::surface(
                &self.refinement,
                &self.scratch,
                &self.limit,
                points,
                normals,
            )?;
            let values = match normals {
                NormalDomain::Corner => self.output.face_varying(values, 3)?,
                NormalDomain::Vertex => self.output.vertex_values(values, 3)?,
            };
            Ok((self.output.vertex_values(positions, 3)?, values))
        })
    }

    /// Whether some output vertex has different limit normals at its corners: the two sides of
    /// a crease, the sectors of a corner (degree 1: every face its own). `false` means one
    /// normal per vertex ([`NormalDomain::Vertex`]) is every corner's normal, bit for bit, in
    /// a quarter of the bytes on a quad mesh (Blender's point custom normals, USD's `vertex`
    /// interpolation); `true`, that per vertex the splits shade smoothly. Averaging rules only,
    /// as [`Plan::limit_surface`]; the limit's stencils are built on first use.
    pub fn limit_normals_split(&self) -> Result<bool> {
        in_pool(|| limit::normals_split(&self.refinement, &self.limit))
    }

    /// Levels the limit evaluation adds to this plan (built on first use, kept in the plan).
    pub fn limit_extra_levels(&self) -> Result<u32> {
        in_pool(|| limit::extra_levels(&self.refinement, &self.limit))
    }

    /// The refinement under the plan.
    #[cfg(test)]
    pub(crate) fn refinement(&self) -> &Refinement {
        &self.refinement
    }
}
