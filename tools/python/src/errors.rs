//! The exception hierarchy and the mapping from the library's typed errors.
//!
//! `morphray.Error` is the base of everything the engine raises; `InputError` (a file that
//! cannot be read or an array that is not a volume), `DeviceError` (Vulkan: no device, device
//! lost, out of device memory) and `MemoryBudgetError` (no plan fits the memory budget) derive
//! from it. Bad arguments (an unknown tissue, a zoom of 0) are `ValueError`, as Python code
//! expects. The message is the library's one-line message, which names the file and says what
//! to do.

use morphray::engine::OpenError;
use morphray::gpu::GpuError;
use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;

pyo3::create_exception!(morphray, Error, PyException, "Base of morphray's errors.");
pyo3::create_exception!(
    morphray,
    InputError,
    Error,
    "The input cannot be read as a volume."
);
pyo3::create_exception!(
    morphray,
    DeviceError,
    Error,
    "Vulkan device error (none found, lost, out of memory)."
);
pyo3::create_exception!(
    morphray,
    MemoryBudgetError,
    Error,
    "No plan of the scene fits the memory budget."
);

/// Adds the exception types to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("Error", py.get_type::<Error>())?;
    m.add("InputError", py.get_type::<InputError>())?;
    m.add("DeviceError", py.get_type::<DeviceError>())?;
    m.add("MemoryBudgetError", py.get_type::<MemoryBudgetError>())?;
    Ok(())
}

/// A Vulkan error.
pub fn gpu(e: GpuError) -> PyErr {
    DeviceError::new_err(e.to_string())
}

/// An error of opening a volume on an engine.
pub fn open(e: OpenError) -> PyErr {
    match e {
        OpenError::Gpu(e) => gpu(e),
        e @ OpenError::DoesNotFit(_) => MemoryBudgetError::new_err(e.to_string()),
    }
}

/// A usage error (bad argument).
pub fn usage(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}
