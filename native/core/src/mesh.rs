//! The input cage: polygon topology, edge creases, corner vertices and hole faces, and the
//! checks on it that need no refinement (index ranges, face sizes, faces of fewer than three
//! distinct vertices, finite values). Any polygon soup is a cage: non-manifold, inconsistently
//! oriented, degenerate or zero-area faces are subdivided as OpenSubdiv does.

use crate::error::{Error, Result};
use crate::memory;
use crate::scalar::Scalar;

/// Sharpness at or above which a crease or corner is infinitely sharp (as in OpenSubdiv); the
/// cage stores larger values, and infinity, as this.
pub const INFINITELY_SHARP: f32 = 10.0;

/// An edge crease between cage vertices `a` and `b`. Sharpness 0 is smooth; at or above
/// [`INFINITELY_SHARP`] (or infinite) the crease is sharp at every level, and is stored as
/// [`INFINITELY_SHARP`] (the one convention of the core, OpenSubdiv's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crease {
    /// First vertex of the edge.
    pub a: u32,
    /// Second vertex of the edge.
    pub b: u32,
    /// Sharpness: the number of levels the crease stays sharp (fractional part blends).
    pub sharpness: f32,
}

/// A corner vertex: kept at its input position while its sharpness lasts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Corner {
    /// The cage vertex.
    pub vertex: u32,
    /// Sharpness, as for creases.
    pub sharpness: f32,
}

/// The topology of an input cage: polygons of at least three distinct vertices (a face may
/// repeat a vertex), creases, corners and holes. Points are not part of the cage, so one cage
/// serves any number of poses.
#[derive(Debug, Clone, PartialEq)]
pub struct Cage {
    num_vertices: usize,
    face_offsets: Vec<u32>,
    face_vertices: Vec<u32>,
    creases: Vec<Crease>,
    corners: Vec<Corner>,
    holes: Vec<u32>,
}

/// True when face offsets (length faces + 1, from 0) are those of quads only: face `f` at
/// `4 f`. The one test of a cage ([`Cage::all_quads`]) and of a level stored with offsets.
pub(crate) fn offsets_of_quads(face_offsets: &[u32]) -> bool {
    (face_offsets.iter().enumerate()).all(|(f, &offset)| offset as usize == 4 * f)
}

fn check_index(what: impl Fn() -> String, index: i64, num_vertices: usize) -> Result<u32> {
    if index < 0 || index as u64 >= num_vertices as u64 {
        return Err(Error::IndexOutOfRange {
            what: what(),
            index,
            num_vertices,
        });
    }
    Ok(index as u32)
}

fn check_sharpness(what: &str, i: usize, s: f32) -> Result<()> {
    if s.is_nan() || s < 0.0 {
        return Err(Error::InvalidInput(format!(
            "{what} {i} has sharpness {s}; it must be >= 0"
        )));
    }
    Ok(())
}

impl Cage {
    /// Builds a cage from face sizes and the flat list of their vertex indices, checking that
    /// every face has at least three distinct vertices and every index is in range. A face may
    /// use a vertex more than once (OpenSubdiv keeps every occurrence: a repeated neighbour is
    /// a degenerate edge); fewer than three distinct vertices is [`Error::RepeatedVertex`].
    pub fn from_indices(
        num_vertices: usize,
        face_sizes: &[i64],
        face_vertices: &[i64],
    ) -> Result<Cage> {
        if face_sizes.is_empty() {
            return Err(Error::EmptyMesh("the mesh has no faces".into()));
        }
        if num_vertices == 0 {
            return Err(Error::EmptyMesh("the mesh has no vertices".into()));
        }
        if num_vertices >= u32::MAX as usize {
            return Err(Error::InvalidInput(format!(
                "{num_vertices} vertices is more than supported"
            )));
        }
        // The tables take about as much as the input; `num_vertices` is the caller's word, so
        // they are allocated fallibly.
        let mut face_offsets = memory::with_capacity(face_sizes.len() + 1)?;
        face_offsets.push(0u32);
        let mut total: u64 = 0;
        for (face, &size) in face_sizes.iter().enumerate() {
            if size < 3 {
                return Err(Error::FaceTooSmall { face, size });
            }
            total += size as u64;
            if total > face_vertices.len() as u64 {
                return Err(Error::InvalidInput(format!(
                    "face sizes add up to more than the {} face vertex indices given",
                    face_vertices.len()
                )));
            }
            face_offsets.push(total as u32);
        }
        if total != face_vertices.len() as u64 {
            return Err(Error::InvalidInput(format!(
                "face sizes add up to {total}, but {} face vertex indices were given",
                face_vertices.len()
            )));
        }
        let mut verts = memory::with_capacity(face_vertices.len())?;
        // The last face each vertex was seen in (linear in the corners, whatever the face sizes).
        let mut seen_in = memory::filled(num_vertices, u32::MAX)?;
        for face in 0..face_sizes.len() {
            let range = face_offsets[face] as usize..face_offsets[face + 1] as usize;
            let (mut distinct, mut repeated) = (0, None);
            for &index in &face_vertices[range] {
                let v = check_index(|| format!("face {face}"), index, num_vertices)?;
                if seen_in[v as usize] == face as u32 {
                    repeated.get_or_insert(v);
                } else {
                    distinct += 1;
                }
                seen_in[v as usize] = face as u32;
                verts.push(v);
            }
            if let (true, Some(v)) = (distinct < 3, repeated) {
                return Err(Error::RepeatedVertex {
                    face,
                    vertex: v as usize,
                });
            }
        }
        Ok(Cage {
            num_vertices,
            face_offsets,
            face_vertices: verts,
            creases: Vec::new(),
            corners: Vec::new(),
            holes: Vec::new(),
        })
    }

    /// Adds edge creases `(a, b, sharpness)`. Whether `a-b` is an edge is checked by the plan.
    pub fn with_creases(mut self, creases: &[(i64, i64, f32)]) -> Result<Cage> {
        memory::reserve(&mut self.creases, creases.len())?;
        for (i, &(a, b, s)) in creases.iter().enumerate() {
            let a = check_index(|| format!("crease {i}"), a, self.num_vertices)?;
            let b = check_index(|| format!("crease {i}"), b, self.num_vertices)?;
            check_sharpness("crease", i, s)?;
            if a == b {
                return Err(Error::CreaseNotAnEdge {
                    crease: i,
                    a: a as usize,
                    b: b as usize,
                });
            }
            self.creases.push(Crease {
                a,
                b,
                sharpness: s.min(INFINITELY_SHARP),
            });
        }
        Ok(self)
    }

    /// Adds corner vertices `(vertex, sharpness)`.
    pub fn with_corners(mut self, corners: &[(i64, f32)]) -> Result<Cage> {
        memory::reserve(&mut self.corners, corners.len())?;
        for (i, &(v, s)) in corners.iter().enumerate() {
            let vertex = check_index(|| format!("corner {i}"), v, self.num_vertices)?;
            check_sharpness("corner", i, s)?;
            self.corners.push(Corner {
                vertex,
                sharpness: s.min(INFINITELY_SHARP),
            });
        }
        Ok(self)
    }

    /// Tags faces as holes (OpenSubdiv's `holeIndices`, OBJ `t hole`): they are refined and
    /// shape their neighbours, but are left out of the output.
    pub fn with_holes(mut self, holes: &[i64]) -> Result<Cage> {
        let faces = self.num_faces();
        memory::reserve(&mut self.holes, holes.len())?;
        for (i, &f) in holes.iter().enumerate() {
            if f < 0 || f as u64 >= faces as u64 {
                return Err(Error::InvalidInput(format!(
                    "hole {i} is face {f}, but the mesh has {faces} faces"
                )));
            }
            self.holes.push(f as u32);
        }
        self.holes.sort_unstable();
        self.holes.dedup();
        Ok(self)
    }

    /// The hole faces, sorted.
    pub fn holes(&self) -> &[u32] {
        &self.holes
    }

    /// Number of vertices (including any that no face uses).
    pub fn num_vertices(&self) -> usize {
        self.num_vertices
    }

    /// Number of faces.
    pub fn num_faces(&self) -> usize {
        self.face_offsets.len() - 1
    }

    /// Offsets of each face's vertices in [`Cage::face_vertices`] (length faces + 1).
    pub fn face_offsets(&self) -> &[u32] {
        &self.face_offsets
    }

    /// True when every face is a quad (one pass over the offsets).
    pub(crate) fn all_quads(&self) -> bool {
        offsets_of_quads(&self.face_offsets)
    }

    /// Vertex indices of all faces, face after face.
    pub fn face_vertices(&self) -> &[u32] {
        &self.face_vertices
    }

    /// Edge creases.
    pub fn creases(&self) -> &[Crease] {
        &self.creases
    }

    /// Corner vertices.
    pub fn corners(&self) -> &[Corner] {
        &self.corners
    }
}

/// Checks the points of a cage: the right length and finite values. Zero-area and collinear
/// faces are fine (degeneracy is a property of positions; no rule divides by an area).
pub fn validate_geometry<T: Scalar>(cage: &Cage, points: &[T], channels: usize) -> Result<()> {
    check_values(points, channels, cage.num_vertices())
}

/// Checks that `values` holds `channels` finite values for each of `count` items.
pub(crate) fn check_values<T: Scalar>(values: &[T], channels: usize, count: usize) -> Result<()> {
    if channels == 0 {
        return Err(Error::InvalidInput(
            "values need at least one channel".into(),
        ));
    }
    if values.len() != count * channels {
        return Err(Error::InvalidInput(format!(
            "expected {count} items of {channels} channels ({} values), got {} values",
            count * channels,
            values.len()
        )));
    }
    if let Some(i) = values.iter().position(|x| !x.is_finite()) {
        return Err(Error::NonFinite {
            vertex: i / channels,
        });
    }
    Ok(())
}
