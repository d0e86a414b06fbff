//! `bidegree._native.subdivide_adaptive`: the binding of the core's adaptive subdivision
//! (`bidegree::adaptive`), with the same conventions as the rest of the module (GIL released,
//! panics caught, core errors as their Python classes).

use bidegree::{subdivide_adaptive as core_adaptive, AdaptiveMesh, AdaptiveOptions, Scalar};
use numpy::{Element, PyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{array2, check_output, contiguous, floats, to_i32, Floats};
use crate::cage::PyCage;
use crate::errors::{invalid, to_py_err};
use crate::options::{degree, levels, memory_budget, parse_boundary};

/// Registers the adaptive functions in the extension module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(subdivide_adaptive, m)?)
}

/// Options from Python arguments.
fn adaptive_options(
    degree: i64,
    max_level: i64,
    tolerance: f64,
    boundary: &str,
    budget: Option<u64>,
    measure_leaves: bool,
) -> bidegree::Result<AdaptiveOptions> {
    Ok(AdaptiveOptions {
        degree: self::degree(degree)?,
        max_level: levels(max_level)?,
        tolerance,
        boundary: parse_boundary(boundary)?,
        memory_budget: memory_budget(budget),
        measure_leaves,
    })
}

/// Adaptive subdivision of a cage with 3-D points: a dict with `points` (N, 3) of the points'
/// dtype, `triangles` int32 (T, 3), `face_origin` and `triangle_level` int32 (T,),
/// `vertex_level` int32 (N,), `vertex_id` int64 (N,), `leaves_per_level` int64 (max_level + 1,)
/// and `max_error` (a float with `measure_leaves`, else None).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (cage, points, degree, max_level, tolerance, boundary, memory_budget=None, measure_leaves=false))]
fn subdivide_adaptive<'py>(
    py: Python<'py>,
    cage: &Bound<'py, PyCage>,
    points: &Bound<'py, PyAny>,
    degree: i64,
    max_level: i64,
    tolerance: f64,
    boundary: &str,
    memory_budget: Option<u64>,
    measure_leaves: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let cage = cage.get();
    let options = adaptive_options(
        degree,
        max_level,
        tolerance,
        boundary,
        memory_budget,
        measure_leaves,
    )
    .map_err(|e| to_py_err(py, e))?;
    match floats(points, "points")? {
        Floats::F32(a) => adaptive(py, cage, &a, options),
        Floats::F64(a) => adaptive(py, cage, &a, options),
    }
}

fn adaptive<'py, T: Scalar + Element>(
    py: Python<'py>,
    cage: &PyCage,
    points: &PyReadonlyArray2<'_, T>,
    options: AdaptiveOptions,
) -> PyResult<Bound<'py, PyDict>> {
    let channels = points.shape()[1];
    let data = contiguous(points, "points")?;
    let (mesh, triangles, face_origin, triangle_level, vertex_level) = cage.run(py, |cage| {
        if channels != 3 {
            return Err(invalid(format!(
                "adaptive subdivision needs 3-D points, not {channels} channels"
            )));
        }
        let mesh: AdaptiveMesh<T> = core_adaptive(cage, data, &options)?;
        check_output(&mesh.points, 3, data)?;
        let triangles = to_i32(mesh.triangles.as_flattened())?;
        let face_origin = to_i32(&mesh.face_origin)?;
        let triangle_level = to_i32(&mesh.triangle_level)?;
        let vertex_level = to_i32(&mesh.vertex_level)?;
        Ok((mesh, triangles, face_origin, triangle_level, vertex_level))
    })?;
    let out = PyDict::new(py);
    out.set_item("points", array2(py, mesh.points, 3)?)?;
    out.set_item("triangles", array2(py, triangles, 3)?)?;
    out.set_item("face_origin", PyArray1::from_vec(py, face_origin))?;
    out.set_item("triangle_level", PyArray1::from_vec(py, triangle_level))?;
    out.set_item("vertex_level", PyArray1::from_vec(py, vertex_level))?;
    let ids = bidegree::memory::collect(mesh.vertex_id.iter().map(|&u| u as i64))
        .map_err(|e| to_py_err(py, e))?;
    out.set_item("vertex_id", PyArray1::from_vec(py, ids))?;
    let leaves: Vec<i64> = mesh.leaves_per_level.iter().map(|&n| n as i64).collect();
    out.set_item("leaves_per_level", PyArray1::from_vec(py, leaves))?;
    out.set_item("max_error", mesh.max_error)?;
    Ok(out)
}
