//! What each pass must move at least: bytes read and written once each, and texture fetches.
//!
//! Decision: costs are computed from the pass's definition, not measured, so they are the floor a
//! pass is compared against (bytes / bandwidth, fetches / texel rate) on any device, including
//! devices we only model (Intel Xe-LP). Texel rates count a trilinear 3D fetch as two bilinear
//! texels (8 taps, 4 per texel-rate unit), matching how vendors quote texel rates.

/// Minimum traffic of one pass execution.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct PassCost {
    /// Bytes read from device memory, each input once.
    pub bytes_read: f64,
    /// Bytes written, each output once.
    pub bytes_written: f64,
    /// Filtered (trilinear) texture fetches.
    pub trilinear_fetches: f64,
    /// Unfiltered texel loads (texelFetch / textureLoad).
    pub texel_loads: f64,
}

impl PassCost {
    /// Bytes moved in total.
    pub fn bytes(&self) -> f64 {
        self.bytes_read + self.bytes_written
    }

    /// Texel-rate units: a trilinear fetch counts 2, an unfiltered load 1.
    pub fn texel_units(&self) -> f64 {
        2.0 * self.trilinear_fetches + self.texel_loads
    }

    /// The larger of the bandwidth and texel-rate bounds, in seconds, on a device with
    /// `bandwidth` bytes/s and `texel_rate` texels/s.
    pub fn bound_seconds(&self, bandwidth: f64, texel_rate: f64) -> f64 {
        (self.bytes() / bandwidth).max(self.texel_units() / texel_rate)
    }
}

/// Min/max: every sample read once.
pub fn minmax(sample_bytes: f64) -> PassCost {
    PassCost {
        bytes_read: sample_bytes,
        ..Default::default()
    }
}

/// One refinement of the robust range's fine histogram: every sample read once (one refinement
/// on a clean scan, two or three with hot voxels far outside the data).
pub fn fine_histogram(sample_bytes: f64) -> PassCost {
    PassCost {
        bytes_read: sample_bytes,
        ..Default::default()
    }
}

/// Normalization: samples read, the normalized volume written.
pub fn normalize(sample_bytes: f64, voxels: f64, normalized_texel_bytes: f64) -> PassCost {
    PassCost {
        bytes_read: sample_bytes,
        bytes_written: voxels * normalized_texel_bytes,
        ..Default::default()
    }
}

/// Histogram: the normalized volume read (plus raw f32 samples to skip non-finite voxels).
pub fn histogram(voxels: f64, normalized_texel_bytes: f64, raw_f32: bool) -> PassCost {
    let raw = if raw_f32 { 4.0 * voxels } else { 0.0 };
    PassCost {
        bytes_read: voxels * normalized_texel_bytes + raw,
        texel_loads: voxels,
        ..Default::default()
    }
}

/// Derivatives: I_norm read once (the 7 or 19 loads per voxel hit the cache), outputs written
/// (`gradient_texel_bytes` per voxel for |g| and k, 0 when nothing is stored).
pub fn derivatives(
    voxels: f64,
    normalized_texel_bytes: f64,
    curvature: bool,
    normals: bool,
    gradient_texel_bytes: f64,
) -> PassCost {
    let gradient_bytes = gradient_texel_bytes;
    let normal_bytes = if normals { 4.0 } else { 0.0 };
    PassCost {
        bytes_read: voxels * normalized_texel_bytes,
        bytes_written: voxels * (gradient_bytes + normal_bytes),
        texel_loads: voxels * if curvature { 19.0 } else { 7.0 },
        ..Default::default()
    }
}

/// Denoising I_norm (any filter): read once, written once (the minimum traffic; the filters'
/// neighbourhoods come from the cache).
pub fn denoise(voxels: f64, normalized_texel_bytes: f64) -> PassCost {
    PassCost {
        bytes_read: voxels * normalized_texel_bytes,
        bytes_written: voxels * normalized_texel_bytes,
        ..Default::default()
    }
}

/// Multi-scale vesselness over `voxels` (R32F scratch, 4 bytes a texel), per scale: three
/// separable Gaussian passes of `2r + 1` loads a texel (r = 3 sigma, sigma's mm counted as
/// voxels: exact at 1 mm) reading and writing the volume, and the Hessian/Frangi pass (19
/// loads, the running maximum read and written).
pub fn vesselness(voxels: f64, scales_mm: &[f32]) -> PassCost {
    let loads: f64 = scales_mm
        .iter()
        .map(|&sigma| 3.0 * (2.0 * (3.0 * sigma as f64).ceil() + 1.0) + 19.0)
        .sum();
    let scales = scales_mm.len() as f64;
    PassCost {
        bytes_read: scales * 4.0 * voxels * 4.0,
        bytes_written: scales * 4.0 * voxels * 4.0,
        texel_loads: voxels * loads,
        ..Default::default()
    }
}

/// Brain extraction (`passes::brain`) with the default parameters on a 1 mm grid: the
/// Gaussian (3 x 7 taps), four bounded distance transforms (3 x (11 + 11 + 11 + 9) taps), the
/// voxel steps and pools (about 10 fetches): 157 f32 loads and 15 f32 stores a voxel.
pub fn brain(voxels: f64) -> PassCost {
    let loads = 3.0 * 7.0 + 3.0 * (11.0 + 11.0 + 11.0 + 9.0) + 10.0;
    PassCost {
        bytes_read: voxels * loads * 4.0,
        bytes_written: voxels * 15.0 * 4.0,
        texel_loads: voxels * loads,
        ..Default::default()
    }
}

/// Raymarch of one frame from counted samples: each marched sample fetches I_norm; each
/// classified sample also fetches the derived volumes (1, or 2 with stored normals), or makes 6
/// (19 with curvature) extra I_norm fetches on the fly. The image is written once (4 bytes a
/// pixel); volume bytes are assumed to come from the cache, so the texel rate is the bound.
pub fn raymarch(
    pixels: f64,
    marched: f64,
    classified: f64,
    derived_fetches_per_classified: f64,
) -> PassCost {
    PassCost {
        bytes_written: pixels * 4.0,
        trilinear_fetches: marched + classified * derived_fetches_per_classified,
        ..Default::default()
    }
}

/// A device we project onto: documented bandwidth and texel rate.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct DeviceModel {
    /// Name, e.g. `Intel Iris Xe (96 EU), model`.
    pub name: &'static str,
    /// DRAM bandwidth, bytes/s.
    pub bandwidth: f64,
    /// Texel rate, bilinear texels/s.
    pub texel_rate: f64,
}

/// Intel Xe-LP (Iris Xe, 96 EU): 68 GB/s (dual-channel LPDDR4X-4266), about 60 GTexel/s (the
/// model's assumptions from the part's specification; no Xe-LP device was measured).
pub const XE_LP: DeviceModel = DeviceModel {
    name: "Intel Iris Xe 96 EU (Xe-LP), model",
    bandwidth: 68e9,
    texel_rate: 60e9,
};

/// NVIDIA H100 SXM: 3.35 TB/s HBM3, about 1045 GTexel/s in compute (from the part's specification).
pub const H100: DeviceModel = DeviceModel {
    name: "NVIDIA H100 80GB HBM3",
    bandwidth: 3.35e12,
    texel_rate: 1045e9,
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_pick_the_binding_resource() {
        // 25.2 MB read at 68 GB/s is 0.37 ms (the Iris Xe min/max estimate).
        let c = minmax(25_165_824.0);
        assert!((c.bound_seconds(XE_LP.bandwidth, XE_LP.texel_rate) * 1e3 - 0.370).abs() < 0.001);
        // 1920x1080 rays x 400 trilinear samples: texel-bound at 2 units per fetch.
        let r = raymarch(1920.0 * 1080.0, 1920.0 * 1080.0 * 400.0, 0.0, 1.0);
        let t = r.bound_seconds(H100.bandwidth, H100.texel_rate);
        assert!((t * 1e3 - 1.587).abs() < 0.01, "{}", t * 1e3);
    }
}
