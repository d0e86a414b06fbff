//! `bidegree._native.analyze` / `basis_function`: the paper's §4 analysis in the core
//! (`bidegree::analysis`: subdivision matrices, Fourier blocks, C1 report) as numpy arrays.

use bidegree::{Error, MAX_DEGREE};
use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::array2;
use crate::errors::{invalid, run, to_py_err};

/// Registers the analysis functions in the extension module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(analyze, m)?)?;
    m.add_function(wrap_pyfunction!(basis_function, m)?)
}

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
        // Cells between grid points; `reshape` refuses a table of another size.
        let cells_shape = [rows.saturating_sub(1), columns.saturating_sub(1)];
        let cells: Vec<f64> = map.cell_jacobian.iter().flatten().copied().collect();
        dict.set_item(
            "map_cell_jacobian",
            shaped(py, cells, &[cells_shape[0], cells_shape[1], 2])?,
        )?;
        let ring: Vec<bool> = map.in_ring.clone();
        dict.set_item(
            "map_in_ring",
            PyArray1::from_vec(py, ring).reshape(cells_shape)?,
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
    // The core refines the one impulse: one channel.
    let Some(channel) = net.values.first() else {
        return Err(to_py_err(
            py,
            Error::Internal("basis_function must return the impulse's channel".into()),
        ));
    };
    let dict = PyDict::new(py);
    let (k, rows, columns) = (channel.len(), net.rows, net.columns);
    let params: Vec<f64> = net.params.iter().flatten().copied().collect();
    dict.set_item("params", shaped(py, params, &[rows, columns, 2])?)?;
    let values: Vec<f64> = channel.iter().flatten().copied().collect();
    dict.set_item("values", shaped(py, values, &[k, rows, columns])?)?;
    dict.set_item("spacing", net.spacing)?;
    dict.set_item("primal", degree % 2 == 1)?;
    Ok(dict)
}
