//! The pipeline cache: one `VkPipelineCache` per engine, kept in memory or persisted on disk per
//! device and driver, so a second start skips the driver's shader compiler.
//!
//! Decisions:
//! - Three explicit modes ([`PipelineCacheConfig`]): `Off` (pipelines are created without a
//!   cache), `InMemory` (the library's default: pipelines of one engine share a cache, and no file
//!   is read or written unless the caller asks) and `Directory` (the command line's default: the
//!   user's cache directory, [`default_dir`]).
//! - One file per device and driver: its name carries the vendor and device ids, the driver
//!   version and the driver's pipeline-cache UUID ([`file_name`]), so two GPUs or a driver update
//!   never read each other's data.
//! - A cache file can never fail a run. Whatever is wrong with it (unreadable, too large, not ours,
//!   truncated, corrupted, another device's or driver's, not a regular file) is a
//!   [`CacheRejection`] with a reason the caller may log, and the cache starts empty. It is read
//!   through `files::read` (opened without blocking, regular files only, capped at
//!   [`MAX_FILE_BYTES`] on the opened handle), so a FIFO or a link to `/dev/zero` in its place
//!   cannot hang or exhaust a run.
//! - The file wraps the driver's data in a small envelope of our own (magic, format version,
//!   payload length, SHA-256 of the payload). The Vulkan specification only makes drivers check
//!   the payload's `VkPipelineCacheHeaderVersionOne` (header length, version, vendor and device
//!   ids, UUID), which this module also checks; a truncated or bit-flipped body behind a good
//!   header is something drivers are not required to survive, so the envelope catches it first.
//! - Saving is explicit ([`PipelineCache::persist`]), meant to run after the first frame (nothing
//!   on the path to the first pixel waits for disk), only when the data differ from what was
//!   loaded, and atomically: a temporary file in the same directory, then a rename, so a reader
//!   never sees half a file and concurrent writers leave one whole file (the last one's).

use super::adapter::AdapterInfo;
use super::device::{Device, DeviceShared};
use super::error::{GpuError, GpuResult, vk_err};
use crate::files::read::{ReadError, read_regular};
use ash::vk;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// Whether and where pipelines are cached.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum PipelineCacheConfig {
    /// No `VkPipelineCache`: every pipeline is compiled from scratch.
    Off,
    /// A cache that lives as long as the engine; nothing touches the disk (the default).
    #[default]
    InMemory,
    /// Loaded from, and saved by [`PipelineCache::persist`] into, this directory (created when
    /// saving if missing), in a file named after the device and driver ([`file_name`]).
    Directory(PathBuf),
}

/// Largest cache file read (bytes); larger files are rejected unread. Real caches of morphray's
/// dozen pipelines are kilobytes to a few megabytes.
pub const MAX_FILE_BYTES: u64 = 256 << 20;

/// Magic at the start of a cache file.
const MAGIC: &[u8; 8] = b"MRPCACHE";
/// Version of the envelope.
const FORMAT_VERSION: u32 = 1;
/// Magic, version, reserved word, payload length, SHA-256.
const ENVELOPE_BYTES: usize = 8 + 4 + 4 + 8 + 32;
/// `VkPipelineCacheHeaderVersionOne`: length, version, vendor id, device id, UUID.
const VK_HEADER_BYTES: usize = 16 + vk::UUID_SIZE;

/// What identifies the device and driver a cache belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CacheKey {
    /// PCI vendor id.
    pub vendor_id: u32,
    /// Vendor's device id.
    pub device_id: u32,
    /// Driver version (vendor-encoded).
    pub driver_version: u32,
    /// The driver's `pipelineCacheUUID`.
    pub uuid: [u8; vk::UUID_SIZE],
}

impl CacheKey {
    /// The key of a physical device.
    pub fn of(adapter: &AdapterInfo) -> CacheKey {
        CacheKey {
            vendor_id: adapter.vendor_id,
            device_id: adapter.device_id,
            driver_version: adapter.driver_version,
            uuid: adapter.pipeline_cache_uuid,
        }
    }
}

/// Why a cache file was not used (the cache then starts empty).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CacheRejection {
    /// The file could not be read.
    #[error("cannot read it: {0}")]
    Unreadable(String),
    /// Not a regular file (a FIFO, a device, a directory, or a link to one).
    #[error("it {0}, not a regular file")]
    NotAFile(&'static str),
    /// Larger than [`MAX_FILE_BYTES`].
    #[error("it has {0} bytes, more than a pipeline cache can sensibly hold")]
    TooLarge(u64),
    /// Shorter than the envelope and a Vulkan header.
    #[error("it has only {0} bytes (truncated?)")]
    TooShort(u64),
    /// Not a morphray cache file, or another version of the format.
    #[error("it is not a morphray pipeline cache (format {0})")]
    NotOurs(String),
    /// The payload is shorter or longer than the envelope says.
    #[error("its payload has {actual} bytes where {expected} were written (truncated?)")]
    LengthMismatch {
        /// Length recorded in the envelope.
        expected: u64,
        /// Bytes present.
        actual: u64,
    },
    /// The payload's checksum does not match.
    #[error("its checksum does not match its contents (corrupted)")]
    Corrupt,
    /// The Vulkan header is malformed.
    #[error("its Vulkan header is malformed: {0}")]
    BadHeader(String),
    /// The data belong to another device or driver.
    #[error("it was written for another device or driver ({0})")]
    Foreign(String),
}

/// What happened when the cache was set up.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct CacheLoad {
    /// `off`, `in-memory` or `directory`.
    pub mode: &'static str,
    /// The file read (or that would be read) in directory mode.
    pub path: Option<PathBuf>,
    /// Bytes of driver data handed to `vkCreatePipelineCache` (0: started empty).
    pub loaded_bytes: u64,
    /// Why a file that exists was not used (None when it was used, or no file existed yet).
    pub rejected: Option<String>,
    /// Host time spent reading and checking the file and creating the cache, milliseconds.
    pub ms: f64,
}

/// What [`PipelineCache::persist`] did.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case", tag = "outcome")]
pub enum PersistOutcome {
    /// Nothing to save: the cache is off or in memory.
    NotPersistent,
    /// The driver's data equal what was loaded; the file was left alone.
    Unchanged {
        /// Bytes of driver data.
        bytes: u64,
    },
    /// The file was (re)written.
    Written {
        /// The file.
        path: PathBuf,
        /// Bytes of driver data.
        bytes: u64,
        /// Host time of getting the data and writing the file, milliseconds.
        ms: f64,
    },
}

/// Writing the cache failed (callers report it as a warning: the run itself succeeded).
#[derive(Debug, thiserror::Error)]
pub enum PersistError {
    /// `vkGetPipelineCacheData` failed.
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// Creating the directory, writing or renaming the file failed.
    #[error("cannot write the pipeline cache {path}: {source}")]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
}

/// A `VkPipelineCache` (or none, when off) with where it came from and where it goes.
pub struct PipelineCache {
    raw: vk::PipelineCache,
    path: Option<PathBuf>,
    /// SHA-256 of the payload loaded (None: started empty), to skip saving unchanged data.
    loaded_hash: Option<[u8; 32]>,
    load: CacheLoad,
    device: Arc<DeviceShared>,
}

/// The user's cache directory for morphray: `$MORPHRAY_CACHE_DIR`, else
/// `$XDG_CACHE_HOME/morphray`, else `~/.cache/morphray` (None when none of these is set).
pub fn default_dir() -> Option<PathBuf> {
    let non_empty = |name: &str| std::env::var_os(name).filter(|v| !v.is_empty());
    if let Some(dir) = non_empty("MORPHRAY_CACHE_DIR") {
        return Some(PathBuf::from(dir));
    }
    if let Some(dir) = non_empty("XDG_CACHE_HOME") {
        return Some(PathBuf::from(dir).join("morphray"));
    }
    non_empty("HOME").map(|home| PathBuf::from(home).join(".cache").join("morphray"))
}

/// The cache file's name for a device and driver:
/// `pipelines-VENDOR-DEVICE-DRIVERVERSION-UUID.bin`, all in hex.
pub fn file_name(key: &CacheKey) -> String {
    let uuid: String = key.uuid.iter().map(|b| format!("{b:02x}")).collect();
    format!(
        "pipelines-{:04x}-{:04x}-{:08x}-{uuid}.bin",
        key.vendor_id, key.device_id, key.driver_version
    )
}

/// Wraps driver data in the file envelope (see the module's decisions).
pub fn encode_file(payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(ENVELOPE_BYTES + payload.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    out.extend_from_slice(&Sha256::digest(payload));
    out.extend_from_slice(payload);
    out
}

fn u32_at(bytes: &[u8], at: usize) -> u32 {
    bytes
        .get(at..at + 4)
        .map_or(0, |w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
}

/// Checks a cache file's bytes against the device and driver `key` and returns the driver data
/// inside it, or why they cannot be used.
pub fn decode_file<'a>(bytes: &'a [u8], key: &CacheKey) -> Result<&'a [u8], CacheRejection> {
    let len = bytes.len() as u64;
    if len > MAX_FILE_BYTES {
        return Err(CacheRejection::TooLarge(len));
    }
    if bytes.len() < ENVELOPE_BYTES + VK_HEADER_BYTES {
        return Err(CacheRejection::TooShort(len));
    }
    if &bytes[..8] != MAGIC {
        return Err(CacheRejection::NotOurs("unknown magic".into()));
    }
    let version = u32_at(bytes, 8);
    if version != FORMAT_VERSION {
        return Err(CacheRejection::NotOurs(format!(
            "version {version}, this build reads {FORMAT_VERSION}"
        )));
    }
    let mut length = [0u8; 8];
    length.copy_from_slice(&bytes[16..24]);
    let expected = u64::from_le_bytes(length);
    let payload = &bytes[ENVELOPE_BYTES..];
    if expected != payload.len() as u64 {
        return Err(CacheRejection::LengthMismatch {
            expected,
            actual: payload.len() as u64,
        });
    }
    if Sha256::digest(payload).as_slice() != &bytes[24..56] {
        return Err(CacheRejection::Corrupt);
    }
    check_vk_header(payload, key)?;
    Ok(payload)
}

/// Checks driver data's `VkPipelineCacheHeaderVersionOne` (all fields little-endian, as the
/// specification defines them regardless of the host) against `key`.
pub fn check_vk_header(payload: &[u8], key: &CacheKey) -> Result<(), CacheRejection> {
    if payload.len() < VK_HEADER_BYTES {
        return Err(CacheRejection::BadHeader(format!(
            "{} bytes, shorter than the {VK_HEADER_BYTES}-byte header",
            payload.len()
        )));
    }
    let header_len = u32_at(payload, 0) as usize;
    if header_len < VK_HEADER_BYTES || header_len > payload.len() {
        return Err(CacheRejection::BadHeader(format!(
            "header length {header_len} outside {VK_HEADER_BYTES}..={}",
            payload.len()
        )));
    }
    let version = u32_at(payload, 4);
    if version != vk::PipelineCacheHeaderVersion::ONE.as_raw() as u32 {
        return Err(CacheRejection::BadHeader(format!(
            "header version {version}, expected 1"
        )));
    }
    let (vendor, device) = (u32_at(payload, 8), u32_at(payload, 12));
    let uuid = &payload[16..16 + vk::UUID_SIZE];
    if vendor != key.vendor_id || device != key.device_id {
        return Err(CacheRejection::Foreign(format!(
            "vendor {vendor:04x} device {device:04x}, this is {:04x} {:04x}",
            key.vendor_id, key.device_id
        )));
    }
    if uuid != key.uuid {
        return Err(CacheRejection::Foreign(
            "the driver's pipeline-cache UUID differs (another driver build)".into(),
        ));
    }
    Ok(())
}

/// Reads and checks the file at `path`: Ok(None) when there is none yet. Only a regular file is
/// read (opened without blocking, so a FIFO or a link to a device in its place is refused at
/// once), and never more than [`MAX_FILE_BYTES`] (checked on the opened handle before reading).
fn read_checked(path: &Path, key: &CacheKey) -> Result<Option<Vec<u8>>, CacheRejection> {
    let bytes = match read_regular(path, MAX_FILE_BYTES) {
        Ok(bytes) => bytes,
        Err(e) if e.is_not_found() => return Ok(None),
        Err(ReadError::TooLarge { len, .. }) => return Err(CacheRejection::TooLarge(len)),
        Err(ReadError::NotRegular { kind, .. }) => return Err(CacheRejection::NotAFile(kind)),
        Err(e) => return Err(CacheRejection::Unreadable(e.to_string())),
    };
    let payload = decode_file(&bytes, key)?;
    Ok(Some(payload.to_vec()))
}

impl PipelineCache {
    /// Sets up the cache `config` describes on `device`. Never fails because of a cache file;
    /// only a device that cannot create even an empty cache is an error.
    pub fn new(device: &Device, config: &PipelineCacheConfig) -> GpuResult<PipelineCache> {
        let start = Instant::now();
        let shared = device.shared.clone();
        let key = CacheKey::of(&shared.adapter);
        let (mode, path) = match config {
            PipelineCacheConfig::Off => ("off", None),
            PipelineCacheConfig::InMemory => ("in-memory", None),
            PipelineCacheConfig::Directory(dir) => ("directory", Some(dir.join(file_name(&key)))),
        };
        let mut cache = PipelineCache {
            raw: vk::PipelineCache::null(),
            path,
            loaded_hash: None,
            load: CacheLoad {
                mode,
                path: None,
                ..Default::default()
            },
            device: shared,
        };
        cache.load.path = cache.path.clone();
        if *config == PipelineCacheConfig::Off {
            return Ok(cache);
        }
        let payload = match cache.path.as_deref().map(|p| read_checked(p, &key)) {
            None | Some(Ok(None)) => None,
            Some(Ok(Some(payload))) => Some(payload),
            Some(Err(rejection)) => {
                cache.load.rejected = Some(rejection.to_string());
                None
            }
        };
        if let Some(payload) = payload {
            match create_raw(&cache.device, &payload) {
                Ok(raw) => {
                    cache.raw = raw;
                    cache.load.loaded_bytes = payload.len() as u64;
                    cache.loaded_hash = Some(Sha256::digest(&payload).into());
                }
                Err(e) => {
                    cache.load.rejected = Some(format!("the driver refused its data: {e}"));
                }
            }
        }
        if cache.raw == vk::PipelineCache::null() {
            cache.raw = create_raw(&cache.device, &[])?;
        }
        cache.load.ms = start.elapsed().as_secs_f64() * 1e3;
        Ok(cache)
    }

    /// The handle every pipeline is created with (null when off).
    pub fn raw(&self) -> vk::PipelineCache {
        self.raw
    }

    /// How the cache was set up: mode, file, bytes loaded, why a file was rejected.
    pub fn load(&self) -> &CacheLoad {
        &self.load
    }

    /// The driver's current data (`vkGetPipelineCacheData`; empty when off), for integrators
    /// who persist it themselves.
    pub fn data(&self) -> GpuResult<Vec<u8>> {
        if self.raw == vk::PipelineCache::null() {
            return Ok(Vec::new());
        }
        // SAFETY: the cache belongs to this device and is not being destroyed.
        unsafe { self.device.raw.get_pipeline_cache_data(self.raw) }
            .map_err(vk_err("vkGetPipelineCacheData"))
    }

    /// Saves the data to the cache file when in directory mode and they changed since loading
    /// (see the module's decisions). A failure leaves any previous file intact.
    pub fn persist(&self) -> Result<PersistOutcome, PersistError> {
        let Some(path) = &self.path else {
            return Ok(PersistOutcome::NotPersistent);
        };
        let start = Instant::now();
        let data = self.data()?;
        let bytes = data.len() as u64;
        let hash: [u8; 32] = Sha256::digest(&data).into();
        // Saved even when the data are only the Vulkan header (drivers without a real cache, such
        // as lavapipe in Mesa 22, return just that): the file then records that this driver
        // was seen, and the save is skipped on every later run because nothing changes.
        if self.loaded_hash == Some(hash) {
            return Ok(PersistOutcome::Unchanged { bytes });
        }
        write_atomically(path, &encode_file(&data))?;
        Ok(PersistOutcome::Written {
            path: path.clone(),
            bytes,
            ms: start.elapsed().as_secs_f64() * 1e3,
        })
    }
}

fn create_raw(device: &DeviceShared, initial: &[u8]) -> GpuResult<vk::PipelineCache> {
    let info = vk::PipelineCacheCreateInfo::default().initial_data(initial);
    // SAFETY: valid create info on a live device; the initial data passed the checks above (the
    // driver checks the header again and may ignore the data).
    unsafe { device.raw.create_pipeline_cache(&info, None) }
        .map_err(vk_err("vkCreatePipelineCache"))
}

/// Writes `bytes` to `path` atomically (`files::write`), creating its directory first.
///
/// The cache file is morphray's own, in its own directory: something that is not a regular file
/// in its place (a FIFO, a link to a device, which the load ignored) is removed first, so the
/// cache works again from the next run on. (User-named outputs are never treated this way:
/// `files::write` refuses to replace anything but a regular file.)
fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), PersistError> {
    let dir = path.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).map_err(|source| PersistError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    // `metadata` follows links: a link to a regular file is kept (the write follows it).
    if let Ok(meta) = std::fs::metadata(path)
        && !meta.is_file()
        && !meta.is_dir()
    {
        std::fs::remove_file(path).map_err(|source| PersistError::Io {
            path: path.to_path_buf(),
            source,
        })?;
    }
    crate::files::write::write_file(path, bytes).map_err(|e| PersistError::Io {
        path: path.to_path_buf(),
        source: e.into_io_error(),
    })
}

impl Drop for PipelineCache {
    fn drop(&mut self) {
        if self.raw != vk::PipelineCache::null() {
            // SAFETY: pipelines created from a cache do not depend on it; no creation is running
            // (the engine owning this cache is being dropped).
            unsafe { self.device.raw.destroy_pipeline_cache(self.raw, None) };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key() -> CacheKey {
        CacheKey {
            vendor_id: 0x10de,
            device_id: 0x2330,
            driver_version: 0x9117_c000,
            uuid: [7; 16],
        }
    }

    /// Driver data as a driver writes it: the Vulkan header, then opaque bytes.
    fn payload(key: &CacheKey, body: &[u8]) -> Vec<u8> {
        let mut p = Vec::new();
        p.extend_from_slice(&(VK_HEADER_BYTES as u32).to_le_bytes());
        p.extend_from_slice(&1u32.to_le_bytes());
        p.extend_from_slice(&key.vendor_id.to_le_bytes());
        p.extend_from_slice(&key.device_id.to_le_bytes());
        p.extend_from_slice(&key.uuid);
        p.extend_from_slice(body);
        p
    }

    #[test]
    fn a_good_file_round_trips() {
        let data = payload(&key(), b"compiled pipelines");
        let file = encode_file(&data);
        assert_eq!(decode_file(&file, &key()), Ok(&data[..]));
    }

    #[test]
    fn truncated_garbage_and_foreign_files_are_rejected() {
        let k = key();
        let file = encode_file(&payload(&k, &[42; 100]));
        // Truncated anywhere: in the envelope, in the header, in the body.
        for cut in [0, 5, 40, ENVELOPE_BYTES + 10, file.len() - 1] {
            assert!(decode_file(&file[..cut], &k).is_err(), "cut at {cut}");
        }
        assert!(matches!(
            decode_file(&file[..file.len() - 1], &k),
            Err(CacheRejection::LengthMismatch { .. })
        ));
        // Garbage, and a raw driver blob without the envelope.
        let garbage: Vec<u8> = (0..4096u32)
            .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
            .collect();
        assert!(matches!(
            decode_file(&garbage, &k),
            Err(CacheRejection::NotOurs(_))
        ));
        assert!(decode_file(&payload(&k, &[1; 64]), &k).is_err());
        // One flipped bit in the body.
        let mut flipped = file.clone();
        let last = flipped.len() - 1;
        flipped[last] ^= 1;
        assert_eq!(decode_file(&flipped, &k), Err(CacheRejection::Corrupt));
        // Another device, another vendor, another driver build (UUID).
        for other in [
            CacheKey {
                device_id: 0x2331,
                ..k
            },
            CacheKey {
                vendor_id: 0x8086,
                ..k
            },
            CacheKey { uuid: [8; 16], ..k },
        ] {
            let foreign = encode_file(&payload(&other, &[1; 64]));
            assert!(
                matches!(decode_file(&foreign, &k), Err(CacheRejection::Foreign(_))),
                "{other:?}"
            );
        }
    }

    #[test]
    fn malformed_vulkan_headers_are_rejected() {
        let k = key();
        let good = payload(&k, &[0; 16]);
        let with = |at: usize, value: u32| {
            let mut p = good.clone();
            p[at..at + 4].copy_from_slice(&value.to_le_bytes());
            encode_file(&p)
        };
        for (file, what) in [
            (with(0, 8), "header length below 32"),
            (with(0, 10_000), "header length beyond the data"),
            (with(4, 2), "unknown header version"),
        ] {
            assert!(
                matches!(decode_file(&file, &k), Err(CacheRejection::BadHeader(_))),
                "{what}"
            );
        }
        let mut other_version = encode_file(&good);
        other_version[8] = 9;
        assert!(matches!(
            decode_file(&other_version, &k),
            Err(CacheRejection::NotOurs(_))
        ));
    }

    #[test]
    fn file_names_carry_device_driver_and_uuid() {
        let name = file_name(&key());
        assert_eq!(
            name,
            "pipelines-10de-2330-9117c000-07070707070707070707070707070707.bin"
        );
    }

    #[test]
    fn oversized_files_are_rejected_unread() {
        let dir = std::env::temp_dir().join(format!("morphray-pc-unit-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("huge.bin");
        let file = std::fs::File::create(&path).unwrap();
        // Sparse: the size is there, the bytes are not.
        file.set_len(MAX_FILE_BYTES + 1).unwrap();
        assert!(matches!(
            read_checked(&path, &key()),
            Err(CacheRejection::TooLarge(_))
        ));
        assert_eq!(read_checked(&dir.join("missing.bin"), &key()), Ok(None));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn fifos_and_links_to_devices_are_rejected_without_blocking() {
        let dir = std::env::temp_dir().join(format!("morphray-pc-special-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let fifo = dir.join("fifo.bin");
        let made = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(made.success());
        let zero = dir.join("zero.bin");
        std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
        let start = std::time::Instant::now();
        assert_eq!(
            read_checked(&fifo, &key()),
            Err(CacheRejection::NotAFile("is a FIFO (named pipe)"))
        );
        assert_eq!(
            read_checked(&zero, &key()),
            Err(CacheRejection::NotAFile("is a character device"))
        );
        assert!(start.elapsed() < std::time::Duration::from_secs(1));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
