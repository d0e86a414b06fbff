//! Core errors as Python exceptions, and the panic boundary.
//!
//! Every call into the core goes through [`run`] / [`detached`] (GIL released) or [`guard`]
//! (cheap accessors): they catch panics, so a panic becomes `bidegree.InternalError` and never
//! a crash or a `PanicException`. The panic hook installed with the module keeps the panic's
//! text off stderr (the user sees the typed error alone); the text and location are kept as the
//! exception's `detail` attribute, for bug reports (with `BIDEGREE_DEBUG` set in the
//! environment the hook also prints them, with a backtrace when `RUST_BACKTRACE` asks).
//! [`to_py_err`] turns each [`bidegree::Error`] variant into its class of
//! `bidegree/_errors.py`, with the variant's details as attributes.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Mutex;

use bidegree::io::Interrupt;
use bidegree::Error;
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::types::PyType;

/// What users read when the core panicked (the panic's own text goes to `detail`).
const INTERNAL_MESSAGE: &str = "a bug in bidegree stopped this request (please report it with \
                                the input; BIDEGREE_DEBUG=1 shows where)";

/// Python class name (in `bidegree._errors`) of each error variant, and the integer details that
/// are attached to the exception as attributes.
fn error_class(error: &Error) -> (&'static str, Vec<(&'static str, i64)>) {
    let n = |x: usize| x as i64;
    match error {
        Error::EmptyMesh(_) => ("EmptyMeshError", vec![]),
        Error::FaceTooSmall { face, size } => (
            "FaceTooSmallError",
            vec![("face", n(*face)), ("size", *size)],
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
        Error::LevelOutOfRange { levels, min, max } => (
            "LevelOutOfRangeError",
            vec![
                ("levels", *levels),
                ("min", i64::from(*min)),
                ("max", i64::from(*max)),
            ],
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
        // The same class as a refused estimate: `budget` is the memory the process can have.
        Error::OutOfMemory {
            required,
            available,
        } => (
            "MemoryBudgetError",
            vec![
                ("required", i64::try_from(*required).unwrap_or(i64::MAX)),
                ("budget", i64::try_from(*available).unwrap_or(i64::MAX)),
            ],
        ),
        Error::InvalidInput(_) => ("InvalidInputError", vec![]),
        Error::Io(_) => ("BidegreeIOError", vec![]),
        Error::Internal(_) => ("InternalError", vec![]),
        Error::NonFiniteOutput { vertex, .. } => ("NonFiniteError", vec![("vertex", n(*vertex))]),
        // Only when a signal handler's exception was lost; nothing was written.
        Error::Interrupted(_) => ("BidegreeIOError", vec![]),
        // The refusal's own class (MemoryBudgetError); `level` when it stopped at a level.
        Error::AdaptiveStopped { stage, error } => {
            let (class, mut details) = error_class(error);
            if let bidegree::AdaptiveStage::Level(level) = stage {
                details.push(("level", i64::from(*level)));
            }
            (class, details)
        }
        Error::InFile { error, line, .. } => {
            let (class, mut details) = error_class(error);
            if let Some(line) = line {
                details.push(("line", n(*line)));
            }
            (class, details)
        }
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
            if let Error::IndexOutOfRange { what, .. } = error.kind() {
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

/// Text and location of the last panic, recorded by the hook (on whichever thread panicked:
/// rayon hands the payload to the caller, the hook ran on the worker).
static LAST_PANIC: Mutex<Option<String>> = Mutex::new(None);

/// Installs the panic hook of the extension (this library's own: every Rust library in a
/// process has its own standard library and hook).
fn install_panic_hook() {
    let default = std::panic::take_hook();
    let debug = std::env::var_os("BIDEGREE_DEBUG").is_some_and(|v| !v.is_empty() && v != "0");
    std::panic::set_hook(Box::new(move |info| {
        let location = info.location().map_or(String::new(), |l| {
            format!(" at {}:{}:{}", l.file(), l.line(), l.column())
        });
        let detail = format!("panicked{location}: {}", panic_message(info.payload()));
        if let Ok(mut last) = LAST_PANIC.lock() {
            *last = Some(detail);
        }
        if debug {
            default(info);
        }
    }));
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

/// How core work failed: a typed error, or a panic (with its text and location).
pub(crate) enum Failure {
    Error(Error),
    Panic(String),
}

impl From<Error> for Failure {
    fn from(error: Error) -> Self {
        Failure::Error(error)
    }
}

impl Failure {
    /// The Python exception: the error's class, or `InternalError` with the panic as `detail`.
    pub(crate) fn into_py(self, py: Python<'_>) -> PyErr {
        match self {
            Failure::Error(error) => to_py_err(py, error),
            Failure::Panic(detail) => {
                let err = to_py_err(py, Error::Internal(INTERNAL_MESSAGE.into()));
                let _ = err.value(py).setattr("detail", detail);
                err
            }
        }
    }
}

/// `work` with panics caught.
fn catch<T>(work: impl FnOnce() -> T) -> Result<T, Failure> {
    catch_unwind(AssertUnwindSafe(work)).map_err(|payload| {
        let recorded = LAST_PANIC.lock().ok().and_then(|mut last| last.take());
        Failure::Panic(recorded.unwrap_or_else(|| panic_message(payload.as_ref())))
    })
}

/// Runs core work with the GIL released and panics caught, keeping the core's error (for a
/// caller that restates it, as a cage from a file does).
pub(crate) fn detached<T, F>(py: Python<'_>, work: F) -> Result<T, Failure>
where
    F: FnOnce() -> bidegree::Result<T> + Send,
    T: Send,
{
    py.detach(move || catch(work)?.map_err(Failure::Error))
}

/// Runs core work with the GIL released and panics caught: every call into the core goes
/// through here (or [`detached`]).
pub(crate) fn run<T, F>(py: Python<'_>, work: F) -> PyResult<T>
where
    F: FnOnce() -> bidegree::Result<T> + Send,
    T: Send,
{
    detached(py, work).map_err(|failure| failure.into_py(py))
}

/// Runs core work that reads or writes a file: `work` gets an [`Interrupt`] that runs Python's
/// signal handlers between chunks (taking the GIL for that moment). When a handler raises
/// (Ctrl-C's `KeyboardInterrupt`, the CLI's SIGTERM handler), the core stops, removes what it
/// had written, and that exception is raised here.
pub(crate) fn run_interruptible<T, F>(py: Python<'_>, work: F) -> PyResult<T>
where
    F: FnOnce(Interrupt<'_>) -> bidegree::Result<T> + Send,
    T: Send,
{
    let raised: Mutex<Option<PyErr>> = Mutex::new(None);
    let interrupt = || {
        Python::attach(|py| py.check_signals()).map_err(|err| {
            if let Ok(mut slot) = raised.lock() {
                *slot = Some(err);
            }
            Error::Interrupted("a signal handler stopped the work".into())
        })
    };
    let outcome = run(py, || work(&interrupt));
    match raised.into_inner().ok().flatten() {
        Some(err) => Err(err),
        None => outcome,
    }
}

/// Runs a cheap core accessor (no GIL release) with panics caught, so that not even a getter
/// can let a panic reach Python.
pub(crate) fn guard<T>(py: Python<'_>, access: impl FnOnce() -> T) -> PyResult<T> {
    catch(access).map_err(|failure| failure.into_py(py))
}

/// Makes a panic in the core on purpose (tests check that it arrives as `InternalError`);
/// `in_worker`: on a rayon worker thread, as a panic in the core's parallel passes would be.
#[pyfunction]
#[pyo3(signature = (in_worker=false))]
fn _panic_for_tests(py: Python<'_>, in_worker: bool) -> PyResult<()> {
    use rayon::prelude::*;
    run(py, move || -> bidegree::Result<()> {
        if in_worker {
            (0..64u32).into_par_iter().for_each(|i| {
                if i == 37 {
                    panic!("deliberate panic for tests on a worker");
                }
            });
        }
        panic!("deliberate panic for tests")
    })
}

/// Installs the panic hook and registers the test hook of the panic boundary in the extension
/// module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    install_panic_hook();
    m.add_function(wrap_pyfunction!(_panic_for_tests, m)?)
}
