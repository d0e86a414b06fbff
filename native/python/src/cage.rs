//! `bidegree._native.Cage`: a validated cage topology (faces, creases, corners), and the
//! geometry check of points against it. A cage read from a file keeps the file's
//! [`ObjSource`]: errors about its faces, creases and corners, found by anything run on the
//! cage ([`PyCage::run`]), are restated in the file's lines and indices.

use std::sync::Arc;

use bidegree::io::ObjSource;
use bidegree::{Cage, Scalar};
use numpy::{Element, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::arrays::{contiguous, floats, Floats};
use crate::errors::{detached, guard, invalid, Failure};
use crate::obj::PyObjSource;

/// Registers the cage class in the extension module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyCage>()
}

/// The cage topology (validated on construction): faces, creases and corners.
#[pyclass(frozen, module = "bidegree._native", name = "Cage")]
pub(crate) struct PyCage {
    inner: Cage,
    source: Option<Arc<ObjSource>>,
}

impl PyCage {
    /// Runs core work on this cage with the GIL released and panics caught (as
    /// [`crate::errors::run`]), its errors restated in the terms of the cage's file.
    pub(crate) fn run<T, F>(&self, py: Python<'_>, work: F) -> PyResult<T>
    where
        F: FnOnce(&Cage) -> bidegree::Result<T> + Send,
        T: Send,
    {
        detached(py, || work(&self.inner))
            .map_err(|failure| restate(&self.source, failure, Some(&self.inner)).into_py(py))
    }
}

/// A failure in the terms of the file the cage came from, if it came from one.
fn restate(source: &Option<Arc<ObjSource>>, failure: Failure, cage: Option<&Cage>) -> Failure {
    match (source, failure) {
        (Some(source), Failure::Error(error)) => Failure::Error(source.restate(error, cage)),
        (_, failure) => failure,
    }
}

#[pymethods]
impl PyCage {
    /// Builds and validates a cage. `crease_edges` holds 2 vertex indices per crease,
    /// `crease_sharpness` one value per crease; `corner_*` one entry per corner; `source`, the
    /// lines of the file the arrays were read from (`read_obj`'s `"source"`), in the same order;
    /// `holes`, the faces tagged as holes.
    #[new]
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (num_vertices, face_sizes, face_indices, crease_edges, crease_sharpness, corner_vertices, corner_sharpness, source=None, holes=None))]
    fn new(
        py: Python<'_>,
        num_vertices: usize,
        face_sizes: PyReadonlyArray1<'_, i64>,
        face_indices: PyReadonlyArray1<'_, i64>,
        crease_edges: PyReadonlyArray1<'_, i64>,
        crease_sharpness: PyReadonlyArray1<'_, f32>,
        corner_vertices: PyReadonlyArray1<'_, i64>,
        corner_sharpness: PyReadonlyArray1<'_, f32>,
        source: Option<&Bound<'_, PyObjSource>>,
        holes: Option<PyReadonlyArray1<'_, i64>>,
    ) -> PyResult<Self> {
        let holes = match &holes {
            Some(h) => contiguous(h, "holes")?,
            None => &[],
        };
        let source = source.map(|s| s.get().source());
        let sizes = contiguous(&face_sizes, "face_sizes")?;
        let indices = contiguous(&face_indices, "face_indices")?;
        let crease_edges = contiguous(&crease_edges, "crease edges")?;
        let crease_sharpness = contiguous(&crease_sharpness, "crease sharpness")?;
        let corner_vertices = contiguous(&corner_vertices, "corner vertices")?;
        let corner_sharpness = contiguous(&corner_sharpness, "corner sharpness")?;
        let built = detached(py, || {
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
                .with_corners(&corners)?
                .with_holes(holes)
        });
        match built {
            Ok(inner) => Ok(PyCage { inner, source }),
            Err(failure) => Err(restate(&source, failure, None).into_py(py)),
        }
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
        match floats(points, "points")? {
            Floats::F32(a) => self.validate(py, &a),
            Floats::F64(a) => self.validate(py, &a),
        }
    }
}

impl PyCage {
    fn validate<T: Scalar + Element>(
        &self,
        py: Python<'_>,
        points: &PyReadonlyArray2<'_, T>,
    ) -> PyResult<()> {
        let channels = points.shape()[1];
        let data = contiguous(points, "points")?;
        self.run(py, |cage| bidegree::validate_geometry(cage, data, channels))
    }
}
