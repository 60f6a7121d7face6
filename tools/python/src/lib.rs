//! `morphray._native`: the Rust half of the `morphray` Python package (the Python half,
//! `morphray/__init__.py`, turns paths, nibabel images and (array, affine) pairs into these
//! calls and adds `_repr_png_`).
//!
//! Decisions:
//! - Thin: everything that is not Python glue lives in the morphray library (the open path, the
//!   scene recipe, the scan summary that `peaks()` returns); this crate maps arguments and errors.
//! - One device per process ([`state`]): every volume is opened and rendered by one engine behind
//!   a mutex, so notebooks that open hundreds of volumes start Vulkan once.
//! - The GIL is released (`Python::detach`) around every call that reads files or touches the
//!   GPU, so other Python threads run meanwhile.
//! - Errors are Python exceptions of a small hierarchy ([`errors`]) whose message is the
//!   library's one-line message.

mod errors;
mod layers;
mod recipe;
mod state;
mod volume;
mod volume_io;

use pyo3::prelude::*;

/// The native module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::register(m)?;
    m.add_class::<volume::Volume>()?;
    m.add_function(wrap_pyfunction!(state::configure, m)?)?;
    m.add_function(wrap_pyfunction!(state::device_name, m)?)?;
    m.add_function(wrap_pyfunction!(volume::open_file, m)?)?;
    m.add_function(wrap_pyfunction!(volume::open_phantom, m)?)?;
    m.add_function(wrap_pyfunction!(volume::open_array, m)?)?;
    m.add_function(wrap_pyfunction!(volume_io::volume_data, m)?)?;
    m.add_function(wrap_pyfunction!(volume_io::volume_header, m)?)?;
    m.add_function(wrap_pyfunction!(volume_io::to_nifti, m)?)?;
    m.add_function(wrap_pyfunction!(recipe::scene_options, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
