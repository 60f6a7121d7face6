//! One file per GPU pass; each owns its pipeline and knows its bindings, push constants and the
//! barriers around it.
//!
//! Decisions: a pass is created once per device (and per variant: sample kind, outputs) and
//! recorded many times; recording takes the resources as arguments and never allocates anything
//! that outlives the recording, except the outputs it returns. Push-constant structs are
//! `#[repr(C)]` + `Pod` and their sizes are checked against the reflection table in tests.

pub mod bandwidth;
pub mod brain;
pub mod brick_bounds;
pub mod brick_distance;
pub mod compositing_probe;
pub mod cost;
pub mod denoise;
pub mod derivatives;
pub mod eigen_probe;
pub mod fine_histogram;
pub mod histogram;
pub mod minmax;
pub mod normalize;
pub mod occupancy;
#[cfg(feature = "viewer")]
pub mod present;
pub mod raymarch;
pub mod slice;
pub mod vesselness;

use crate::gpu::shaders::ShaderInfo;
use crate::volume::SampleKind;

/// Workgroup count and per-invocation loop shape of a grid-stride dispatch over `items`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LinearDispatch {
    /// Workgroups along x.
    pub workgroups: u32,
    /// Loop steps every invocation runs (the same for all, so subgroup operations and barriers
    /// stay in uniform control flow).
    pub iterations: u32,
    /// Items between one invocation's consecutive steps (= invocations in the dispatch).
    pub stride: u32,
}

/// Plans a grid-stride dispatch: about `items_per_invocation` items per invocation, at most
/// `max_workgroups` workgroups (the device's x limit), every item covered exactly once.
pub fn linear_dispatch(
    items: u64,
    workgroup_size: u32,
    items_per_invocation: u32,
    max_workgroups: u32,
) -> LinearDispatch {
    let per_group = workgroup_size as u64 * items_per_invocation.max(1) as u64;
    let wanted = items.div_ceil(per_group).max(1);
    let workgroups = wanted.min(max_workgroups.max(1) as u64) as u32;
    let stride = workgroups as u64 * workgroup_size as u64;
    let iterations = items.div_ceil(stride).max(1);
    LinearDispatch {
        workgroups,
        iterations: iterations as u32,
        stride: stride as u32,
    }
}

/// The WGSL variant of a per-sample-kind kernel.
pub(crate) fn variant(
    kind: SampleKind,
    u8_: &'static ShaderInfo,
    i8_: &'static ShaderInfo,
    u16_: &'static ShaderInfo,
    i16_: &'static ShaderInfo,
    f32_: &'static ShaderInfo,
) -> &'static ShaderInfo {
    match kind {
        SampleKind::U8 => u8_,
        SampleKind::I8 => i8_,
        SampleKind::U16 => u16_,
        SampleKind::I16 => i16_,
        SampleKind::F32 => f32_,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_dispatch_covers_every_item_once() {
        for items in [1u64, 31, 32, 33, 255, 256, 257, 1_000_003, 12_582_912] {
            for max in [1u32, 7, 65_535] {
                let d = linear_dispatch(items, 256, 4, max);
                assert!(d.workgroups >= 1 && d.workgroups <= max);
                assert_eq!(d.stride, d.workgroups * 256);
                let covered = d.iterations as u64 * d.stride as u64;
                assert!(covered >= items, "{items} items, {d:?}");
                assert!(
                    covered - items < d.stride as u64,
                    "a whole idle step for {items}: {d:?}"
                );
            }
        }
    }
}
