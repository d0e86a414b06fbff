//! `bidegree._native`: the thin pyo3 layer between the Python package `bidegree` and the Rust
//! core. It owns argument conversion (numpy arrays in and out, without copies where possible),
//! releasing the GIL around every call into the core, catching panics (they become
//! `bidegree.InternalError`, never a crash or a `PanicException`) and turning each
//! [`bidegree::Error`] variant into its Python exception class (defined in
//! `bidegree/_errors.py`). Behaviour lives in the core; argument checks with friendly messages
//! live in the Python layer (`bidegree/__init__.py`), which always hands over C-contiguous arrays
//! of the expected dtypes. This layer checks again and refuses anything else.

mod adaptive;

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;

use bidegree::io::{self, ObjMesh};
use bidegree::{
    Boundary, Cage, Creasing, Error, Options, OutputKind, Plan, Rules, Scalar,
    DEFAULT_MEMORY_BUDGET, MAX_DEGREE, MAX_LEVELS,
};
use numpy::ndarray::Dimension;
use numpy::{
    Element, PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray, PyReadonlyArray1,
    PyReadonlyArray2, PyUntypedArrayMethods,
};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyType};

// ---------------------------------------------------------------------------------------------
// Errors and panics

/// Python class name (in `bidegree._errors`) of each error variant, and the integer details that
/// are attached to the exception as attributes.
fn error_class(error: &Error) -> (&'static str, Vec<(&'static str, i64)>) {
    let n = |x: usize| x as i64;
    match error {
        Error::EmptyMesh(_) => ("EmptyMeshError", vec![]),
        Error::FaceTooSmall { face, size } => (
            "FaceTooSmallError",
            vec![("face", n(*face)), ("size", n(*size))],
        ),
        Error::RepeatedVertex { face, vertex } => (
            "RepeatedVertexError",
            vec![("face", n(*face)), ("vertex", n(*vertex))],
        ),
        Error::IndexOutOfRange {
            index,
            num_vertices,
            ..
        } => (
            "IndexOutOfRangeError",
            vec![("index", *index), ("num_vertices", n(*num_vertices))],
        ),
        Error::NonFinite { vertex } => ("NonFiniteError", vec![("vertex", n(*vertex))]),
        Error::DegenerateFace { face } => ("DegenerateFaceError", vec![("face", n(*face))]),
        Error::NonManifoldEdge { a, b, faces } => (
            "NonManifoldEdgeError",
            vec![("a", n(*a)), ("b", n(*b)), ("faces", n(*faces))],
        ),
        Error::InconsistentOrientation {
            a,
            b,
            face_a,
            face_b,
        } => (
            "InconsistentOrientationError",
            vec![
                ("a", n(*a)),
                ("b", n(*b)),
                ("face_a", n(*face_a)),
                ("face_b", n(*face_b)),
            ],
        ),
        Error::CreaseNotAnEdge { crease, a, b } => (
            "CreaseNotAnEdgeError",
            vec![("crease", n(*crease)), ("a", n(*a)), ("b", n(*b))],
        ),
        Error::DegreeOutOfRange { degree, max } => (
            "DegreeOutOfRangeError",
            vec![("degree", *degree), ("max", i64::from(*max))],
        ),
        Error::LevelOutOfRange { levels, max } => (
            "LevelOutOfRangeError",
            vec![("levels", *levels), ("max", i64::from(*max))],
        ),
        Error::MemoryBudget {
            required,
            budget,
            faces,
        } => (
            "MemoryBudgetError",
            vec![
                ("required", i64::try_from(*required).unwrap_or(i64::MAX)),
                ("budget", i64::try_from(*budget).unwrap_or(i64::MAX)),
                ("faces", i64::try_from(*faces).unwrap_or(i64::MAX)),
            ],
        ),
        Error::InvalidInput(_) => ("InvalidInputError", vec![]),
        Error::Io(_) => ("BidegreeIOError", vec![]),
        Error::Internal(_) => ("InternalError", vec![]),
    }
}

/// The Python exception for a core error: the class of its variant, the message of its
/// `Display`, and its details as attributes (e.g. `err.face`).
fn to_py_err(py: Python<'_>, error: Error) -> PyErr {
    let (class, details) = error_class(&error);
    let message = error.to_string();
    let class = py
        .import("bidegree._errors")
        .and_then(|module| module.getattr(class))
        .and_then(|class| class.cast_into::<PyType>().map_err(PyErr::from));
    match class {
        Ok(class) => {
            let err = PyErr::from_type(class, (message,));
            let value = err.value(py);
            for (name, number) in details {
                // Attributes are a convenience: failing to set one must not hide the error.
                let _ = value.setattr(name, number);
            }
            if let Error::IndexOutOfRange { what, .. } = &error {
                let _ = value.setattr("what", what.as_str());
            }
            err
        }
        // Only when the package is broken (the Python half missing).
        Err(_) => PyRuntimeError::new_err(message),
    }
}

fn invalid(message: impl Into<String>) -> Error {
    Error::InvalidInput(message.into())
}

/// Text of a panic payload.
fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "a panic without a message".to_string()
    }
}

/// Runs core work with the GIL released and panics caught: every call into the core goes
/// through here.
fn run<T, F>(py: Python<'_>, work: F) -> PyResult<T>
where
    F: FnOnce() -> bidegree::Result<T> + Send,
    T: Send,
{
    let outcome = py.detach(move || match catch_unwind(AssertUnwindSafe(work)) {
        Ok(result) => result,
        Err(payload) => Err(Error::Internal(format!(
            "the core panicked: {}",
            panic_message(payload.as_ref())
        ))),
    });
    outcome.map_err(|error| to_py_err(py, error))
}

/// Runs a cheap core accessor (no GIL release) with panics caught, so that not even a getter
/// can let a panic reach Python.
fn guard<T>(py: Python<'_>, access: impl FnOnce() -> T) -> PyResult<T> {
    catch_unwind(AssertUnwindSafe(access)).map_err(|payload| {
        to_py_err(
            py,
            Error::Internal(format!(
                "the core panicked: {}",
                panic_message(payload.as_ref())
            )),
        )
    })
}

// ---------------------------------------------------------------------------------------------
// Array conversion

/// The data of a C-contiguous array. `as_slice` alone would also accept, and misread, Fortran
/// order; the Python layer always passes C-contiguous arrays, so this is a guard.
fn contiguous<'a, T: Element, D: Dimension>(
    array: &'a PyReadonlyArray<'_, T, D>,
    what: &str,
) -> PyResult<&'a [T]> {
    if !array.is_c_contiguous() {
        return Err(to_py_err(
            array.py(),
            invalid(format!("{what} must be C-contiguous")),
        ));
    }
    array
        .as_slice()
        .map_err(|_| to_py_err(array.py(), invalid(format!("{what} is not contiguous"))))
}

/// A 2-D float array of either supported precision.
enum Floats<'py> {
    F32(PyReadonlyArray2<'py, f32>),
    F64(PyReadonlyArray2<'py, f64>),
}

fn floats<'py>(values: &Bound<'py, PyAny>, what: &str) -> PyResult<Floats<'py>> {
    let py = values.py();
    let borrow_error = |_| to_py_err(py, invalid(format!("{what} is being written elsewhere")));
    if let Ok(array) = values.cast::<PyArray2<f32>>() {
        return Ok(Floats::F32(array.try_readonly().map_err(borrow_error)?));
    }
    if let Ok(array) = values.cast::<PyArray2<f64>>() {
        return Ok(Floats::F64(array.try_readonly().map_err(borrow_error)?));
    }
    Err(to_py_err(
        py,
        invalid(format!(
            "{what} must be a 2-D float32 or float64 numpy array"
        )),
    ))
}

/// A `(rows, channels)` array owning `data` (no copy).
fn array2<'py, T: Element>(
    py: Python<'py>,
    data: Vec<T>,
    channels: usize,
) -> PyResult<Bound<'py, PyArray2<T>>> {
    let rows = data.len().checked_div(channels).unwrap_or(0);
    PyArray1::from_vec(py, data).reshape([rows, channels])
}

/// `u32` indices as `int32` (what numpy and Blender index with).
fn to_i32(values: &[u32]) -> bidegree::Result<Vec<i32>> {
    values
        .iter()
        .map(|&v| i32::try_from(v).map_err(|_| Error::Internal(format!("index {v} exceeds int32"))))
        .collect()
}

fn parse_output(output: &str) -> bidegree::Result<OutputKind> {
    match output {
        "primal" => Ok(OutputKind::Primal),
        "dual" => Ok(OutputKind::Dual),
        other => Err(invalid(format!(
            "output must be 'primal' or 'dual', not {other:?}"
        ))),
    }
}

fn parse_boundary(boundary: &str) -> bidegree::Result<Boundary> {
    match boundary {
        "edge-only" => Ok(Boundary::EdgeOnly),
        "edge-and-corner" => Ok(Boundary::EdgeAndCorner),
        other => Err(invalid(format!(
            "boundary must be 'edge-only' or 'edge-and-corner', not {other:?}"
        ))),
    }
}

fn output_name(output: OutputKind) -> &'static str {
    match output {
        OutputKind::Primal => "primal",
        OutputKind::Dual => "dual",
    }
}

fn parse_rules(rules: &str, creasing: &str) -> bidegree::Result<(Rules, Creasing)> {
    let rules = match rules {
        "averaging" => Rules::Averaging,
        "classic" => Rules::Classic,
        other => {
            return Err(Error::InvalidInput(format!(
                "rules must be 'averaging' or 'classic', not {other:?}"
            )))
        }
    };
    let creasing = match creasing {
        "uniform" => Creasing::Uniform,
        "chaikin" => Creasing::Chaikin,
        other => {
            return Err(Error::InvalidInput(format!(
                "creasing must be 'uniform' or 'chaikin', not {other:?}"
            )))
        }
    };
    Ok((rules, creasing))
}

fn boundary_name(boundary: Boundary) -> &'static str {
    match boundary {
        Boundary::EdgeOnly => "edge-only",
        Boundary::EdgeAndCorner => "edge-and-corner",
    }
}

/// Options from Python arguments; degree and levels come as `i64` so that negative or huge
/// values are reported as the range errors they are.
fn options(
    degree: i64,
    levels: i64,
    output: &str,
    boundary: &str,
    memory_budget: Option<u64>,
    rules: &str,
    creasing: &str,
) -> bidegree::Result<Options> {
    let (rules, creasing) = parse_rules(rules, creasing)?;
    let degree = u32::try_from(degree).map_err(|_| Error::DegreeOutOfRange {
        degree,
        max: MAX_DEGREE,
    })?;
    let levels = u32::try_from(levels).map_err(|_| Error::LevelOutOfRange {
        levels,
        max: MAX_LEVELS,
    })?;
    Ok(Options {
        degree,
        levels,
        output: parse_output(output)?,
        boundary: parse_boundary(boundary)?,
        memory_budget: memory_budget.unwrap_or(DEFAULT_MEMORY_BUDGET),
        rules,
        creasing,
    })
}

// ---------------------------------------------------------------------------------------------
// Cage

/// The cage topology (validated on construction): faces, creases and corners.
#[pyclass(frozen, module = "bidegree._native", name = "Cage")]
struct PyCage {
    inner: Cage,
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
    run(py, || bidegree::validate_geometry(cage, data, channels))
}

// ---------------------------------------------------------------------------------------------
// Plan

/// A subdivision plan: the refined topology for one cage and one set of options, evaluated any
/// number of times.
#[pyclass(frozen, module = "bidegree._native", name = "Plan")]
struct PyPlan {
    inner: Plan,
}

impl PyPlan {
    fn indices<'py>(
        &self,
        py: Python<'py>,
        pick: impl FnOnce(&Plan) -> bidegree::Result<Vec<i32>> + Send,
    ) -> PyResult<Bound<'py, PyArray1<i32>>> {
        let plan = &self.inner;
        let data = run(py, || pick(plan))?;
        Ok(PyArray1::from_vec(py, data))
    }
}

#[pymethods]
impl PyPlan {
    /// Builds the plan (topology only; the memory budget is checked first).
    #[new]
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (cage, degree, levels, output, boundary, memory_budget=None, rules="averaging", creasing="uniform"))]
    fn new(
        py: Python<'_>,
        cage: &Bound<'_, PyCage>,
        degree: i64,
        levels: i64,
        output: &str,
        boundary: &str,
        memory_budget: Option<u64>,
        rules: &str,
        creasing: &str,
    ) -> PyResult<Self> {
        let cage = &cage.get().inner;
        let inner = run(py, || {
            Plan::new(
                cage,
                &options(
                    degree,
                    levels,
                    output,
                    boundary,
                    memory_budget,
                    rules,
                    creasing,
                )?,
            )
        })?;
        Ok(PyPlan { inner })
    }

    /// Per cage vertex values `(V, C)` -> per output vertex values `(N, C)`, same dtype.
    fn evaluate<'py>(
        &self,
        py: Python<'py>,
        values: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        match floats(values, "values")? {
            Floats::F32(a) => Ok(evaluate(py, &self.inner, &a, false)?.into_any()),
            Floats::F64(a) => Ok(evaluate(py, &self.inner, &a, false)?.into_any()),
        }
    }

    /// Limit positions `(N, C)` at the output vertices (the first ones are the cage vertices'
    /// limits), from per cage vertex values `(V, C)`: every degree of the averaging rules,
    /// degree 3 of the classic ones.
    fn limit_positions<'py>(
        &self,
        py: Python<'py>,
        values: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        fn limit<'py, T: Scalar + Element>(
            py: Python<'py>,
            plan: &Plan,
            values: &PyReadonlyArray2<'_, T>,
        ) -> PyResult<Bound<'py, PyArray2<T>>> {
            let channels = values.shape()[1];
            let data = contiguous(values, "values")?;
            let out = run(py, || {
                if channels == 0 {
                    return Err(invalid("values need at least one channel"));
                }
                plan.limit_positions(data, channels)
            })?;
            array2(py, out, channels)
        }
        match floats(values, "values")? {
            Floats::F32(a) => Ok(limit(py, &self.inner, &a)?.into_any()),
            Floats::F64(a) => Ok(limit(py, &self.inner, &a)?.into_any()),
        }
    }

    /// Limit positions `(N, 3)` and unit limit normals `(output corners, 3)` of points `(V, 3)`.
    fn limit_surface<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        type Pair<'py> = (Bound<'py, PyAny>, Bound<'py, PyAny>);
        fn surface<'py, T: Scalar + Element>(
            py: Python<'py>,
            plan: &Plan,
            points: &PyReadonlyArray2<'_, T>,
        ) -> PyResult<Pair<'py>> {
            if points.shape()[1] != 3 {
                let shape = points.shape();
                return Err(to_py_err(
                    py,
                    invalid(format!("points must have shape (V, 3), not {shape:?}")),
                ));
            }
            let data = contiguous(points, "points")?;
            let (positions, normals) = run(py, || plan.limit_surface(data))?;
            Ok((
                array2(py, positions, 3)?.into_any(),
                array2(py, normals, 3)?.into_any(),
            ))
        }
        match floats(points, "points")? {
            Floats::F32(a) => surface(py, &self.inner, &a),
            Floats::F64(a) => surface(py, &self.inner, &a),
        }
    }

    /// Levels the limit evaluation adds to the plan (0 when every output vertex is clean).
    #[getter]
    fn limit_extra_levels(&self, py: Python<'_>) -> PyResult<u32> {
        run(py, || self.inner.limit_extra_levels())
    }

    /// `"averaging"` or `"classic"`.
    #[getter]
    fn rules(&self, py: Python<'_>) -> PyResult<&'static str> {
        guard(py, || match self.inner.options().rules {
            Rules::Averaging => "averaging",
            Rules::Classic => "classic",
        })
    }

    /// Per cage face corner values `(corners, C)` -> per output face corner values, linearly.
    fn evaluate_face_varying<'py>(
        &self,
        py: Python<'py>,
        values: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        match floats(values, "values")? {
            Floats::F32(a) => Ok(evaluate(py, &self.inner, &a, true)?.into_any()),
            Floats::F64(a) => Ok(evaluate(py, &self.inner, &a, true)?.into_any()),
        }
    }

    /// Degree of the scheme.
    #[getter]
    fn degree(&self, py: Python<'_>) -> PyResult<u32> {
        guard(py, || self.inner.options().degree)
    }

    /// Number of levels.
    #[getter]
    fn levels(&self, py: Python<'_>) -> PyResult<u32> {
        guard(py, || self.inner.options().levels)
    }

    /// `"primal"` or `"dual"`.
    #[getter]
    fn output(&self, py: Python<'_>) -> PyResult<&'static str> {
        guard(py, || output_name(self.inner.options().output))
    }

    /// `"edge-only"` or `"edge-and-corner"`.
    #[getter]
    fn boundary(&self, py: Python<'_>) -> PyResult<&'static str> {
        guard(py, || boundary_name(self.inner.options().boundary))
    }

    /// Memory budget the plan was made under, in bytes.
    #[getter]
    fn memory_budget(&self, py: Python<'_>) -> PyResult<u64> {
        guard(py, || self.inner.options().memory_budget)
    }

    /// Number of cage vertices the plan expects values for.
    #[getter]
    fn num_input_vertices(&self, py: Python<'_>) -> PyResult<usize> {
        guard(py, || self.inner.num_input_vertices())
    }

    /// Number of output vertices.
    #[getter]
    fn num_output_vertices(&self, py: Python<'_>) -> PyResult<usize> {
        guard(py, || self.inner.num_output_vertices())
    }

    /// Number of output faces.
    #[getter]
    fn num_output_faces(&self, py: Python<'_>) -> PyResult<usize> {
        guard(py, || self.inner.num_output_faces())
    }

    /// Cage vertices in no face (dropped from the output), int32.
    fn isolated_vertices<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<i32>>> {
        self.indices(py, |plan| to_i32(plan.isolated_vertices()))
    }

    /// Corners of each output face, int32 `(F,)`.
    fn face_sizes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<i32>>> {
        self.indices(py, |plan| {
            plan.output_face_offsets()
                .windows(2)
                .map(|w| {
                    i32::try_from(w[1] - w[0])
                        .map_err(|_| Error::Internal("face size exceeds int32".into()))
                })
                .collect()
        })
    }

    /// Output vertex of each output face corner, int32.
    fn face_indices<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<i32>>> {
        self.indices(py, |plan| to_i32(plan.output_face_vertices()))
    }

    /// Cage face each output face comes from, int32 `(F,)`.
    fn face_origin<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<i32>>> {
        self.indices(py, |plan| to_i32(plan.output_face_origin()))
    }

    /// Edge (index into `edges`) from each output face corner to the next, int32.
    fn corner_edges<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<i32>>> {
        self.indices(py, |plan| to_i32(plan.output_corner_edges()))
    }

    /// Edges of the output mesh, int32 `(E, 2)`.
    fn edges<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i32>>> {
        let plan = &self.inner;
        let flat = run(py, || {
            let edges = plan.output_edges();
            to_i32(edges.as_flattened())
        })?;
        array2(py, flat, 2)
    }

    /// Writes the output mesh with `points` `(N, 3)` and optional face-varying `uvs`
    /// `(corners, 2)` and `normals` `(corners, 3)` (same dtype as `points`) as OBJ.
    #[pyo3(signature = (path, points, uvs=None, normals=None))]
    fn write_obj(
        &self,
        py: Python<'_>,
        path: PathBuf,
        points: &Bound<'_, PyAny>,
        uvs: Option<&Bound<'_, PyAny>>,
        normals: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let plan = &self.inner;
        let (offsets, vertices) = guard(py, || {
            (plan.output_face_offsets(), plan.output_face_vertices())
        })?;
        write_mesh(py, &path, points, offsets, vertices, [uvs, normals])
    }
}

fn evaluate<'py, T: Scalar + Element>(
    py: Python<'py>,
    plan: &Plan,
    values: &PyReadonlyArray2<'_, T>,
    face_varying: bool,
) -> PyResult<Bound<'py, PyArray2<T>>> {
    let channels = values.shape()[1];
    let data = contiguous(values, "values")?;
    let out = run(py, || {
        if channels == 0 {
            return Err(invalid("values need at least one channel"));
        }
        if face_varying {
            plan.evaluate_face_varying(data, channels)
        } else {
            plan.evaluate(data, channels)
        }
    })?;
    array2(py, out, channels)
}

fn evaluate_fresh<'py, T: Scalar + Element>(
    py: Python<'py>,
    cage: &Cage,
    points: &PyReadonlyArray2<'_, T>,
    options: Options,
    evaluate: bool,
) -> PyResult<(PyPlan, Option<Bound<'py, PyAny>>)> {
    let channels = points.shape()[1];
    let data = contiguous(points, "points")?;
    let (plan, out) = run(py, || {
        if channels == 0 {
            return Err(invalid("points need at least one channel"));
        }
        if evaluate {
            let (plan, out) = bidegree::subdivide(cage, data, channels, &options)?;
            return Ok((plan, Some(out)));
        }
        bidegree::validate_geometry(cage, data, channels)?;
        Ok((Plan::new(cage, &options)?, None))
    })?;
    let out = match out {
        Some(out) => Some(array2(py, out, channels)?.into_any()),
        None => None,
    };
    Ok((PyPlan { inner: plan }, out))
}

/// Validates the geometry, builds the plan and (with `evaluate`) evaluates the points in one
/// call; without `evaluate` the points are `None` (a caller that wants limit positions only).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (cage, points, degree, levels, output, boundary, memory_budget=None, rules="averaging", creasing="uniform", evaluate=true))]
fn subdivide<'py>(
    py: Python<'py>,
    cage: &Bound<'py, PyCage>,
    points: &Bound<'py, PyAny>,
    degree: i64,
    levels: i64,
    output: &str,
    boundary: &str,
    memory_budget: Option<u64>,
    rules: &str,
    creasing: &str,
    evaluate: bool,
) -> PyResult<(PyPlan, Option<Bound<'py, PyAny>>)> {
    let cage = &cage.get().inner;
    let options = options(
        degree,
        levels,
        output,
        boundary,
        memory_budget,
        rules,
        creasing,
    )
    .map_err(|e| to_py_err(py, e))?;
    match floats(points, "points")? {
        Floats::F32(a) => evaluate_fresh(py, cage, &a, options, evaluate),
        Floats::F64(a) => evaluate_fresh(py, cage, &a, options, evaluate),
    }
}

/// Output size and peak memory of a request, without doing it: `(vertices, faces, bytes)`.
#[pyfunction]
#[pyo3(signature = (cage, degree, levels, output="primal", boundary="edge-only"))]
fn estimate(
    py: Python<'_>,
    cage: &Bound<'_, PyCage>,
    degree: i64,
    levels: i64,
    output: &str,
    boundary: &str,
) -> PyResult<(u64, u64, u64)> {
    let cage = &cage.get().inner;
    let estimate = run(py, || {
        bidegree::estimate(
            cage,
            &options(
                degree,
                levels,
                output,
                boundary,
                Some(u64::MAX),
                "averaging",
                "uniform",
            )?,
        )
    })?;
    Ok((estimate.vertices, estimate.faces, estimate.bytes))
}

// ---------------------------------------------------------------------------------------------
// OBJ

/// Reads an OBJ file into a dict of numpy arrays: `points` (V,3) float64, `face_sizes` and
/// `face_indices` int64, `uvs` (T,2) float64, `face_uvs` int64 or None, `crease_edges` (K,2)
/// int64, `crease_sharpness` float32, `corner_vertices` int64, `corner_sharpness` float32,
/// `boundary` (`"edge-only"`, `"edge-and-corner"` or None when the file has no tag).
#[pyfunction]
fn read_obj<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let mesh: ObjMesh = run(py, || io::read_obj(&path))?;
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
    dict.set_item("corner_sharpness", PyArray1::from_vec(py, sharpness))?;
    dict.set_item("boundary", mesh.boundary.map(boundary_name))?;
    Ok(dict)
}

/// Writes a polygon mesh as OBJ: `points` (V,3) float32|float64, `face_offsets` uint32 (F+1),
/// `face_indices` uint32, optional face-varying `uvs` (corners,2) and `normals` (corners,3) of
/// the same dtype as `points`.
#[pyfunction]
#[pyo3(signature = (path, points, face_offsets, face_indices, uvs=None, normals=None))]
fn write_obj(
    py: Python<'_>,
    path: PathBuf,
    points: &Bound<'_, PyAny>,
    face_offsets: PyReadonlyArray1<'_, u32>,
    face_indices: PyReadonlyArray1<'_, u32>,
    uvs: Option<&Bound<'_, PyAny>>,
    normals: Option<&Bound<'_, PyAny>>,
) -> PyResult<()> {
    let offsets = contiguous(&face_offsets, "face_offsets")?;
    let vertices = contiguous(&face_indices, "face_indices")?;
    write_mesh(py, &path, points, offsets, vertices, [uvs, normals])
}

/// Face-varying arrays of an OBJ write: uvs, normals.
type FaceVarying<'a, 'py> = [Option<&'a Bound<'py, PyAny>>; 2];

fn write_mesh(
    py: Python<'_>,
    path: &std::path::Path,
    points: &Bound<'_, PyAny>,
    offsets: &[u32],
    vertices: &[u32],
    face_varying: FaceVarying<'_, '_>,
) -> PyResult<()> {
    let [uvs, normals] = [(face_varying[0], "uvs"), (face_varying[1], "normals")]
        .map(|(a, what)| a.map(|a| floats(a, what)).transpose());
    let (uvs, normals) = (uvs?, normals?);
    match floats(points, "points")? {
        Floats::F32(p) => {
            let extra = [same_dtype(py, &uvs, f32s)?, same_dtype(py, &normals, f32s)?];
            write_typed(py, path, &p, offsets, vertices, extra, io::write_obj_f32)
        }
        Floats::F64(p) => {
            let extra = [same_dtype(py, &uvs, f64s)?, same_dtype(py, &normals, f64s)?];
            write_typed(py, path, &p, offsets, vertices, extra, io::write_obj)
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

/// Signature of the typed OBJ writers in the core.
type ObjWriter<T> = fn(
    &std::path::Path,
    &[T],
    &[u32],
    &[u32],
    Option<(&[T], &[u32])>,
    Option<&[T]>,
) -> bidegree::Result<()>;

fn write_typed<T: Element + Sync>(
    py: Python<'_>,
    path: &std::path::Path,
    points: &PyReadonlyArray2<'_, T>,
    offsets: &[u32],
    vertices: &[u32],
    [uvs, normals]: [Option<PyReadonlyArray2<'_, T>>; 2],
    writer: ObjWriter<T>,
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
                return Err(to_py_err(py, invalid("uvs must have shape (corners, 2)")));
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
    run(py, || {
        // Face-varying: one UV per face corner, in corner order.
        let corner_ids: Vec<u32>;
        let uvs = match uv {
            Some(values) => {
                if values.len() / 2 != vertices.len() {
                    return Err(invalid(format!(
                        "{} uvs for {} face corners",
                        values.len() / 2,
                        vertices.len()
                    )));
                }
                let count = u32::try_from(vertices.len())
                    .map_err(|_| invalid("too many face corners for OBJ uv indices"))?;
                corner_ids = (0..count).collect();
                Some((values, corner_ids.as_slice()))
            }
            None => None,
        };
        writer(path, data, offsets, vertices, uvs, normals)
    })
}

// ---------------------------------------------------------------------------------------------
// Analysis (the paper's §4: subdivision matrices, Fourier blocks, C1 report)

/// Complex values as a numpy complex128 array.
fn complex_array<'py>(
    py: Python<'py>,
    values: &[bidegree::analysis::C64],
) -> Bound<'py, PyArray1<numpy::Complex64>> {
    PyArray1::from_vec(
        py,
        values
            .iter()
            .map(|z| numpy::Complex64::new(z.re, z.im))
            .collect(),
    )
}

/// A float array of the given shape owning `data`.
fn shaped<'py>(py: Python<'py>, data: Vec<f64>, shape: &[usize]) -> PyResult<Bound<'py, PyAny>> {
    Ok(PyArray1::from_vec(py, data)
        .reshape(shape.to_vec())?
        .into_any())
}

/// Checked degree and valence of an analysis request.
fn analysis_args(degree: i64, valence: i64) -> bidegree::Result<(u32, usize)> {
    if !(1..=i64::from(MAX_DEGREE)).contains(&degree) {
        return Err(Error::DegreeOutOfRange {
            degree,
            max: MAX_DEGREE,
        });
    }
    if !(3..=1000).contains(&valence) {
        return Err(invalid(format!(
            "valence must be in 3..=1000, got {valence}"
        )));
    }
    Ok((degree as u32, valence as usize))
}

/// The analysis of one degree and valence (`bidegree.analysis` in the core): `matrix` (n,n)
/// float64 and `labels` (n,3) int64 (sector, i, j), `eigenvalues` complex128 (the union of the
/// Fourier blocks' spectra, by decreasing modulus) with `modes` int64, `blocks` (the complex
/// Fourier blocks, one per mode) and `block_eigenvalues` (per mode). With `steps > 0` also the
/// report (`text`, `c1`, `dominant`, `subdominant`, `third`, ... and the characteristic map:
/// `map_points` (k, rows, columns, 2), `map_params` (rows, columns, 2), `map_cell_jacobian`
/// (rows-1, columns-1, 2), `map_in_ring`, `map_spacing`, `map_steps`).
#[pyfunction]
#[pyo3(signature = (degree, valence, steps=4))]
fn analyze<'py>(
    py: Python<'py>,
    degree: i64,
    valence: i64,
    steps: i64,
) -> PyResult<Bound<'py, PyDict>> {
    use bidegree::analysis::{subdivision_matrix, FourierBlock, Report, C64};
    type Analysis = (
        bidegree::analysis::SubdivisionMatrix,
        Vec<FourierBlock>,
        Vec<Vec<C64>>,
        Vec<(C64, usize)>,
        Option<Report>,
    );
    let result: Analysis = run(py, || {
        let (degree, valence) = analysis_args(degree, valence)?;
        if !(0..=8).contains(&steps) {
            return Err(invalid(format!("steps must be in 0..=8, got {steps}")));
        }
        let m = subdivision_matrix(degree, valence)?;
        let blocks = m.fourier_blocks();
        let spectra = m.block_eigenvalues()?;
        let all = m.eigenvalues_by_blocks()?;
        let report = if steps > 0 {
            Some(m.report(steps as usize)?)
        } else {
            None
        };
        Ok((m, blocks, spectra, all, report))
    })?;
    let (m, blocks, spectra, all, report) = result;
    let dict = PyDict::new(py);
    let n = m.labels.len();
    dict.set_item("degree", m.degree)?;
    dict.set_item("valence", m.valence)?;
    // nalgebra is column-major: transpose into numpy's row-major order.
    dict.set_item(
        "matrix",
        shaped(py, m.matrix.transpose().as_slice().to_vec(), &[n, n])?,
    )?;
    let labels: Vec<i64> = m
        .labels
        .iter()
        .flat_map(|&(s, i, j)| [s as i64, i as i64, j as i64])
        .collect();
    dict.set_item("labels", array2(py, labels, 3)?)?;
    let (values, modes): (Vec<C64>, Vec<i64>) =
        all.iter().map(|&(z, mode)| (z, mode as i64)).unzip();
    dict.set_item("eigenvalues", complex_array(py, &values))?;
    dict.set_item("modes", PyArray1::from_vec(py, modes))?;
    let block_list = pyo3::types::PyList::empty(py);
    for block in &blocks {
        let b = block.matrix.transpose();
        let size = b.nrows();
        block_list.append(complex_array(py, b.as_slice()).reshape([size, size])?)?;
    }
    dict.set_item("blocks", block_list)?;
    let spectra_list = pyo3::types::PyList::empty(py);
    for values in &spectra {
        spectra_list.append(complex_array(py, values))?;
    }
    dict.set_item("block_eigenvalues", spectra_list)?;
    if let Some(r) = report {
        let z = |z: C64| pyo3::types::PyComplex::from_doubles(py, z.re, z.im);
        dict.set_item("text", r.to_string())?;
        dict.set_item("dominant", z(r.dominant))?;
        dict.set_item("dominant_simple", r.dominant_simple)?;
        dict.set_item("subdominant", complex_array(py, &r.subdominant))?;
        dict.set_item("subdominant_real", r.subdominant_real)?;
        dict.set_item("subdominant_equal", r.subdominant_equal)?;
        dict.set_item("subdominant_simple", r.subdominant_simple)?;
        dict.set_item("third", z(r.third))?;
        dict.set_item("third_mode", r.third_mode)?;
        dict.set_item("subdominant_isolated", r.subdominant_isolated)?;
        dict.set_item("subdominant_squared", r.subdominant_squared)?;
        dict.set_item("c2_excluded", r.c2_excluded)?;
        dict.set_item("jacobian_min", r.jacobian_min)?;
        dict.set_item("jacobian_max", r.jacobian_max)?;
        dict.set_item("winding", r.winding)?;
        dict.set_item("winding_turns", r.winding_turns)?;
        dict.set_item("regular", r.regular)?;
        dict.set_item("c1", r.c1)?;
        let map = &r.map;
        let (k, rows, columns) = (map.valence, map.rows, map.columns);
        let points: Vec<f64> = map.points.iter().flatten().flatten().copied().collect();
        dict.set_item("map_points", shaped(py, points, &[k, rows, columns, 2])?)?;
        let params: Vec<f64> = map.params.iter().flatten().copied().collect();
        dict.set_item("map_params", shaped(py, params, &[rows, columns, 2])?)?;
        let cells: Vec<f64> = map.cell_jacobian.iter().flatten().copied().collect();
        dict.set_item(
            "map_cell_jacobian",
            shaped(py, cells, &[rows - 1, columns - 1, 2])?,
        )?;
        let ring: Vec<bool> = map.in_ring.clone();
        dict.set_item(
            "map_in_ring",
            PyArray1::from_vec(py, ring).reshape([rows - 1, columns - 1])?,
        )?;
        dict.set_item("map_spacing", map.spacing)?;
        dict.set_item("map_steps", map.steps)?;
    }
    Ok(dict)
}

/// A basis function near an irregular point (`bidegree.analysis.basis_function`): the level-1
/// impulse at `label` (the primal centre or a face of the dual k-gon by default) refined by
/// `steps` engine steps: `params` (rows, columns, 2) sector coordinates (level-1 units),
/// `values` (k, rows, columns), `spacing`, `primal`.
#[pyfunction]
#[pyo3(signature = (degree, valence, steps=3, label=(0, 0, 0)))]
fn basis_function<'py>(
    py: Python<'py>,
    degree: i64,
    valence: i64,
    steps: i64,
    label: (usize, usize, usize),
) -> PyResult<Bound<'py, PyDict>> {
    let net = run(py, || {
        let (degree, valence) = analysis_args(degree, valence)?;
        if !(0..=6).contains(&steps) {
            return Err(invalid(format!("steps must be in 0..=6, got {steps}")));
        }
        bidegree::analysis::basis_function(degree, valence, label, steps as usize)
    })?;
    let dict = PyDict::new(py);
    let (k, rows, columns) = (net.values[0].len(), net.rows, net.columns);
    let params: Vec<f64> = net.params.iter().flatten().copied().collect();
    dict.set_item("params", shaped(py, params, &[rows, columns, 2])?)?;
    let values: Vec<f64> = net.values[0].iter().flatten().copied().collect();
    dict.set_item("values", shaped(py, values, &[k, rows, columns])?)?;
    dict.set_item("spacing", net.spacing)?;
    dict.set_item("primal", degree % 2 == 1)?;
    Ok(dict)
}

/// Makes a panic in the core on purpose (tests check that it arrives as `InternalError`).
#[pyfunction]
fn _panic_for_tests(py: Python<'_>) -> PyResult<()> {
    run(py, || -> bidegree::Result<()> {
        panic!("deliberate panic for tests")
    })
}

/// The extension module `bidegree._native`.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("MAX_DEGREE", MAX_DEGREE)?;
    m.add("MAX_LEVELS", MAX_LEVELS)?;
    m.add("DEFAULT_MEMORY_BUDGET", DEFAULT_MEMORY_BUDGET)?;
    m.add("INFINITELY_SHARP", bidegree::INFINITELY_SHARP)?;
    m.add_class::<PyCage>()?;
    m.add_class::<PyPlan>()?;
    m.add_function(wrap_pyfunction!(subdivide, m)?)?;
    m.add_function(wrap_pyfunction!(estimate, m)?)?;
    m.add_function(wrap_pyfunction!(read_obj, m)?)?;
    m.add_function(wrap_pyfunction!(write_obj, m)?)?;
    m.add_function(wrap_pyfunction!(analyze, m)?)?;
    m.add_function(wrap_pyfunction!(basis_function, m)?)?;
    m.add_function(wrap_pyfunction!(_panic_for_tests, m)?)?;
    adaptive::register(m)?;
    Ok(())
}
