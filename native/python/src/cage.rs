//! `bidegree._native.Cage`: a validated cage topology (faces, creases, corners), and the
//! geometry check of points against it.

use bidegree::{Cage, Scalar};
use numpy::{Element, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::arrays::{contiguous, floats, Floats};
use crate::errors::{guard, invalid, run};

/// Registers the cage class in the extension module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyCage>()
}

/// The cage topology (validated on construction): faces, creases and corners.
#[pyclass(frozen, module = "bidegree._native", name = "Cage")]
pub(crate) struct PyCage {
    pub(crate) inner: Cage,
}

#[pymethods]
impl PyCage {
    /// Builds and validates a cage. `crease_edges` holds 2 vertex indices per crease,
    /// `crease_sharpness` one value per crease; `corner_*` one entry per corner.
    #[new]
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (num_vertices, face_sizes, face_indices, crease_edges, crease_sharpness, corner_vertices, corner_sharpness))]
    fn new(
        py: Python<'_>,
        num_vertices: usize,
        face_sizes: PyReadonlyArray1<'_, i64>,
        face_indices: PyReadonlyArray1<'_, i64>,
        crease_edges: PyReadonlyArray1<'_, i64>,
        crease_sharpness: PyReadonlyArray1<'_, f32>,
        corner_vertices: PyReadonlyArray1<'_, i64>,
        corner_sharpness: PyReadonlyArray1<'_, f32>,
    ) -> PyResult<Self> {
        let sizes = contiguous(&face_sizes, "face_sizes")?;
        let indices = contiguous(&face_indices, "face_indices")?;
        let crease_edges = contiguous(&crease_edges, "crease edges")?;
        let crease_sharpness = contiguous(&crease_sharpness, "crease sharpness")?;
        let corner_vertices = contiguous(&corner_vertices, "corner vertices")?;
        let corner_sharpness = contiguous(&corner_sharpness, "corner sharpness")?;
        let inner = run(py, || {
            if crease_edges.len() != 2 * crease_sharpness.len() {
                return Err(invalid(format!(
                    "{} crease vertex indices for {} crease sharpness values (need 2 per crease)",
                    crease_edges.len(),
                    crease_sharpness.len()
                )));
            }
            if corner_vertices.len() != corner_sharpness.len() {
                return Err(invalid(format!(
                    "{} corner vertices but {} corner sharpness values",
                    corner_vertices.len(),
                    corner_sharpness.len()
                )));
            }
            let creases: Vec<(i64, i64, f32)> = crease_edges
                .chunks_exact(2)
                .zip(crease_sharpness)
                .map(|(edge, &s)| (edge[0], edge[1], s))
                .collect();
            let corners: Vec<(i64, f32)> = corner_vertices
                .iter()
                .copied()
                .zip(corner_sharpness.iter().copied())
                .collect();
            Cage::from_indices(num_vertices, sizes, indices)?
                .with_creases(&creases)?
                .with_corners(&corners)
        })?;
        Ok(PyCage { inner })
    }

    /// Number of cage vertices (including isolated ones).
    #[getter]
    fn num_vertices(&self, py: Python<'_>) -> PyResult<usize> {
        guard(py, || self.inner.num_vertices())
    }

    /// Number of cage faces.
    #[getter]
    fn num_faces(&self, py: Python<'_>) -> PyResult<usize> {
        guard(py, || self.inner.num_faces())
    }

    /// Checks points for subdivision: finite values, no zero-area face.
    fn validate_geometry(&self, py: Python<'_>, points: &Bound<'_, PyAny>) -> PyResult<()> {
        let cage = &self.inner;
        match floats(points, "points")? {
            Floats::F32(a) => validate(py, cage, &a),
            Floats::F64(a) => validate(py, cage, &a),
        }
    }
}

fn validate<T: Scalar + Element>(
    py: Python<'_>,
    cage: &Cage,
    points: &PyReadonlyArray2<'_, T>,
) -> PyResult<()> {
    let channels = points.shape()[1];
    let data = contiguous(points, "points")?;
    run(py, || {
        bidegree::mesh::validate_geometry(cage, data, channels)
    })
}
