//! `bidegree._native.Plan` and the one-call functions `subdivide` and `estimate`: a plan's
//! evaluations (vertex and face-varying values, limit positions and normals) and its output
//! topology as numpy arrays.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use bidegree::{Error, FaceVaryingMode, NormalDomain, Options, Plan, Scalar};
use numpy::{
    Element, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods,
};
use pyo3::prelude::*;

use crate::arrays::{array2, check_output, contiguous, floats, to_i32, Floats};
use crate::cage::PyCage;
use crate::errors::{guard, invalid, run, to_py_err};
use crate::obj::{write_mesh, FaceVarying};
use crate::options::{
    boundary_name, options, output_name, parse_face_varying_mode, parse_normal_domain, rules_name,
};

/// Registers the plan class and the one-call functions in the extension module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyPlan>()?;
    m.add_function(wrap_pyfunction!(subdivide, m)?)?;
    m.add_function(wrap_pyfunction!(estimate, m)?)
}

/// A subdivision plan: the refined topology for one cage and one set of options, evaluated any
/// number of times.
#[pyclass(frozen, module = "bidegree._native", name = "Plan")]
pub(crate) struct PyPlan {
    inner: Plan,
    /// The face-varying index arrays handed out (int32), per kept topology of the core (the
    /// most recent first): every call on one topology and mode returns the same array.
    shared_indices: Mutex<Vec<KeptIndices>>,
}

/// A core face-varying index table and the int32 array handed out for it.
type KeptIndices = (Arc<[u32]>, Py<PyArray1<i32>>);

/// Values in the indexed form as a numpy array, with the core's kept indices.
type SharedArrays<'py> = (Bound<'py, PyAny>, Arc<[u32]>);

/// Face-varying index arrays a plan keeps for Python (the core keeps four topologies).
const KEPT_INDICES: usize = 4;

impl PyPlan {
    fn indices<'py>(
        &self,
        py: Python<'py>,
        pick: impl FnOnce(&Plan) -> bidegree::Result<Vec<i32>> + Send,
    ) -> PyResult<Bound<'py, PyArray1<i32>>> {
        let plan = &self.inner;
        let data = run(py, || {
            plan.complete_output()?;
            pick(plan)
        })?;
        Ok(PyArray1::from_vec(py, data))
    }

    /// The plan's core `PyPlan` around `inner`.
    fn wrap(inner: Plan) -> PyPlan {
        PyPlan {
            inner,
            shared_indices: Mutex::new(Vec::new()),
        }
    }

    /// The int32 array of the core's kept face-varying `indices`, made on first use and kept.
    fn indices_array<'py>(
        &self,
        py: Python<'py>,
        indices: Arc<[u32]>,
    ) -> PyResult<Bound<'py, PyArray1<i32>>> {
        let lock = || {
            self.shared_indices
                .lock()
                .unwrap_or_else(|e| e.into_inner())
        };
        if let Some((_, array)) = lock().iter().find(|(k, _)| Arc::ptr_eq(k, &indices)) {
            return Ok(array.bind(py).clone());
        }
        // Not under the lock: the conversion runs without the GIL.
        let data = run(py, || to_i32(&indices))?;
        let array = PyArray1::from_vec(py, data);
        let mut kept = lock();
        kept.insert(0, (indices, array.clone().unbind()));
        kept.truncate(KEPT_INDICES);
        Ok(array)
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
        let inner = cage.get().run(py, |cage| {
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
        Ok(PyPlan::wrap(inner))
    }

    /// Per cage vertex values `(V, C)` -> per output vertex values `(N, C)`, same dtype.
    fn evaluate<'py>(
        &self,
        py: Python<'py>,
        values: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        match floats(values, "values")? {
            Floats::F32(a) => Ok(evaluate(py, &self.inner, &a, Evaluation::Vertex)?.into_any()),
            Floats::F64(a) => Ok(evaluate(py, &self.inner, &a, Evaluation::Vertex)?.into_any()),
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
                let out = plan.limit_positions(data, channels)?;
                check_output(&out, channels, data)?;
                Ok(out)
            })?;
            array2(py, out, channels)
        }
        match floats(values, "values")? {
            Floats::F32(a) => Ok(limit(py, &self.inner, &a)?.into_any()),
            Floats::F64(a) => Ok(limit(py, &self.inner, &a)?.into_any()),
        }
    }

    /// Limit positions `(N, 3)` and unit limit normals `(output corners, 3)` (or `(N, 3)`
    /// with `normals="vertex"`) of points `(V, 3)`.
    #[pyo3(signature = (points, normals="corner"))]
    fn limit_surface<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        normals: &str,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        type Pair<'py> = (Bound<'py, PyAny>, Bound<'py, PyAny>);
        fn surface<'py, T: Scalar + Element>(
            py: Python<'py>,
            plan: &Plan,
            points: &PyReadonlyArray2<'_, T>,
            domain: NormalDomain,
        ) -> PyResult<Pair<'py>> {
            if points.shape()[1] != 3 {
                let shape = points.shape();
                return Err(to_py_err(
                    py,
                    invalid(format!("points must have shape (V, 3), not {shape:?}")),
                ));
            }
            let data = contiguous(points, "points")?;
            let (positions, normals) = run(py, || {
                let (positions, normals) = plan.limit_surface_with(data, domain)?;
                check_output(&positions, 3, data)?;
                Ok((positions, normals))
            })?;
            Ok((
                array2(py, positions, 3)?.into_any(),
                array2(py, normals, 3)?.into_any(),
            ))
        }
        let domain = parse_normal_domain(normals).map_err(|e| to_py_err(py, e))?;
        match floats(points, "points")? {
            Floats::F32(a) => surface(py, &self.inner, &a, domain),
            Floats::F64(a) => surface(py, &self.inner, &a, domain),
        }
    }

    /// Frees the working arrays that evaluations and limits keep for the next call (a few of
    /// the last level's size); the next call allocates them again. The topology and the
    /// limit's stencils stay.
    fn release_buffers(&self, py: Python<'_>) -> PyResult<()> {
        run(py, || {
            self.inner.release_buffers();
            Ok(())
        })
    }

    /// Levels the limit evaluation adds to the plan (0 when every output vertex is clean or
    /// near an isolated irregular vertex).
    #[getter]
    fn limit_extra_levels(&self, py: Python<'_>) -> PyResult<u32> {
        run(py, || self.inner.limit_extra_levels())
    }

    /// Whether some output vertex has different limit normals at its corners (creases,
    /// corners; degree 1's faces): without, normals per vertex are exact.
    #[getter]
    fn limit_normals_split(&self, py: Python<'_>) -> PyResult<bool> {
        run(py, || self.inner.limit_normals_split())
    }

    /// `"averaging"` or `"classic"`.
    #[getter]
    fn rules(&self, py: Python<'_>) -> PyResult<&'static str> {
        guard(py, || rules_name(self.inner.options().rules))
    }

    /// Per cage face corner values `(corners, C)` -> per output face corner values, in the
    /// face-varying `mode` (one of OpenSubdiv's six names), optionally on the limit surface.
    /// With `indices` (uint32, one per cage corner): `values` `(N, C)` are indexed by them and
    /// they are the face-varying topology (OpenSubdiv's index buffer).
    #[pyo3(signature = (values, mode="all", limit=false, indices=None))]
    fn evaluate_face_varying<'py>(
        &self,
        py: Python<'py>,
        values: &Bound<'py, PyAny>,
        mode: &str,
        limit: bool,
        indices: Option<PyReadonlyArray1<'py, u32>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let how = face_varying(py, mode, limit, &indices)?;
        match floats(values, "values")? {
            Floats::F32(a) => Ok(evaluate(py, &self.inner, &a, how)?.into_any()),
            Floats::F64(a) => Ok(evaluate(py, &self.inner, &a, how)?.into_any()),
        }
    }

    /// `evaluate_face_varying` in the indexed form: `(values (N, C), indices int32 (output
    /// corners,))`, the values at the refined face-varying mesh's vertices that the output uses
    /// and each output corner's index into them. The indices are topology: the same array for
    /// every call on one face-varying topology and mode.
    #[pyo3(signature = (values, mode="all", limit=false, indices=None))]
    fn evaluate_face_varying_shared<'py>(
        &self,
        py: Python<'py>,
        values: &Bound<'py, PyAny>,
        mode: &str,
        limit: bool,
        indices: Option<PyReadonlyArray1<'py, u32>>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyArray1<i32>>)> {
        let how = face_varying(py, mode, limit, &indices)?;
        let (out, shared) = match floats(values, "values")? {
            Floats::F32(a) => evaluate_shared(py, &self.inner, &a, how)?,
            Floats::F64(a) => evaluate_shared(py, &self.inner, &a, how)?,
        };
        Ok((out, self.indices_array(py, shared)?))
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
            let offsets = plan.output_face_offsets();
            let mut sizes = bidegree::memory::with_capacity(offsets.len().saturating_sub(1))?;
            for w in offsets.windows(2) {
                sizes.push(
                    i32::try_from(w[1] - w[0])
                        .map_err(|_| Error::Internal("face size exceeds int32".into()))?,
                );
            }
            Ok(sizes)
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

    /// Cage edge (row of `cage_edges`) each output edge lies on, -1 inside a cage face, int32.
    fn edge_origin<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<i32>>> {
        self.indices(py, |plan| {
            plan.output_edge_origin()?
                .iter()
                .map(|&e| {
                    if e == bidegree::Level::NONE {
                        Ok(-1)
                    } else {
                        i32::try_from(e)
                            .map_err(|_| Error::Internal(format!("index {e} exceeds int32")))
                    }
                })
                .collect()
        })
    }

    /// Sharpness each output edge keeps at the last level, float32 `(E,)`.
    fn edge_sharpness<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let plan = &self.inner;
        let sharpness = run(py, || plan.output_edge_sharpness())?;
        Ok(PyArray1::from_vec(py, sharpness))
    }

    /// Edges of the cage as pairs of cage vertices (smaller first), ordered by pair, int32 `(E, 2)`.
    fn cage_edges<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i32>>> {
        let plan = &self.inner;
        let flat = run(py, || to_i32(plan.cage_edges().as_flattened()))?;
        array2(py, flat, 2)
    }

    /// Edges of the output mesh, int32 `(E, 2)`.
    fn edges<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i32>>> {
        let plan = &self.inner;
        let flat = run(py, || {
            plan.complete_output()?;
            let edges = plan.output_edges();
            to_i32(edges.as_flattened())
        })?;
        array2(py, flat, 2)
    }

    /// Writes the output mesh with `points` `(N, 3)` and optional face-varying `uvs`
    /// `(corners, 2)` and `normals` `(corners, 3)` (same dtype as `points`) as OBJ; with
    /// `uv_indices` (uint32 per output corner) the `uvs` are (N, 2) shared `vt` lines.
    #[pyo3(signature = (path, points, uvs=None, normals=None, uv_indices=None))]
    fn write_obj(
        &self,
        py: Python<'_>,
        path: PathBuf,
        points: &Bound<'_, PyAny>,
        uvs: Option<&Bound<'_, PyAny>>,
        normals: Option<&Bound<'_, PyAny>>,
        uv_indices: Option<PyReadonlyArray1<'_, u32>>,
    ) -> PyResult<()> {
        let plan = &self.inner;
        let (offsets, vertices) = run(py, || {
            plan.complete_output()?;
            Ok((plan.output_face_offsets(), plan.output_face_vertices()))
        })?;
        let extra = FaceVarying {
            uvs,
            normals,
            uv_indices: uv_indices.as_ref(),
        };
        write_mesh(py, &path, points, offsets, vertices, extra)
    }
}

/// What `evaluate` computes: per-vertex values, or face-varying values in a mode.
#[derive(Clone, Copy)]
enum Evaluation<'a> {
    Vertex,
    FaceVarying {
        mode: FaceVaryingMode,
        limit: bool,
        indices: Option<&'a [u32]>,
    },
}

fn evaluate<'py, T: Scalar + Element>(
    py: Python<'py>,
    plan: &Plan,
    values: &PyReadonlyArray2<'_, T>,
    how: Evaluation<'_>,
) -> PyResult<Bound<'py, PyArray2<T>>> {
    let channels = values.shape()[1];
    let data = contiguous(values, "values")?;
    let out = run(py, || {
        if channels == 0 {
            return Err(invalid("values need at least one channel"));
        }
        let out = match how {
            Evaluation::FaceVarying {
                mode,
                limit,
                indices: None,
            } => plan.evaluate_face_varying(data, channels, mode, limit)?,
            Evaluation::FaceVarying {
                mode,
                limit,
                indices: Some(indices),
            } => plan.evaluate_face_varying_indexed(data, channels, indices, mode, limit)?,
            Evaluation::Vertex => plan.evaluate(data, channels)?,
        };
        check_output(&out, channels, data)?;
        Ok(out)
    })?;
    array2(py, out, channels)
}

/// The arguments of a face-varying evaluation, checked.
fn face_varying<'a>(
    py: Python<'_>,
    mode: &str,
    limit: bool,
    indices: &'a Option<PyReadonlyArray1<'_, u32>>,
) -> PyResult<Evaluation<'a>> {
    let mode = parse_face_varying_mode(mode).map_err(|e| to_py_err(py, e))?;
    let indices = (indices.as_ref())
        .map(|a| a.as_slice())
        .transpose()
        .map_err(|_| to_py_err(py, invalid("indices must be a contiguous uint32 array")))?;
    Ok(Evaluation::FaceVarying {
        mode,
        limit,
        indices,
    })
}

/// [`evaluate`] of face-varying values in the indexed form (`how` is a face-varying
/// evaluation).
fn evaluate_shared<'py, T: Scalar + Element>(
    py: Python<'py>,
    plan: &Plan,
    values: &PyReadonlyArray2<'_, T>,
    how: Evaluation<'_>,
) -> PyResult<SharedArrays<'py>> {
    let Evaluation::FaceVarying {
        mode,
        limit,
        indices,
    } = how
    else {
        return Err(to_py_err(
            py,
            invalid("per-vertex values have no indexed form"),
        ));
    };
    let channels = values.shape()[1];
    let data = contiguous(values, "values")?;
    let out = run(py, || {
        if channels == 0 {
            return Err(invalid("values need at least one channel"));
        }
        let out = plan.evaluate_face_varying_shared(data, channels, indices, mode, limit)?;
        check_output(&out.values, channels, data)?;
        Ok(out)
    })?;
    Ok((array2(py, out.values, channels)?.into_any(), out.indices))
}

fn evaluate_fresh<'py, T: Scalar + Element>(
    py: Python<'py>,
    cage: &PyCage,
    points: &PyReadonlyArray2<'_, T>,
    options: Options,
    evaluate: bool,
) -> PyResult<(PyPlan, Option<Bound<'py, PyAny>>)> {
    let channels = points.shape()[1];
    let data = contiguous(points, "points")?;
    let (plan, out) = cage.run(py, |cage| {
        if channels == 0 {
            return Err(invalid("points need at least one channel"));
        }
        if evaluate {
            let (plan, out) = bidegree::subdivide(cage, data, channels, &options)?;
            check_output(&out, channels, data)?;
            return Ok((plan, Some(out)));
        }
        bidegree::validate_geometry(cage, data, channels)?;
        Ok((Plan::new(cage, &options)?, None))
    })?;
    let out = match out {
        Some(out) => Some(array2(py, out, channels)?.into_any()),
        None => None,
    };
    Ok((PyPlan::wrap(plan), out))
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
    let cage = cage.get();
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
    let estimate = cage.get().run(py, |cage| {
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
