//! The one place where core errors become Python exceptions.
//!
//! Hierarchy (created at import, re-exported by `gmsfric.errors`):
//! `GmsfricError(Exception)`; `InvalidInputError(GmsfricError, ValueError)` for bad arguments;
//! `SimulationError(GmsfricError, RuntimeError)` for runs that produce non-finite values;
//! `ResourceError(GmsfricError, MemoryError)` for work that cannot fit in memory. An interrupted
//! run (Ctrl-C) is a `KeyboardInterrupt`.

use gms_core::CoreError;
use pyo3::exceptions::{PyException, PyKeyboardInterrupt, PyMemoryError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple, PyType};

pyo3::create_exception!(_gmsfric, GmsfricError, PyException, "Base class of every gmsfric error.");

static INVALID_INPUT: PyOnceLock<Py<PyType>> = PyOnceLock::new();
static SIMULATION: PyOnceLock<Py<PyType>> = PyOnceLock::new();
static RESOURCE: PyOnceLock<Py<PyType>> = PyOnceLock::new();

fn subclass(py: Python<'_>, name: &str, second_base: Bound<'_, PyType>, doc: &str) -> PyResult<Py<PyType>> {
    let bases = PyTuple::new(py, [py.get_type::<GmsfricError>(), second_base])?;
    let ns = PyDict::new(py);
    ns.set_item("__doc__", doc)?;
    ns.set_item("__module__", "gmsfric.errors")?;
    let ty = py.get_type::<PyType>().call1((name, bases, ns))?;
    Ok(ty.cast_into::<PyType>()?.unbind())
}

/// Create the exception classes and add them to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("GmsfricError", py.get_type::<GmsfricError>())?;
    let invalid = INVALID_INPUT.get_or_try_init(py, || {
        subclass(py, "InvalidInputError", py.get_type::<PyValueError>(), "An argument is invalid: wrong shape, non-finite, out of range. Names the argument.")
    })?;
    m.add("InvalidInputError", invalid.bind(py))?;
    let sim = SIMULATION.get_or_try_init(py, || {
        subclass(py, "SimulationError", py.get_type::<PyRuntimeError>(), "A simulation could not be completed (it diverged).")
    })?;
    m.add("SimulationError", sim.bind(py))?;
    let res = RESOURCE.get_or_try_init(py, || {
        subclass(py, "ResourceError", py.get_type::<PyMemoryError>(), "The work would need more memory than is available (the message gives the size asked for).")
    })?;
    m.add("ResourceError", res.bind(py))?;
    Ok(())
}

/// Convert a core error into the matching Python exception. Exhaustive on purpose: a new core
/// variant must be mapped here before the binding compiles.
pub fn to_pyerr(err: CoreError) -> PyErr {
    let msg = err.to_string();
    Python::attach(|py| {
        let lock = match err {
            CoreError::Empty { .. }
            | CoreError::LengthMismatch { .. }
            | CoreError::NonFinite { .. }
            | CoreError::NotPositive { .. }
            | CoreError::Negative { .. }
            | CoreError::NotIncreasing { .. }
            | CoreError::InvalidParameter { .. } => &INVALID_INPUT,
            CoreError::NonFiniteOutput { .. } => &SIMULATION,
            CoreError::TooLarge { .. } => &RESOURCE,
            CoreError::Interrupted => return PyKeyboardInterrupt::new_err(msg),
        };
        match lock.get(py) {
            Some(ty) => PyErr::from_type(ty.bind(py).clone(), msg),
            None => PyValueError::new_err(msg),
        }
    })
}

/// A failed run of a batch -> the Python exception of its error, the message prefixed by the run
/// index when there is more than one run.
pub fn batch_err(py: Python<'_>, e: gms_core::batch::BatchError, n_runs: usize) -> PyErr {
    let base = to_pyerr(e.error);
    if n_runs <= 1 {
        return base;
    }
    let msg = format!("run {} (of {n_runs}) failed: {}", e.run, base.value(py));
    PyErr::from_type(base.get_type(py), msg)
}

/// `result.py()?` converts a core result at the call site.
pub trait IntoPy<T> {
    fn py(self) -> PyResult<T>;
}

impl<T> IntoPy<T> for gms_core::Result<T> {
    fn py(self) -> PyResult<T> {
        self.map_err(to_pyerr)
    }
}
