//! A volume's host data and geometry for Python (issue 32 item 3): `np.asarray(vol)`, the
//! affine, the spacing, a NIfTI-like header, and NIfTI export of the volume or of any map on
//! its grid with its affine.
//!
//! Decisions:
//! - Values are physical (after the file's scaling), as nibabel's `dataobj` gives them: the
//!   stored dtype when the scaling is the identity, float32 otherwise.
//! - Arrays are (i, j, k), Fortran-ordered (x fastest), as nibabel's, so `vol.affine` maps their
//!   indices to RAS+ mm.
//! - `to_nifti` writes with the library's NIfTI-1 writer (`volume::nifti`): the sform is the
//!   volume's affine, a map keeps its own dtype (uint8, int8, uint16, int16 or float32; other
//!   dtypes become float32), and an existing file is replaced only with `force`; the input file
//!   is never replaced (`files::write::check_output`).

use crate::errors;
use crate::volume::Volume;
use morphray::files::write::{OutputKind, check_output};
use morphray::volume::{LinearMap, SampleKind, Samples, Volume as HostVolume};
use numpy::ndarray::{Array3, ShapeBuilder};
use numpy::{IntoPyArray, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use std::path::{Path, PathBuf};

/// (i, j, k) Fortran-ordered array of `values` (x fastest) on `dims`.
fn fortran<'py, T: numpy::Element>(
    py: Python<'py>,
    dims: [usize; 3],
    values: Vec<T>,
) -> PyResult<Bound<'py, PyAny>> {
    let array = Array3::from_shape_vec((dims[0], dims[1], dims[2]).f(), values)
        .map_err(|e| errors::Error::new_err(e.to_string()))?;
    Ok(array.into_pyarray(py).into_any())
}

/// Decodes little-endian samples of `N` bytes.
fn decode<const N: usize, T>(bytes: &[u8], from: fn([u8; N]) -> T) -> Vec<T> {
    bytes
        .chunks_exact(N)
        .map(|c| {
            let mut b = [0u8; N];
            b.copy_from_slice(c);
            from(b)
        })
        .collect()
}

/// The volume's physical values as an (i, j, k) array (module doc).
#[pyfunction]
pub fn volume_data<'py>(py: Python<'py>, volume: &Volume) -> PyResult<Bound<'py, PyAny>> {
    volume.with_host(|host| {
        let dims = host.dims;
        let samples = &host.samples;
        if host.to_physical != LinearMap::IDENTITY {
            let map = host.to_physical;
            let values = (0..samples.len())
                .map(|i| (map.slope * samples.get(i) + map.intercept) as f32)
                .collect();
            return fortran(py, dims, values);
        }
        let bytes = samples.as_bytes();
        match samples.kind() {
            SampleKind::U8 => fortran(py, dims, bytes.to_vec()),
            SampleKind::I8 => fortran(py, dims, decode(bytes, i8::from_le_bytes)),
            SampleKind::U16 => fortran(py, dims, decode(bytes, u16::from_le_bytes)),
            SampleKind::I16 => fortran(py, dims, decode(bytes, i16::from_le_bytes)),
            SampleKind::F32 => fortran(py, dims, decode(bytes, f32::from_le_bytes)),
        }
    })
}

/// The numpy dtype name of a sample kind.
fn numpy_name(kind: SampleKind) -> &'static str {
    match kind {
        SampleKind::U8 => "uint8",
        SampleKind::I8 => "int8",
        SampleKind::U16 => "uint16",
        SampleKind::I16 => "int16",
        SampleKind::F32 => "float32",
    }
}

/// The header as JSON text: dims, spacing (pixdim), the stored dtype and scaling, the affine
/// and which field it came from, the voxel unit, and what the file says about the scan.
#[pyfunction]
pub fn volume_header(volume: &Volume) -> PyResult<String> {
    volume.with_host(|host| {
        let header = serde_json::json!({
            "dim": host.dims,
            "pixdim": host.spacing_mm,
            "datatype": numpy_name(host.samples.kind()),
            "scl_slope": host.to_physical.slope,
            "scl_inter": host.to_physical.intercept,
            "affine": host.orientation.affine,
            "affine_source": host.orientation.source,
            "xyz_units": "mm",
            "descrip": host.name,
            "facts": host.facts,
        });
        Ok(header.to_string())
    })
}

/// Samples of a numpy map in a NIfTI-writable dtype (others as float32), x fastest.
fn map_samples(array: &Bound<'_, PyAny>) -> PyResult<(Samples, [usize; 3])> {
    macro_rules! take {
        ($t:ty, $make:expr) => {
            if let Ok(a) = array.extract::<PyReadonlyArray3<'_, $t>>() {
                let shape = a.shape();
                let dims = [shape[0], shape[1], shape[2]];
                let values: Vec<$t> = a.as_array().t().iter().copied().collect();
                return Ok(($make(values), dims));
            }
        };
    }
    take!(u8, Samples::from_u8);
    take!(i8, |v: Vec<i8>| Samples::from_i8(&v));
    take!(u16, |v: Vec<u16>| Samples::from_u16(&v));
    take!(i16, |v: Vec<i16>| Samples::from_i16(&v));
    take!(f32, |v: Vec<f32>| Samples::from_f32(&v));
    Err(errors::usage(
        "data must be a 3-D numpy array of uint8, int8, uint16, int16 or float32 (the Python \
         side converts other dtypes to float32)",
    ))
}

/// Writes the volume, or `data` (an (i, j, k) array of the volume's shape) with the volume's
/// affine, as NIfTI-1 (`.nii` or `.nii.gz`); an existing file only with `force`.
#[pyfunction]
#[pyo3(signature = (volume, path, data=None, force=false))]
pub fn to_nifti(
    py: Python<'_>,
    volume: &Volume,
    path: PathBuf,
    data: Option<&Bound<'_, PyAny>>,
    force: bool,
) -> PyResult<()> {
    let map = data.map(map_samples).transpose()?;
    py.detach(|| {
        volume.with_host(|host| {
            let inputs: Vec<&Path> = volume.input_path().into_iter().collect();
            check_output(&path, OutputKind::Nifti, &inputs, force)
                .map_err(|e| errors::usage(e.to_string()))?;
            let written = match map {
                None => write(host, &path, force),
                Some((samples, dims)) => {
                    if dims != host.dims {
                        return Err(errors::usage(format!(
                            "data of shape {dims:?} is not on the volume's grid {:?}",
                            host.dims
                        )));
                    }
                    let map = HostVolume::from_voxels(
                        &host.name,
                        dims,
                        samples,
                        host.orientation.affine,
                        LinearMap::IDENTITY,
                    )
                    .map_err(|e| errors::usage(e.to_string()))?;
                    write(&map, &path, force)
                }
            };
            written.map_err(|e| errors::Error::new_err(e.to_string()))
        })
    })
}

fn write(
    volume: &HostVolume,
    path: &Path,
    force: bool,
) -> Result<(), morphray::volume::nifti::NiftiError> {
    let gzip = path.to_string_lossy().to_ascii_lowercase().ends_with(".gz");
    if force {
        morphray::volume::nifti::write_nifti1(volume, path, gzip)
    } else {
        morphray::volume::nifti::write_new_nifti1(volume, path, gzip)
    }
}
