//! Device profiles and kernel tuning: run the constrained paths of a smaller GPU on any device,
//! and choose workgroup and subgroup sizes per pass for profiling.
//!
//! Decisions:
//! - A profile only ever *clamps* what the real device offers (a smaller 3D image limit, fewer
//!   subgroup sizes, fewer timestamp bits, a smaller memory budget, no float atomics, uploads
//!   without staging); it never claims a capability the device lacks, so everything the engine
//!   does under a profile really runs. That is what lets lavapipe and the H100 test the Intel
//!   Gen12 (Xe-LP) paths: bricking past 2048 texels, unified-memory uploads, integer-only atomics.
//! - `gen12` is built in (what Mesa's ANV reports for Tiger Lake: maxImageDimension3D 2048, one
//!   DEVICE_LOCAL heap in system memory with host-visible types, subgroup sizes 8-32, no float
//!   atomic add, 36-bit timestamps). Its heap is what Mesa's ANV driver reports for the machine's
//!   RAM: half of it up to 4 GiB, three quarters above (`anv_compute_sys_heap_size`); the built-in
//!   profile assumes 16 GiB. Other profiles are small TOML files with the same keys (see
//!   [`DeviceProfile`]).
//! - Workgroup sizes are specialization constants of the kernels that declare
//!   `local_size_x_id` (raymarch, normalize, derivatives); the WGSL reductions size their shared
//!   memory and loops for 256 invocations and stay fixed. A subgroup size is pinned with
//!   `requiredSubgroupSize` where the device supports subgroup size control for compute, because
//!   Xe-LP reports 32 even when a kernel runs SIMD8 or SIMD16 (BENCHMARKS.md "Intel Gen12").

use super::adapter::AdapterInfo;
use super::error::{GpuError, GpuResult};

/// Limits and properties of a constrained device class, applied on top of the real device.
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct DeviceProfile {
    /// Short name (`gen12`).
    pub name: String,
    /// What the profile models, for reports.
    #[serde(default)]
    pub description: String,
    /// Largest 3D image side.
    pub max_image_dimension_3d: Option<u32>,
    /// Device memory is system memory: uploads write it directly, without a staging copy.
    #[serde(default)]
    pub unified_memory: bool,
    /// System RAM of the modelled machine in bytes (suffixes K, M, G); the device-local budget is
    /// what ANV reports for it (half up to 4 GiB, three quarters above).
    #[serde(default, with = "bytes_option")]
    pub system_ram: Option<u64>,
    /// Subgroup sizes the device can run compute shaders at.
    pub subgroup_sizes: Option<Vec<u32>>,
    /// Whether shaders may use float atomics (Xe-LP: no).
    #[serde(default = "yes")]
    pub float_atomics: bool,
    /// Valid bits of GPU timestamps.
    pub timestamp_valid_bits: Option<u32>,
    /// Default workgroup of the tunable kernels, `XxY[xZ]`.
    pub workgroup: Option<String>,
    /// Default subgroup size to pin (`requiredSubgroupSize`).
    pub subgroup_size: Option<u32>,
}

fn yes() -> bool {
    true
}

/// The built-in Intel Gen12 (Xe-LP) profile, also the example of the file format.
pub const GEN12_TOML: &str = include_str!("profiles/gen12.toml");

impl DeviceProfile {
    /// A built-in profile by name (`gen12`), or a profile read from a TOML file at `name`.
    pub fn load(name: &str) -> GpuResult<DeviceProfile> {
        if name.eq_ignore_ascii_case("gen12") || name.eq_ignore_ascii_case("xe-lp") {
            return Self::parse(GEN12_TOML, "the built-in gen12 profile");
        }
        let path = std::path::Path::new(name);
        if path.extension().is_none_or(|e| e != "toml") {
            return Err(GpuError::InvalidRequest(format!(
                "unknown profile `{name}`: use `gen12`, or the path of a .toml profile file"
            )));
        }
        // A regular file of at most 1 MiB (profiles are a few hundred bytes): a FIFO or a
        // device named as the profile is refused at once instead of blocking or filling memory.
        let bytes = crate::files::read::read_regular(path, 1 << 20)
            .map_err(|e| GpuError::InvalidRequest(format!("cannot read profile: {e}")))?;
        let text = String::from_utf8(bytes).map_err(|_| {
            GpuError::InvalidRequest(format!(
                "cannot read profile {}: it is not UTF-8 text",
                path.display()
            ))
        })?;
        Self::parse(&text, &path.display().to_string())
    }

    /// Parses a profile from TOML text (`origin` names it in errors).
    pub fn parse(text: &str, origin: &str) -> GpuResult<DeviceProfile> {
        let profile: DeviceProfile = toml::from_str(text).map_err(|e| {
            GpuError::InvalidRequest(format!(
                "{origin}: {}",
                e.to_string()
                    .split_whitespace()
                    .collect::<Vec<_>>()
                    .join(" ")
            ))
        })?;
        if let Some(sizes) = &profile.subgroup_sizes
            && (sizes.is_empty() || sizes.iter().any(|s| !s.is_power_of_two() || *s > 128))
        {
            return Err(GpuError::InvalidRequest(format!(
                "{origin}: subgroup_sizes must be powers of two up to 128, got {sizes:?}"
            )));
        }
        if profile.max_image_dimension_3d == Some(0) {
            return Err(GpuError::InvalidRequest(format!(
                "{origin}: max_image_dimension_3d must be positive"
            )));
        }
        if let Some(w) = &profile.workgroup {
            parse_workgroup(w).map_err(|e| GpuError::InvalidRequest(format!("{origin}: {e}")))?;
        }
        Ok(profile)
    }

    /// The device-local heap the modelled machine's driver reports (ANV's rule).
    pub fn heap_bytes(&self) -> Option<u64> {
        self.system_ram
            .map(|ram| if ram <= 4 << 30 { ram / 2 } else { ram / 4 * 3 })
    }

    /// `adapter` clamped to this profile: never more than the device offers.
    pub fn clamp(&self, mut adapter: AdapterInfo) -> AdapterInfo {
        if let Some(limit) = self.max_image_dimension_3d {
            adapter.max_image_dimension_3d = adapter.max_image_dimension_3d.min(limit);
        }
        adapter.unified_memory |= self.unified_memory;
        if let Some(bits) = self.timestamp_valid_bits {
            adapter.timestamp_valid_bits = adapter.timestamp_valid_bits.min(bits);
        }
        adapter.float_atomics &= self.float_atomics;
        if let (Some(sizes), Some((lo, hi))) = (&self.subgroup_sizes, adapter.subgroup_size_range) {
            let common: Vec<u32> = sizes
                .iter()
                .copied()
                .filter(|s| (lo..=hi).contains(s))
                .collect();
            adapter.subgroup_size_range = match (common.iter().min(), common.iter().max()) {
                (Some(&a), Some(&b)) => Some((a, b)),
                // No size in common: nothing can be pinned.
                _ => None,
            };
        }
        adapter.profile = Some(self.name.clone());
        adapter
    }
}

/// Which workgroup and subgroup sizes the tunable kernels run with.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct KernelTuning {
    /// (pass, size): a pass name (`raymarch`, `normalize`, `derivatives`) or None for every
    /// tunable pass; later entries win.
    pub workgroups: Vec<(Option<String>, [u32; 3])>,
    /// Subgroup size to pin on every pipeline.
    pub subgroup_size: Option<u32>,
}

/// The passes whose workgroup size can be chosen.
pub const TUNABLE_PASSES: [&str; 3] = ["raymarch", "normalize", "derivatives"];

impl KernelTuning {
    /// Parses one `--wg` value: `XxY[xZ]` for every tunable pass or `PASS=XxY[xZ]` for one.
    pub fn add_workgroup(&mut self, text: &str) -> Result<(), String> {
        let (pass, size) = match text.split_once('=') {
            Some((pass, size)) => {
                let pass = pass.trim().to_ascii_lowercase();
                if !TUNABLE_PASSES.contains(&pass.as_str()) {
                    return Err(format!(
                        "`{pass}` has no selectable workgroup; choose one of {}",
                        TUNABLE_PASSES.join(", ")
                    ));
                }
                (Some(pass), size)
            }
            None => (None, text),
        };
        self.workgroups.push((pass, parse_workgroup(size)?));
        Ok(())
    }

    /// The workgroup chosen for the pass whose shader source is `source` (its file stem names
    /// the pass), if any; `two_d` passes get z = 1.
    pub fn workgroup_for(&self, source: &str) -> Option<[u32; 3]> {
        let stem = std::path::Path::new(source)
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or(source);
        self.workgroups
            .iter()
            .rev()
            .find(|(pass, _)| pass.as_deref().is_none_or(|p| p == stem))
            .map(|(_, size)| *size)
    }

    /// This tuning with the profile's defaults under it (explicit choices win).
    pub fn with_profile_defaults(mut self, profile: Option<&DeviceProfile>) -> Self {
        let Some(profile) = profile else {
            return self;
        };
        if let Some(size) = profile
            .workgroup
            .as_deref()
            .and_then(|w| parse_workgroup(w).ok())
        {
            self.workgroups.insert(0, (None, size));
        }
        if self.subgroup_size.is_none() {
            self.subgroup_size = profile.subgroup_size;
        }
        self
    }
}

/// Parses `XxY` or `XxYxZ` (z defaults to 1), each side 1..=1024.
pub fn parse_workgroup(text: &str) -> Result<[u32; 3], String> {
    let parts: Vec<Option<u32>> = text
        .split(['x', 'X'])
        .map(|p| {
            p.trim()
                .parse::<u32>()
                .ok()
                .filter(|v| (1..=1024).contains(v))
        })
        .collect();
    match parts.as_slice() {
        [Some(x), Some(y)] => Ok([*x, *y, 1]),
        [Some(x), Some(y), Some(z)] => Ok([*x, *y, *z]),
        _ => Err(format!(
            "`{text}` is not a workgroup size XxY or XxYxZ (sides 1 to 1024, e.g. 8x8)"
        )),
    }
}

/// Checks a chosen workgroup against the device's limits and the kernel's dimensionality.
pub fn check_workgroup(
    adapter: &AdapterInfo,
    shader: &str,
    default: [u32; 3],
    size: [u32; 3],
) -> GpuResult<()> {
    if default[2] == 1 && size[2] != 1 {
        return Err(GpuError::InvalidRequest(format!(
            "{shader} is a 2D kernel: its workgroup's z must be 1, not {}",
            size[2]
        )));
    }
    let invocations = size.iter().map(|&s| s as u64).product::<u64>();
    let over_axis = size
        .iter()
        .zip(adapter.max_workgroup_size)
        .any(|(s, m)| *s > m);
    if over_axis || invocations > adapter.max_workgroup_invocations as u64 {
        return Err(GpuError::Unsupported(format!(
            "{shader}: workgroup {}x{}x{} exceeds {}'s limits ({:?} per axis, {} invocations)",
            size[0],
            size[1],
            size[2],
            adapter.name,
            adapter.max_workgroup_size,
            adapter.max_workgroup_invocations
        )));
    }
    Ok(())
}

/// Checks that `size` can be pinned on this device (subgroup size control, within range).
pub fn check_subgroup_size(adapter: &AdapterInfo, size: u32) -> GpuResult<()> {
    match adapter.subgroup_size_range {
        Some((lo, hi)) if (lo..=hi).contains(&size) && size.is_power_of_two() => Ok(()),
        Some((lo, hi)) => Err(GpuError::Unsupported(format!(
            "subgroup size {size} is not available on {}{}: it runs compute at {lo} to {hi}",
            adapter.name,
            adapter
                .profile
                .as_ref()
                .map(|p| format!(" under the {p} profile"))
                .unwrap_or_default()
        ))),
        None => Err(GpuError::Unsupported(format!(
            "{} cannot pin a subgroup size (no subgroup size control for compute{}); it runs at {}",
            adapter.name,
            adapter
                .profile
                .as_ref()
                .map(|p| format!(", or no size in common with the {p} profile"))
                .unwrap_or_default(),
            adapter.subgroup_size
        ))),
    }
}

mod bytes_option {
    //! `system_ram = "16G"` or a plain number of bytes.
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(value: &Option<u64>, s: S) -> Result<S::Ok, S::Error> {
        match value {
            Some(v) => s.serialize_u64(*v),
            None => s.serialize_none(),
        }
    }

    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Raw {
        Number(u64),
        Text(String),
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u64>, D::Error> {
        let raw = Option::<Raw>::deserialize(d)?;
        raw.map(|r| match r {
            Raw::Number(n) => Ok(n),
            Raw::Text(t) => super::parse_bytes(&t).map_err(serde::de::Error::custom),
        })
        .transpose()
    }
}

/// Parses a byte count with an optional K, M or G suffix (binary units); the number may have a
/// decimal fraction (`1.5G`, `0.5M`), rounded down to whole bytes.
pub fn parse_bytes(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let (number, unit) = match t.char_indices().find(|(_, c)| c.is_ascii_alphabetic()) {
        Some((i, _)) => (&t[..i], t[i..].to_ascii_uppercase()),
        None => (t, String::new()),
    };
    let form = "use a positive number of bytes, optionally with a decimal fraction and K, M or G \
                (binary: 512M, 1.5G, 2000000)";
    let scale: u64 = match unit.trim_end_matches('B').trim_end_matches('I') {
        "" => 1,
        "K" => 1 << 10,
        "M" => 1 << 20,
        "G" => 1 << 30,
        _ => return Err(format!("`{text}` is not a size: {form}")),
    };
    let number = number.trim();
    // Digits with at most one point: no signs, exponents, `inf` or `nan`.
    let digits = !number.is_empty()
        && number.chars().all(|c| c.is_ascii_digit() || c == '.')
        && number.matches('.').count() <= 1
        && number != ".";
    let bytes = if !digits {
        None
    } else if let Ok(n) = number.parse::<u64>() {
        n.checked_mul(scale)
    } else {
        // Exact for every size below 2^53 bytes (8 PiB); larger decimal sizes round down.
        number
            .parse::<f64>()
            .ok()
            .map(|n| (n * scale as f64).floor())
            .filter(|n| *n < u64::MAX as f64)
            .map(|n| n as u64)
    };
    bytes
        .filter(|&n| n > 0)
        .ok_or_else(|| format!("`{text}` is not a size: {form}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Before: `read_to_string` on a FIFO named `x.toml` blocked forever.
    #[test]
    fn a_fifo_named_as_the_profile_is_refused_at_once() {
        let dir = std::env::temp_dir().join(format!("morphray-profile-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let fifo = dir.join("pipe.toml");
        let made = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(made.success());
        let start = std::time::Instant::now();
        let e = DeviceProfile::load(fifo.to_str().unwrap()).unwrap_err();
        assert!(start.elapsed() < std::time::Duration::from_secs(1));
        assert!(e.to_string().contains("FIFO"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn sizes_take_decimal_fractions_and_say_the_accepted_form() {
        assert_eq!(parse_bytes("1.5G"), Ok(3 << 29));
        assert_eq!(parse_bytes("512M"), Ok(512 << 20));
        assert_eq!(parse_bytes("0.5k"), Ok(512));
        assert_eq!(parse_bytes("2000000"), Ok(2_000_000));
        assert_eq!(parse_bytes("1.5 GiB"), Ok(3 << 29));
        for bad in [
            "0", "0.0001", "-1G", "1e9", "inf", "nan", "1.2.3G", "G", "1.5T", ".",
        ] {
            let e = parse_bytes(bad).unwrap_err();
            assert!(
                e.contains("is not a size") && e.contains("1.5G"),
                "{bad}: {e}"
            );
        }
        assert!(parse_bytes("99999999999999999999999").is_err());
    }

    #[test]
    fn the_gen12_profile_parses_with_the_documented_limits() {
        let p = DeviceProfile::load("gen12").unwrap();
        assert_eq!(p.max_image_dimension_3d, Some(2048));
        assert!(p.unified_memory && !p.float_atomics);
        assert_eq!(p.subgroup_sizes.as_deref(), Some(&[8, 16, 32][..]));
        assert_eq!(p.timestamp_valid_bits, Some(36));
        // 16 GiB of RAM: ANV reports three quarters.
        assert_eq!(p.heap_bytes(), Some(12 << 30));
    }

    #[test]
    fn bad_profiles_are_typed_errors_naming_the_file() {
        let err = DeviceProfile::parse("name = \"x\"\nbogus = 1\n", "p.toml").unwrap_err();
        assert!(err.to_string().contains("p.toml") && err.to_string().contains("bogus"));
        let err = DeviceProfile::parse("name = \"x\"\nsubgroup_sizes = [12]\n", "p.toml")
            .unwrap_err()
            .to_string();
        assert!(err.contains("powers of two"), "{err}");
        let err = DeviceProfile::parse("name = \"x\"\nsystem_ram = \"lots\"\n", "p.toml")
            .unwrap_err()
            .to_string();
        assert!(err.contains("lots"), "{err}");
        assert!(DeviceProfile::load("nonesuch").is_err());
        assert!(DeviceProfile::load("/nonexistent/profile.toml").is_err());
    }

    #[test]
    fn anv_heap_rule() {
        let p = |ram: u64| DeviceProfile {
            system_ram: Some(ram),
            ..DeviceProfile::parse("name = \"t\"", "t").unwrap()
        };
        assert_eq!(p(4 << 30).heap_bytes(), Some(2 << 30));
        assert_eq!(p(8 << 30).heap_bytes(), Some(6 << 30));
    }

    #[test]
    fn workgroups_parse_per_pass_and_later_choices_win() {
        let mut t = KernelTuning::default();
        t.add_workgroup("8x8").unwrap();
        t.add_workgroup("raymarch=16x4").unwrap();
        assert_eq!(t.workgroup_for("shaders/raymarch.comp"), Some([16, 4, 1]));
        assert_eq!(t.workgroup_for("shaders/derivatives.comp"), Some([8, 8, 1]));
        assert!(t.add_workgroup("minmax=64").is_err());
        assert!(t.add_workgroup("0x8").is_err());
        assert!(t.add_workgroup("8").is_err());
        assert_eq!(parse_workgroup("4x4x4"), Ok([4, 4, 4]));
    }
}
