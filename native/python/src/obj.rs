//! `bidegree._native.read_obj` / `write_obj`: the core's OBJ reader and writer (`bidegree::io`)
//! with numpy arrays, interruptible by Python's signal handlers (Ctrl-C, the CLI's SIGTERM).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use bidegree::io::{self, ObjFloat, ObjMesh, ObjOutput, ObjSource, ReadOptions, Uvs};
use numpy::{Element, PyArray1, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{array2, contiguous, floats, Floats};
use crate::errors::{invalid, run_interruptible, to_py_err};
use crate::options::{boundary_name, creasing_name, memory_budget};

/// Registers the OBJ functions in the extension module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("DEFAULT_MAX_INPUT_BYTES", io::DEFAULT_MAX_INPUT_BYTES)?;
    m.add_class::<PyObjSource>()?;
    m.add_function(wrap_pyfunction!(read_obj, m)?)?;
    m.add_function(wrap_pyfunction!(write_obj, m)?)
}

/// Where the faces, creases and corners of a mesh read by `read_obj` are in its file; handed
/// to `Cage(..., source=...)` so that errors about them name the file's lines.
#[pyclass(frozen, module = "bidegree._native", name = "ObjSource")]
pub(crate) struct PyObjSource {
    inner: Arc<ObjSource>,
}

impl PyObjSource {
    /// The shared source.
    pub(crate) fn source(&self) -> Arc<ObjSource> {
        Arc::clone(&self.inner)
    }
}

#[pymethods]
impl PyObjSource {
    /// The file's name.
    #[getter]
    fn name(&self) -> &str {
        &self.inner.name
    }

    /// Line of each face (1-based).
    fn face_lines<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        PyArray1::from_iter(py, self.inner.face_lines.iter().map(|&l| l as u64))
    }
}

/// Reads an OBJ file (streamed; at most `max_bytes` of input, default 2 GiB, and at most
/// `memory_budget` bytes for the mesh, default 4 GiB) into a dict of numpy arrays: `points`
/// (V,3) float64, `face_sizes` and `face_indices` int64, `uvs` (T,2) float64, `face_uvs` int64
/// or None, `crease_edges` (K,2) int64, `crease_sharpness` float32, `corner_vertices` int64,
/// `corner_sharpness` float32, `holes` int64, `boundary` (`"edge-only"`, `"edge-and-corner"`, `"none"` or None when the
/// file has no tag), `creasing` (`"uniform"`, `"chaikin"` or None), `warnings` (one line per
/// kind of statement or tag skipped) and `source` (an `ObjSource`).
#[pyfunction]
#[pyo3(signature = (path, max_bytes=None, memory_budget=None))]
fn read_obj<'py>(
    py: Python<'py>,
    path: PathBuf,
    max_bytes: Option<u64>,
    memory_budget: Option<u64>,
) -> PyResult<Bound<'py, PyDict>> {
    let options = ReadOptions {
        max_bytes: max_bytes.unwrap_or(io::DEFAULT_MAX_INPUT_BYTES),
        memory_budget: self::memory_budget(memory_budget),
    };
    let mesh: ObjMesh =
        run_interruptible(py, |interrupt| io::read_obj(&path, &options, interrupt))?;
    let dict = PyDict::new(py);
    dict.set_item("points", array2(py, mesh.points, 3)?)?;
    dict.set_item("face_sizes", PyArray1::from_vec(py, mesh.face_sizes))?;
    dict.set_item("face_indices", PyArray1::from_vec(py, mesh.face_vertices))?;
    dict.set_item("uvs", array2(py, mesh.uvs, 2)?)?;
    dict.set_item("face_uvs", mesh.face_uvs.map(|f| PyArray1::from_vec(py, f)))?;
    let (mut edges, mut sharpness) = (Vec::new(), Vec::new());
    for (a, b, s) in mesh.creases {
        edges.extend([a, b]);
        sharpness.push(s);
    }
    dict.set_item("crease_edges", array2(py, edges, 2)?)?;
    dict.set_item("crease_sharpness", PyArray1::from_vec(py, sharpness))?;
    let (vertices, sharpness): (Vec<i64>, Vec<f32>) = mesh.corners.into_iter().unzip();
    dict.set_item("corner_vertices", PyArray1::from_vec(py, vertices))?;
    dict.set_item("holes", PyArray1::from_vec(py, mesh.holes))?;
    dict.set_item("corner_sharpness", PyArray1::from_vec(py, sharpness))?;
    dict.set_item("boundary", mesh.boundary.map(boundary_name))?;
    dict.set_item("creasing", mesh.creasing.map(creasing_name))?;
    dict.set_item("warnings", mesh.warnings)?;
    let source = PyObjSource {
        inner: Arc::new(mesh.source),
    };
    dict.set_item("source", Py::new(py, source)?)?;
    Ok(dict)
}

/// Writes a polygon mesh as OBJ, atomically (a temporary file renamed over `path` when
/// complete; nothing is left on an error or a signal): `points` (V,3) float32|float64,
/// `face_offsets` uint32 (F+1), `face_indices` uint32, optional face-varying `uvs` (corners,2)
/// and `normals` (corners,3) of the same dtype as `points`; with `uv_indices` (uint32 per face
/// corner) the `uvs` are (N,2) shared `vt` lines and the corners' `vt` indices are those.
#[pyfunction]
#[pyo3(signature = (path, points, face_offsets, face_indices, uvs=None, normals=None, uv_indices=None))]
#[allow(clippy::too_many_arguments)]
fn write_obj(
    py: Python<'_>,
    path: PathBuf,
    points: &Bound<'_, PyAny>,
    face_offsets: PyReadonlyArray1<'_, u32>,
    face_indices: PyReadonlyArray1<'_, u32>,
    uvs: Option<&Bound<'_, PyAny>>,
    normals: Option<&Bound<'_, PyAny>>,
    uv_indices: Option<PyReadonlyArray1<'_, u32>>,
) -> PyResult<()> {
    let offsets = contiguous(&face_offsets, "face_offsets")?;
    let vertices = contiguous(&face_indices, "face_indices")?;
    let extra = FaceVarying {
        uvs,
        normals,
        uv_indices: uv_indices.as_ref(),
    };
    write_mesh(py, &path, points, offsets, vertices, extra)
}

/// Face-varying arrays of an OBJ write: uvs (per corner, or the `vt` values `uv_indices`
/// index), normals.
pub(crate) struct FaceVarying<'a, 'py> {
    pub(crate) uvs: Option<&'a Bound<'py, PyAny>>,
    pub(crate) normals: Option<&'a Bound<'py, PyAny>>,
    pub(crate) uv_indices: Option<&'a PyReadonlyArray1<'py, u32>>,
}

pub(crate) fn write_mesh(
    py: Python<'_>,
    path: &Path,
    points: &Bound<'_, PyAny>,
    offsets: &[u32],
    vertices: &[u32],
    face_varying: FaceVarying<'_, '_>,
) -> PyResult<()> {
    let uv_indices = (face_varying.uv_indices)
        .map(|a| contiguous(a, "uv_indices"))
        .transpose()?;
    let [uvs, normals] = [(face_varying.uvs, "uvs"), (face_varying.normals, "normals")]
        .map(|(a, what)| a.map(|a| floats(a, what)).transpose());
    let (uvs, normals) = (uvs?, normals?);
    match floats(points, "points")? {
        Floats::F32(p) => {
            let extra = [same_dtype(py, &uvs, f32s)?, same_dtype(py, &normals, f32s)?];
            write_typed(py, path, &p, offsets, vertices, extra, uv_indices)
        }
        Floats::F64(p) => {
            let extra = [same_dtype(py, &uvs, f64s)?, same_dtype(py, &normals, f64s)?];
            write_typed(py, path, &p, offsets, vertices, extra, uv_indices)
        }
    }
}

fn f32s<'a, 'py>(a: &'a Floats<'py>) -> Option<&'a PyReadonlyArray2<'py, f32>> {
    match a {
        Floats::F32(a) => Some(a),
        Floats::F64(_) => None,
    }
}

fn f64s<'a, 'py>(a: &'a Floats<'py>) -> Option<&'a PyReadonlyArray2<'py, f64>> {
    match a {
        Floats::F64(a) => Some(a),
        Floats::F32(_) => None,
    }
}

/// An optional face-varying array, which must have the dtype `pick` selects (that of the
/// points).
fn same_dtype<'py, T: Element>(
    py: Python<'_>,
    array: &Option<Floats<'py>>,
    pick: for<'a> fn(&'a Floats<'py>) -> Option<&'a PyReadonlyArray2<'py, T>>,
) -> PyResult<Option<PyReadonlyArray2<'py, T>>> {
    match array {
        None => Ok(None),
        Some(a) => pick(a)
            .cloned()
            .map(Some)
            .ok_or_else(|| to_py_err(py, invalid("uvs and normals must have the dtype of points"))),
    }
}

fn write_typed<T: Element + ObjFloat>(
    py: Python<'_>,
    path: &Path,
    points: &PyReadonlyArray2<'_, T>,
    offsets: &[u32],
    vertices: &[u32],
    [uvs, normals]: [Option<PyReadonlyArray2<'_, T>>; 2],
    uv_indices: Option<&[u32]>,
) -> PyResult<()> {
    if points.shape()[1] != 3 {
        return Err(to_py_err(
            py,
            invalid(format!(
                "OBJ needs 3 coordinates per point, not {}",
                points.shape()[1]
            )),
        ));
    }
    let data = contiguous(points, "points")?;
    let uv = match &uvs {
        Some(u) => {
            if u.shape()[1] != 2 {
                return Err(to_py_err(py, invalid("uvs must have shape (N, 2)")));
            }
            Some(contiguous(u, "uvs")?)
        }
        None => None,
    };
    let normals = match &normals {
        Some(n) => {
            if n.shape()[1] != 3 {
                return Err(to_py_err(
                    py,
                    invalid("normals must have shape (corners, 3)"),
                ));
            }
            Some(contiguous(n, "normals")?)
        }
        None => None,
    };
    let mesh = ObjOutput {
        points: data,
        face_offsets: offsets,
        face_vertices: vertices,
        uvs: uv.map(|values| match uv_indices {
            Some(indices) => Uvs::Indexed { values, indices },
            None => Uvs::PerCorner(values),
        }),
        normals,
    };
    run_interruptible(py, |interrupt| io::write_obj(path, &mesh, interrupt))
}
