//! The input cage: polygon topology, edge creases and corner vertices, and the checks on it
//! that need no refinement (index ranges, face sizes, repeated vertices, geometry).

use crate::error::{Error, Result};
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

/// The topology of an input cage: polygons of any size >= 3, creases and corners.
/// Points are not part of the cage, so one cage serves any number of poses.
#[derive(Debug, Clone, PartialEq)]
pub struct Cage {
    num_vertices: usize,
    face_offsets: Vec<u32>,
    face_vertices: Vec<u32>,
    creases: Vec<Crease>,
    corners: Vec<Corner>,
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
    /// every face has at least three distinct vertices and every index is in range.
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
        let mut face_offsets = Vec::with_capacity(face_sizes.len() + 1);
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
        let mut verts = Vec::with_capacity(face_vertices.len());
        // The last face each vertex was seen in (linear in the corners, whatever the face sizes).
        let mut seen_in = vec![u32::MAX; num_vertices];
        for face in 0..face_sizes.len() {
            let range = face_offsets[face] as usize..face_offsets[face + 1] as usize;
            for &index in &face_vertices[range] {
                let v = check_index(|| format!("face {face}"), index, num_vertices)?;
                if seen_in[v as usize] == face as u32 {
                    return Err(Error::RepeatedVertex {
                        face,
                        vertex: v as usize,
                    });
                }
                seen_in[v as usize] = face as u32;
                verts.push(v);
            }
        }
        Ok(Cage {
            num_vertices,
            face_offsets,
            face_vertices: verts,
            creases: Vec::new(),
            corners: Vec::new(),
        })
    }

    /// Adds edge creases `(a, b, sharpness)`. Whether `a-b` is an edge is checked by the plan.
    pub fn with_creases(mut self, creases: &[(i64, i64, f32)]) -> Result<Cage> {
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

/// Checks the points of a cage: the right length, finite values, and no face of zero area
/// (measured by the norm of its vector area against the squared size of the cage; only the
/// first three channels are taken as positions).
pub fn validate_geometry<T: Scalar>(cage: &Cage, points: &[T], channels: usize) -> Result<()> {
    check_values(points, channels, cage.num_vertices())?;
    if channels < 3 {
        return Ok(());
    }
    let p = |v: u32| -> [f64; 3] {
        let i = v as usize * channels;
        [
            points[i].to_f64(),
            points[i + 1].to_f64(),
            points[i + 2].to_f64(),
        ]
    };
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for &v in cage.face_vertices() {
        let q = p(v);
        for k in 0..3 {
            lo[k] = lo[k].min(q[k]);
            hi[k] = hi[k].max(q[k]);
        }
    }
    let diag2: f64 = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum();
    // Relative to f32 resolution of the cage size: a face this small vanishes in single precision.
    let tolerance = diag2 * 1e-14;
    let offsets = cage.face_offsets();
    let verts = cage.face_vertices();
    for face in 0..cage.num_faces() {
        let fv = &verts[offsets[face] as usize..offsets[face + 1] as usize];
        let o = p(fv[0]);
        let mut area = [0.0f64; 3];
        for w in fv[1..].windows(2) {
            let (a, b) = (p(w[0]), p(w[1]));
            let u = [a[0] - o[0], a[1] - o[1], a[2] - o[2]];
            let v = [b[0] - o[0], b[1] - o[1], b[2] - o[2]];
            area[0] += u[1] * v[2] - u[2] * v[1];
            area[1] += u[2] * v[0] - u[0] * v[2];
            area[2] += u[0] * v[1] - u[1] * v[0];
        }
        let norm = (area[0] * area[0] + area[1] * area[1] + area[2] * area[2]).sqrt() * 0.5;
        if norm.is_nan() || norm <= tolerance {
            return Err(Error::DegenerateFace { face });
        }
    }
    Ok(())
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
