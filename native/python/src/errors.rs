//! Core errors as Python exceptions, and the panic boundary.
//!
//! Every call into the core goes through [`run`] (GIL released) or [`guard`] (cheap accessors):
//! both catch panics, so a panic becomes `bidegree.InternalError` and never a crash or a
//! `PanicException`. [`to_py_err`] turns each [`bidegree::Error`] variant into its class of
//! `bidegree/_errors.py`, with the variant's details as attributes.

use std::panic::{catch_unwind, AssertUnwindSafe};

use bidegree::Error;
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::types::PyType;

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
pub(crate) fn to_py_err(py: Python<'_>, error: Error) -> PyErr {
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

pub(crate) fn invalid(message: impl Into<String>) -> Error {
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
pub(crate) fn run<T, F>(py: Python<'_>, work: F) -> PyResult<T>
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
pub(crate) fn guard<T>(py: Python<'_>, access: impl FnOnce() -> T) -> PyResult<T> {
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

/// Makes a panic in the core on purpose (tests check that it arrives as `InternalError`).
#[pyfunction]
fn _panic_for_tests(py: Python<'_>) -> PyResult<()> {
    run(py, || -> bidegree::Result<()> {
        panic!("deliberate panic for tests")
    })
}

/// Registers the test hook of the panic boundary in the extension module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(_panic_for_tests, m)?)
}
