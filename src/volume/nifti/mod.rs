//! NIfTI-1, NIfTI-2 and ANALYZE 7.5 reader (and a small NIfTI-1 writer), to the loader
//! contract that `tests/nifti_loader.rs` checks point by point: every odd file gets a
//! documented outcome, nothing a user feeds it can panic.
//!
//! Decisions:
//! - Three phases the engine can time and schedule separately: [`read_file`] (I/O, regular
//!   files only: a FIFO or a device is refused at once), [`inflate_if_gzip`] (CPU, bounded by the
//!   size the header declares), [`parse`] (header, validation, conversion of one frame).
//!   [`load_file_timed`] runs all three the way the command line does, timing each, and handles
//!   `.hdr`/`.img` pairs given by either file; [`load_path`] is the same without timings.
//! - [`parse`] takes the buffer by value, so the voxels of the native kinds are moved to the
//!   front of that same allocation and the volume owns it: the voxel bytes are copied at most
//!   once after inflation (zero times for a pair whose `.img` starts at byte 0).
//! - Validation order: header size/byte order/magic (header.rs), `dim[0]` 1..=7, datatype
//!   (complex and float128 are named errors), dims >= 1 with checked size arithmetic, vox_offset
//!   (finite, whole, >= 0; a single file's offset below 352 (NIfTI-1) or 544 (NIfTI-2) is raised
//!   to that minimum with a warning, as the standard says), then offset + all frames' bytes must
//!   fit in the data (layout.rs). Only then is memory for samples allocated, so no header can
//!   make the loader allocate more than the file could hold; and gzip data is inflated only
//!   after the header it starts with was validated, into at most the size it declares
//!   (bounded.rs), so no file can make the loader inflate more than its header admits.
//! - Dims above `dim[0]` are ignored; missing spatial dims (1-D / 2-D images) are 1; dims 4..7
//!   multiply into frames; one frame is loaded ([`LoadOptions::frame`], default 0) with a
//!   warning when there are several.
//! - ANALYZE 7.5: pixdim orientation, no scaling (`funused1`, SPM's scale factor, is reported but
//!   not applied, with a warning when it is not 0 or 1).
//! - Every repair is a sentence in `Volume::warnings`; [`HeaderSummary`] reports the fields as
//!   read (JSON via serde), so a user can see both what the file says and what was shown.

pub mod bounded;
mod convert;
pub mod datatype;
mod error;
pub mod extensions;
mod frame_mean;
pub mod frames;
pub mod gzip;
pub mod gzip_parallel;
pub mod header;
mod layout;
mod load;
pub mod orientation;
mod pack;
mod writer;

pub use bounded::inflate_if_gzip;
pub use datatype::Datatype;
pub use error::NiftiError;
pub use extensions::Extension;
pub use header::{ByteOrder, RawHeader, Storage, Version};
pub use load::{PhaseTimes, load_file_timed, load_path, read_file};
pub use orientation::{OrientationFields, ResolvedGeometry};
pub use writer::{write_new_nifti1, write_nifti1};

use crate::volume::Volume;
use header::Decoded;

/// Choices the caller makes when loading.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LoadOptions {
    /// Which frame of a 4-D (or higher) file to load, from 0.
    pub frame: usize,
    /// Load the mean over all frames instead (a 4-D file only; `frame` is then ignored).
    pub mean: bool,
}

/// A loaded frame and what the header said.
#[derive(Clone, Debug)]
pub struct LoadedNifti {
    /// The frame, ready for the engine (repairs listed in `volume.warnings`).
    pub volume: Volume,
    /// The header fields as read.
    pub header: HeaderSummary,
}

/// Header facts, as read from the file (before repairs), for reports and JSON output.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct HeaderSummary {
    /// NIfTI-1, NIfTI-2 or ANALYZE 7.5.
    pub version: Version,
    /// Single `.nii` or `.hdr`/`.img` pair.
    pub storage: Storage,
    /// Byte order of header and voxels.
    pub byte_order: ByteOrder,
    /// The file's datatype (serialised by name, e.g. `"int16"`).
    pub datatype: Datatype,
    /// `bitpix` as read (may disagree with the datatype; the datatype wins).
    pub bitpix: i16,
    /// `dim[1..=dim[0]]`.
    pub dims: Vec<usize>,
    /// Product of dims 4..=`dim[0]` (1 for a 3-D file).
    pub frames: usize,
    /// Which frame was loaded.
    pub frame_loaded: usize,
    /// The number of frames averaged, when the mean over the frames was loaded instead.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mean_of_frames: Option<usize>,
    /// `vox_offset` as read.
    pub vox_offset: f64,
    /// Byte position the voxels were actually read from (after the minimum-offset rule).
    pub data_offset: usize,
    /// `scl_slope` as read (ANALYZE: `funused1`).
    pub scl_slope: f64,
    /// `scl_inter` as read (ANALYZE: `funused2`).
    pub scl_inter: f64,
    /// `qform_code` (0 for ANALYZE).
    pub qform_code: i32,
    /// `sform_code` (0 for ANALYZE).
    pub sform_code: i32,
    /// `xyzt_units` as read.
    pub xyzt_units: i32,
    /// `descrip`, trimmed, lossy UTF-8.
    pub description: String,
    /// Header extensions (code and size); empty when absent or ignored.
    pub extensions: Vec<Extension>,
    /// True when the file (or either file of a pair) was gzip-compressed.
    pub gzip: bool,
    /// gzip members inflated (summed over both files of a pair); 0 when not compressed.
    pub gzip_members: usize,
}

impl HeaderSummary {
    /// Records how many gzip members the data had (for callers that ran [`inflate_if_gzip`]
    /// themselves before [`parse`]).
    pub fn set_gzip_members(&mut self, members: usize) {
        self.gzip_members = members;
        self.gzip = members > 0;
    }
}

/// Phase 3: decodes a single-file NIfTI (`n+1` / `n+2`) from its (inflated) bytes and converts
/// the selected frame. Bytes that are still gzip-compressed are inflated first, bounded by the
/// size the header declares (and counted in `header.gzip_members`); after a separate
/// [`inflate_if_gzip`], record the member count with [`HeaderSummary::set_gzip_members`].
/// `name` becomes `Volume::name`.
///
/// A header whose voxels live in a separate `.img` (magic `ni1`/`ni2`, or ANALYZE) gives
/// [`NiftiError::SeparateImageFile`]: use [`parse_pair`] or [`load_path`].
pub fn parse(bytes: Vec<u8>, name: &str, opts: &LoadOptions) -> Result<LoadedNifti, NiftiError> {
    let (bytes, members) = inflate_if_gzip(bytes)?;
    let decoded = header::decode(&bytes)?;
    if decoded.storage == Storage::Pair {
        let version = match decoded.version {
            Version::Nifti1 => "NIfTI-1 (ni1)",
            Version::Nifti2 => "NIfTI-2 (ni2)",
            Version::Analyze75 => "ANALYZE 7.5",
        };
        return Err(NiftiError::SeparateImageFile { version });
    }
    build_single(decoded, bytes, name, opts, members)
}

/// Phase 3 for a `.hdr`/`.img` pair: `header` holds the `.hdr` bytes, `image` the `.img` bytes
/// (either may still be gzip-compressed; the image is inflated within the size the header
/// declares for it). `vox_offset` counts from the start of `image`.
pub fn parse_pair(
    header: &[u8],
    image: Vec<u8>,
    name: &str,
    opts: &LoadOptions,
) -> Result<LoadedNifti, NiftiError> {
    let (header, header_members) = inflate_if_gzip(header.to_vec())?;
    let decoded = header::decode(&header)?;
    let (image, image_members) = bounded::inflate_image(image, &decoded)?;
    build_pair(
        decoded,
        &header,
        image,
        name,
        opts,
        header_members + image_members,
    )
}

/// The last step of [`parse`] on a decoded single-file header and its (inflated) bytes.
pub(crate) fn build_single(
    decoded: Decoded,
    bytes: Vec<u8>,
    name: &str,
    opts: &LoadOptions,
    members: usize,
) -> Result<LoadedNifti, NiftiError> {
    let ext_start = decoded.version.header_len() + 4;
    build(
        decoded,
        ExtensionArea::SameFile { start: ext_start },
        bytes,
        name,
        opts,
        members,
    )
}

/// The last step of [`parse_pair`]: a decoded `.hdr` (its inflated bytes in `header`) and the
/// inflated `.img`.
pub(crate) fn build_pair(
    mut decoded: Decoded,
    header: &[u8],
    image: Vec<u8>,
    name: &str,
    opts: &LoadOptions,
    members: usize,
) -> Result<LoadedNifti, NiftiError> {
    if decoded.storage == Storage::SingleFile {
        decoded.warnings.push(format!(
            "the {} header has the single-file magic, but it came with a separate image file; the voxels are read from the image file",
            decoded.version.label()
        ));
    }
    build(
        decoded,
        ExtensionArea::HeaderFile(header),
        image,
        name,
        opts,
        members,
    )
}

/// Where the extension bytes are.
enum ExtensionArea<'a> {
    /// In the data buffer, from `start` up to the voxel offset.
    SameFile { start: usize },
    /// In a separate header buffer, from byte 352/544 to its end.
    HeaderFile(&'a [u8]),
}

/// Shared tail of [`parse`] and [`parse_pair`]: validation, extensions, conversion, geometry.
fn build(
    decoded: Decoded,
    extensions: ExtensionArea,
    data: Vec<u8>,
    name: &str,
    opts: &LoadOptions,
    gzip_members: usize,
) -> Result<LoadedNifti, NiftiError> {
    let h = &decoded.header;
    let mut warnings = decoded.warnings.clone();
    let (datatype, bytes_per_voxel) = layout::datatype_of(&decoded)?;
    let pair = matches!(extensions, ExtensionArea::HeaderFile(_));
    let lay = layout::plan(&decoded, datatype, bytes_per_voxel, pair, &mut warnings)?;
    if lay.end > data.len() {
        return Err(NiftiError::TruncatedData {
            file: if pair { "image file" } else { "file" },
            len: data.len(),
            needed: lay.total,
            offset: lay.offset,
        });
    }

    if opts.frame >= lay.frames {
        return Err(NiftiError::FrameOutOfRange {
            frame: opts.frame,
            frames: lay.frames,
        });
    }
    let mean = opts.mean && lay.frames > 1;
    if lay.frames > 1 && !mean {
        warnings.push(format!(
            "{}-D file with {} frames: showing frame {}",
            lay.dims.len(),
            lay.frames,
            opts.frame
        ));
    }

    let header_len = decoded.version.header_len();
    let ext_list = if h.extender[0] != 0 {
        let region = match extensions {
            ExtensionArea::SameFile { start } => data.get(start..lay.offset).unwrap_or_default(),
            ExtensionArea::HeaderFile(hdr) => hdr.get(header_len + 4..).unwrap_or_default(),
        };
        let (list, warning) = extensions::parse(region, decoded.byte_order);
        warnings.extend(warning);
        list
    } else {
        Vec::new()
    };

    let (slope, inter) = if decoded.version == Version::Analyze75 {
        if h.scl_slope.is_finite() && h.scl_slope != 0.0 && h.scl_slope != 1.0 {
            warnings.push(format!(
                "ANALYZE field funused1 is {} (SPM's scale factor); it is not applied",
                h.scl_slope
            ));
        }
        (0.0, 0.0)
    } else {
        (h.scl_slope, h.scl_inter)
    };

    let geometry = orientation::resolve(&OrientationFields {
        qform_code: h.qform_code,
        sform_code: h.sform_code,
        quatern: h.quatern,
        qoffset: h.qoffset,
        pixdim: spatial_pixdim(h, lay.dims.len()),
        srow: h.srow,
        xyzt_units: h.xyzt_units,
    });
    warnings.extend(geometry.warnings);

    let summary = HeaderSummary {
        version: decoded.version,
        storage: decoded.storage,
        byte_order: decoded.byte_order,
        datatype,
        bitpix: h.bitpix,
        dims: lay.dims.clone(),
        frames: lay.frames,
        frame_loaded: opts.frame,
        mean_of_frames: mean.then_some(lay.frames),
        vox_offset: h.vox_offset,
        data_offset: lay.offset,
        scl_slope: h.scl_slope,
        scl_inter: h.scl_inter,
        qform_code: h.qform_code,
        sform_code: h.sform_code,
        xyzt_units: h.xyzt_units,
        description: h.description(),
        extensions: ext_list,
        gzip: gzip_members > 0,
        gzip_members,
    };

    let (samples, to_physical, converted) = if mean {
        frame_mean::mean_frame(&frame_mean::Frames {
            data: &data,
            offset: lay.offset,
            frame_bytes: lay.frame_bytes,
            frames: lay.frames,
            datatype,
            order: decoded.byte_order,
            scaling: (slope, inter),
        })?
    } else {
        one_frame(
            data,
            &lay,
            opts.frame,
            (datatype, decoded.byte_order),
            (slope, inter),
        )?
    };
    warnings.extend(converted);

    let volume = Volume {
        name: name.to_string(),
        dims: lay.dims3,
        spacing_mm: geometry.spacing_mm,
        orientation: geometry.orientation,
        samples,
        to_physical,
        warnings,
        facts: crate::volume::facts::from_descrip(&summary.description),
    };
    Ok(LoadedNifti {
        volume,
        header: summary,
    })
}

/// Frame `frame` of the file's bytes, converted (the single copy of its voxels).
fn one_frame(
    data: Vec<u8>,
    lay: &layout::Layout,
    frame: usize,
    (datatype, order): (Datatype, ByteOrder),
    (slope, inter): (f64, f64),
) -> Result<
    (
        crate::volume::Samples,
        crate::volume::LinearMap,
        Vec<String>,
    ),
    NiftiError,
> {
    // In range because frame < frames and offset + frames * frame_bytes <= data.len() (layout);
    // checked anyway.
    let start = frame_mean::frame_start(frame, lay.frames, lay.frame_bytes, lay.offset)?;
    let converted =
        convert::convert_frame(data, start, lay.frame_bytes, datatype, order, slope, inter)?;
    Ok((converted.samples, converted.to_physical, converted.warnings))
}

/// `pixdim[0..=3]` for the orientation: the size of an axis beyond `dim[0]` (for example
/// `pixdim[3]` of a 2-D image) is an unused field that is often 0, so it becomes 1 silently
/// instead of being reported as a repair.
fn spatial_pixdim(h: &RawHeader, used_dims: usize) -> [f64; 4] {
    std::array::from_fn(|i| {
        let p = h.pixdim[i];
        if i > used_dims && !(p.is_finite() && p > 0.0) {
            1.0
        } else {
            p
        }
    })
}
