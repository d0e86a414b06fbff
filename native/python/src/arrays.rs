//! numpy arrays in and out: C-contiguous views of the caller's arrays (no copy), float arrays
//! of either precision, and core vectors handed to numpy without a copy.

use bidegree::{Error, Scalar};
use numpy::ndarray::Dimension;
use numpy::{
    Element, PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray, PyReadonlyArray2,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use rayon::prelude::*;

use crate::errors::{invalid, to_py_err};

/// The data of a C-contiguous array. `as_slice` alone would also accept, and misread, Fortran
/// order; the Python layer always passes C-contiguous arrays, so this is a guard.
pub(crate) fn contiguous<'a, T: Element, D: Dimension>(
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
pub(crate) enum Floats<'py> {
    F32(PyReadonlyArray2<'py, f32>),
    F64(PyReadonlyArray2<'py, f64>),
}

pub(crate) fn floats<'py>(values: &Bound<'py, PyAny>, what: &str) -> PyResult<Floats<'py>> {
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
pub(crate) fn array2<'py, T: Element>(
    py: Python<'py>,
    data: Vec<T>,
    channels: usize,
) -> PyResult<Bound<'py, PyArray2<T>>> {
    let rows = data.len().checked_div(channels).unwrap_or(0);
    PyArray1::from_vec(py, data).reshape([rows, channels])
}

/// `u32` indices as `int32` (what numpy and Blender index with).
pub(crate) fn to_i32(values: &[u32]) -> bidegree::Result<Vec<i32>> {
    let mut out = bidegree::memory::with_capacity(values.len())?;
    for &v in values {
        out.push(
            i32::try_from(v).map_err(|_| Error::Internal(format!("index {v} exceeds int32")))?,
        );
    }
    Ok(out)
}

/// Refuses core output with a NaN or infinite value that finite input did not cause: the
/// computation overflowed its floating-point type (float32 beyond about 3.4e38), and the
/// result would silently hold `inf`. NaN in gives NaN out (a plan does not validate the values
/// it is given), so non-finite output from non-finite `input` passes. One parallel scan of the
/// output; the input is scanned only when the output has such a value.
pub(crate) fn check_output<T: Scalar>(
    output: &[T],
    channels: usize,
    input: &[T],
) -> bidegree::Result<()> {
    if output.par_iter().all(|x| x.is_finite()) || input.par_iter().any(|x| !x.is_finite()) {
        return Ok(());
    }
    let first = output
        .par_iter()
        .position_first(|x| !x.is_finite())
        .unwrap_or(0);
    Err(Error::NonFiniteOutput {
        vertex: first / channels.max(1),
        scalar: if std::mem::size_of::<T>() == 4 {
            "float32"
        } else {
            "float64"
        },
    })
}
