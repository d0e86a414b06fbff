//! OBJ reading and writing.
//!
//! This module owns the Wavefront OBJ format and nothing else:
//! - [`read_obj`] / [`parse_obj`] ([`read`]) turn OBJ text into an [`ObjMesh`]: positions
//!   (`v`), texture coordinates (`vt`, face-varying), polygons (`f` in the forms `v`, `v/vt`,
//!   `v//vn`, `v/vt/vn`, with 1-based or negative (relative) indices), and the tag lines of
//!   OpenSubdiv's test shapes (`t crease`, `t corner`, `t interpolateboundary`,
//!   `t creasemethod`). Normals, groups, objects, smoothing groups, materials and comments are
//!   skipped; unknown statements, free-form geometry and other tags are skipped with one
//!   warning per kind ([`ObjMesh::warnings`]). A file is streamed under a byte limit.
//! - [`write_obj`] ([`write`](mod@write)) writes a polygon mesh (with optional face-varying UVs and
//!   normals), formatting in parallel into large buffers, atomically.
//!
//! Malformed input is refused with [`Error::Io`](crate::Error::Io) carrying
//! `"path:LINE: message"`. The parser checks the file itself (syntax, finite numbers, indices
//! that refer to nothing, tag arguments); the topology (repeated vertices, manifoldness,
//! orientation, creases that are no edges) is checked when a [`crate::Cage`] is built from the
//! result, and [`ObjSource::restate`] tells those errors in the file's terms.

pub mod read;
pub mod write;

pub use read::{parse_obj, read_obj, ObjSource, ReadOptions, DEFAULT_MAX_INPUT_BYTES};
pub use write::{write_obj, ObjFloat, ObjOutput, Uvs};

use crate::error::Result;
use crate::{Boundary, Creasing};

/// Asked between chunks of a long read or write whether to stop: an `Err` stops the work
/// (nothing is written) and is returned. The binding checks for signals (Ctrl-C, SIGTERM) here.
pub type Interrupt<'a> = &'a dyn Fn() -> Result<()>;

/// An [`Interrupt`] that never stops.
pub const UNINTERRUPTED: Interrupt<'static> = &|| Ok(());

/// A polygon mesh as read from an OBJ file. Indices are 0-based.
#[derive(Debug, Clone, Default)]
pub struct ObjMesh {
    /// Positions, 3 per vertex, interleaved (`x0 y0 z0 x1 ...`).
    pub points: Vec<f64>,
    /// Number of corners of each face.
    pub face_sizes: Vec<i64>,
    /// Vertex index of each face corner, faces one after the other.
    pub face_vertices: Vec<i64>,
    /// Texture coordinates, 2 per `vt` line (`u0 v0 u1 ...`).
    pub uvs: Vec<f64>,
    /// Texture coordinate index of each face corner (parallel to `face_vertices`); `Some` only
    /// when every face corner of the file names one.
    pub face_uvs: Option<Vec<i64>>,
    /// Crease edges `(a, b, sharpness)` from `t crease` tags.
    pub creases: Vec<(i64, i64, f32)>,
    /// Corner vertices `(vertex, sharpness)` from `t corner` tags.
    pub corners: Vec<(i64, f32)>,
    /// Faces (0-based) tagged by `t hole` tags.
    pub holes: Vec<i64>,
    /// Boundary rule from a `t interpolateboundary` tag, if the file has one.
    pub boundary: Option<Boundary>,
    /// Creasing method from a `t creasemethod` tag (`normal` is uniform), if the file has one.
    pub creasing: Option<Creasing>,
    /// One message per kind of thing the reader skipped (`"path:LINE: ..."`, the line of the
    /// first one, with a count).
    pub warnings: Vec<String>,
    /// Where the faces, creases and corners are in the file.
    pub source: ObjSource,
}

impl ObjMesh {
    /// Number of vertices (`v` lines).
    pub fn num_vertices(&self) -> usize {
        self.points.len() / 3
    }

    /// Number of faces (`f` lines).
    pub fn num_faces(&self) -> usize {
        self.face_sizes.len()
    }
}

#[cfg(test)]
mod tests;
