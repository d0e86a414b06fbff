//! `bidegree._native`: the thin pyo3 layer between the Python package `bidegree` and the Rust
//! core. It owns argument conversion (numpy arrays in and out, without copies where possible),
//! releasing the GIL around every call into the core, catching panics (they become
//! `bidegree.InternalError`, never a crash or a `PanicException`) and turning each
//! [`bidegree::Error`] variant into its Python exception class (defined in
//! `bidegree/_errors.py`). Behaviour lives in the core; argument checks with friendly messages
//! live in the Python layer (`bidegree/__init__.py`), which always hands over C-contiguous arrays
//! of the expected dtypes. This layer checks again and refuses anything else.
//!
//! Modules, bottom up: [`errors`] (error classes, the panic boundary) and [`arrays`] (numpy
//! conversion) and [`options`] (option values) are shared; [`cage`], [`plan`], [`obj`],
//! [`adaptive`] and [`analysis`] each bind one part of the core and register its Python names.

mod adaptive;
mod analysis;
mod arrays;
mod cage;
mod errors;
mod obj;
mod options;
mod plan;

use bidegree::memory::{default_memory_budget, machine_memory, ADDRESS_SPACE_HEADROOM};
use bidegree::{INFINITELY_SHARP, MAX_DEGREE, MAX_LEVELS};
use pyo3::prelude::*;

/// The extension's Rust allocations (the core's levels, working buffers and the arrays handed
/// to numpy) go through mimalloc, not the C library's `malloc`: with glibc the next call on the
/// same plan faulted the pages of the last one's large arrays in again (page faults a call, 4k
/// ico cage at level 3: 136 a cached degree-4 evaluation, 1,147 a cached degree-6 limit; 0 or 1
/// with mimalloc), which glibc had given back to the system when they were freed (under
/// `strace`, in one case: a rayon worker's arena heap mapped and unmapped every call); mimalloc
/// keeps freed pages for a second before purging them, longer than a frame.
/// Transparent huge pages stay as mimalloc has them (allowed): on a VM that reports free pages
/// to its host their first touch is bimodal by process, and `MIMALLOC_ALLOW_THP=0` turns them
/// off for the whole process (README, measured there).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// The extension module `bidegree._native`.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("MAX_DEGREE", MAX_DEGREE)?;
    m.add("MAX_LEVELS", MAX_LEVELS)?;
    m.add("DEFAULT_MEMORY_BUDGET", default_memory_budget())?;
    m.add("MACHINE_MEMORY", machine_memory())?;
    m.add("ADDRESS_SPACE_HEADROOM", ADDRESS_SPACE_HEADROOM)?;
    m.add("INFINITELY_SHARP", INFINITELY_SHARP)?;
    errors::register(m)?;
    cage::register(m)?;
    plan::register(m)?;
    obj::register(m)?;
    adaptive::register(m)?;
    analysis::register(m)
}
