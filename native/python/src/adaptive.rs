//! `bidegree._native.subdivide_adaptive`: the binding of the core's adaptive subdivision
//! (`bidegree::adaptive`), with the same conventions as the rest of the module (GIL released,
//! panics caught, core errors as their Python classes).

use bidegree::{
    subdivide_adaptive_with_data as core_adaptive, AdaptiveData, AdaptiveMesh, AdaptiveOptions,
    FaceVaryingMode, Scalar,
};
use numpy::{
    Element, PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::arrays::{array2, check_output, contiguous, floats, to_i32, Floats};
use crate::cage::PyCage;
use crate::errors::{invalid, to_py_err};
use crate::options::{degree, levels, memory_budget, parse_boundary, parse_face_varying_mode};

/// A face-varying set from Python: values (cage corners, C), its mode, and its topology
/// (uint32 per cage corner) or None (welded by value).
type FaceVaryingSet<'py> = (
    Bound<'py, PyAny>,
    FaceVaryingMode,
    Option<PyReadonlyArray1<'py, u32>>,
);

/// A face-varying set as Python gives it: values, mode name, indices or None.
type GivenSet<'py> = (
    Bound<'py, PyAny>,
    String,
    Option<PyReadonlyArray1<'py, u32>>,
);

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
/// `vertex_level` int32 (N,), `vertex_id` int64 (N,), `leaves_per_level` int64 (max_level + 1,),
/// `max_error` (a float with `measure_leaves`, else None), `edge_origin` (int32 (3 T,), -1
/// inside cage faces), `edge_level` (int32 (3 T,)), `edge_sharpness` (float32 (3 T,)),
/// `cage_edges` (int32 (E0, 2)), `vertex_values` ((N, C) for
/// `vertex_values` (cage vertices, C) in the points' dtype, else None) and `face_varying` (a
/// list: for each `(values (cage corners, C), mode, indices)` of `face_varying`, (3 T, C) at
/// the triangle corners; `indices`, uint32 per cage corner or None, is the set's face-varying
/// topology).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (cage, points, degree, max_level, tolerance, boundary, memory_budget=None, measure_leaves=false, vertex_values=None, face_varying=None))]
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
    vertex_values: Option<&Bound<'py, PyAny>>,
    face_varying: Option<Vec<GivenSet<'py>>>,
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
    let mut sets = Vec::new();
    for (values, mode, indices) in face_varying.unwrap_or_default() {
        sets.push((
            values,
            parse_face_varying_mode(&mode).map_err(|e| to_py_err(py, e))?,
            indices,
        ));
    }
    match floats(points, "points")? {
        Floats::F32(a) => adaptive(py, cage, &a, options, vertex_values, &sets),
        Floats::F64(a) => adaptive(py, cage, &a, options, vertex_values, &sets),
    }
}

/// A 2-D array of the points' dtype `T` (the Python layer converts).
fn same_dtype<'py, T: Element>(
    values: &Bound<'py, PyAny>,
    what: &str,
) -> PyResult<PyReadonlyArray2<'py, T>> {
    let py = values.py();
    let array = values.cast::<PyArray2<T>>().map_err(|_| {
        to_py_err(
            py,
            invalid(format!(
                "{what} must be a 2-D numpy array of the points' dtype"
            )),
        )
    })?;
    array
        .try_readonly()
        .map_err(|_| to_py_err(py, invalid(format!("{what} is being written elsewhere"))))
}

fn adaptive<'py, T: Scalar + Element>(
    py: Python<'py>,
    cage: &PyCage,
    points: &PyReadonlyArray2<'_, T>,
    options: AdaptiveOptions,
    vertex_values: Option<&Bound<'py, PyAny>>,
    face_varying: &[FaceVaryingSet<'py>],
) -> PyResult<Bound<'py, PyDict>> {
    let channels = points.shape()[1];
    let data = contiguous(points, "points")?;
    let vertex_values = vertex_values
        .map(|v| same_dtype::<T>(v, "vertex_values"))
        .transpose()?;
    let mut extra = AdaptiveData::default();
    let sets = (face_varying.iter())
        .map(|(v, mode, _)| Ok((same_dtype::<T>(v, "face_varying values")?, *mode)))
        .collect::<PyResult<Vec<_>>>()?;
    for (_, _, indices) in face_varying {
        let indices = (indices.as_ref())
            .map(|a| a.as_slice())
            .transpose()
            .map_err(|_| to_py_err(py, invalid("indices must be a contiguous uint32 array")))?;
        extra.face_varying_indices.push(indices);
    }
    let mut vertex_channels = 0;
    if let Some(values) = &vertex_values {
        vertex_channels = values.shape()[1];
        extra.vertex_values = Some((contiguous(values, "vertex_values")?, vertex_channels));
    }
    let mut set_channels = Vec::new();
    for (values, mode) in &sets {
        let width = values.shape()[1];
        set_channels.push(width);
        extra
            .face_varying
            .push((contiguous(values, "face_varying values")?, width, *mode));
    }
    let (mesh, triangles, face_origin, triangle_level, vertex_level) = cage.run(py, |cage| {
        if channels != 3 {
            return Err(invalid(format!(
                "adaptive subdivision needs 3-D points, not {channels} channels"
            )));
        }
        if vertex_channels == 0 && extra.vertex_values.is_some() || set_channels.contains(&0) {
            return Err(invalid("values need at least one channel"));
        }
        let mesh: AdaptiveMesh<T> = core_adaptive(cage, data, &options, &extra)?;
        check_output(&mesh.points, 3, data)?;
        if let Some((values, width)) = extra.vertex_values {
            check_output(&mesh.vertex_values, width, values)?;
        }
        for (out, &(values, width, _)) in mesh.face_varying.iter().zip(&extra.face_varying) {
            check_output(out, width, values)?;
        }
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
    let AdaptiveMesh {
        vertex_values,
        face_varying,
        edge_origin,
        edge_level,
        edge_sharpness,
        cage_edges,
        cage_vertex,
        vertex_sharpness,
        ..
    } = mesh;
    let edge_origin = none_as_minus_one(&edge_origin).map_err(|e| to_py_err(py, e))?;
    out.set_item("edge_origin", PyArray1::from_vec(py, edge_origin))?;
    let cage_vertex = none_as_minus_one(&cage_vertex).map_err(|e| to_py_err(py, e))?;
    out.set_item("cage_vertex", PyArray1::from_vec(py, cage_vertex))?;
    out.set_item("vertex_sharpness", PyArray1::from_vec(py, vertex_sharpness))?;
    let edge_level = to_i32(&edge_level).map_err(|e| to_py_err(py, e))?;
    out.set_item("edge_level", PyArray1::from_vec(py, edge_level))?;
    out.set_item("edge_sharpness", PyArray1::from_vec(py, edge_sharpness))?;
    let cage_edges = to_i32(cage_edges.as_flattened()).map_err(|e| to_py_err(py, e))?;
    out.set_item("cage_edges", array2(py, cage_edges, 2)?)?;
    if extra.vertex_values.is_some() {
        out.set_item("vertex_values", array2(py, vertex_values, vertex_channels)?)?;
    } else {
        out.set_item("vertex_values", py.None())?;
    }
    let sets = PyList::empty(py);
    for (values, width) in face_varying.into_iter().zip(set_channels) {
        sets.append(array2(py, values, width)?)?;
    }
    out.set_item("face_varying", sets)?;
    Ok(out)
}

/// Indices as int32, [`bidegree::Level::NONE`] as -1.
fn none_as_minus_one(values: &[u32]) -> bidegree::Result<Vec<i32>> {
    (values.iter())
        .map(|&e| {
            if e == bidegree::Level::NONE {
                Ok(-1)
            } else {
                to_i32(&[e]).map(|x| x[0])
            }
        })
        .collect()
}
