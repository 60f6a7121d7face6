//! Why no plan fits, in words a user can act on: the volume (its bytes, the budget, the
//! bricking limit, the smallest plan tried), or, when a small image would fit, the image (its
//! size and the largest of its shape that fits: a 16384x16384 render of a 400 KB volume was
//! once blamed on bricking the volume).

use super::{
    BRICKING_MAX_RATIO, BRICKING_SLACK, DoesNotFit, ImageSizes, Layout, Plan, PlanInput,
    STORAGE_BRICK, STORAGE_HALO, bricking_limit, plan_with, voxels,
};
use crate::scene::Effects;

impl std::fmt::Display for DoesNotFit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mib = |b: u64| b as f64 / f64::from(1 << 20);
        // One decimal: a plan a few hundred kB over the budget must not read as equal to it.
        match self.image {
            Some(([w, h], [fw, fh])) => write!(
                f,
                "the {w}x{h} image is too large, not the volume: with it the plan needs {:.1} MiB \
                 of GPU memory (memory budget {:.1} MiB); the largest image of that shape that \
                 fits is {fw}x{fh}: use a smaller --size (or a larger --memory-budget, when the \
                 device has more)",
                mib(self.smallest_bytes),
                mib(self.budget)
            ),
            None => write!(
                f,
                "the volume ({:?} voxels, {} bytes as R16) {}: the smallest plan tried ({}) needs \
                 {} bytes",
                self.dims, self.volume_bytes, self.limit, self.smallest_plan, self.smallest_bytes
            ),
        }
    }
}

impl std::error::Error for DoesNotFit {}

/// When a plan would fit with a small image but not with `input.image`: the largest image of
/// the same shape that fits (the image, not the volume, is the cause).
pub(super) fn image_that_fits(
    effects: Effects,
    input: &PlanInput,
    sizes: &dyn ImageSizes,
) -> Option<([u32; 2], [u32; 2])> {
    let [w, h] = input.image;
    let long = w.max(h).max(1);
    let shaped = |side: u32| -> [u32; 2] {
        let scale = f64::from(side) / f64::from(long);
        [w, h].map(|s| ((f64::from(s) * scale).floor() as u32).max(1))
    };
    let fits_at = |side: u32| {
        let at = PlanInput {
            image: shaped(side),
            ..*input
        };
        plan_with(effects, &at, sizes, false).is_ok()
    };
    // The smallest picture anyone renders; not even that fits: the volume is the cause.
    let small = 64.min(long);
    if small == long || !fits_at(small) {
        return None;
    }
    let (mut good, mut bad) = (small, long);
    while bad - good > 1 {
        let mid = good + (bad - good) / 2;
        if fits_at(mid) {
            good = mid;
        } else {
            bad = mid;
        }
    }
    Some((input.image, shaped(good)))
}

/// The error for a plan whose smallest form, `smallest`, still exceeds the budget.
pub(super) fn does_not_fit(input: &PlanInput, smallest: &Plan) -> DoesNotFit {
    let current = smallest;
    let over_budget = current.peak_bytes > input.budget;
    let limit = bricking_limit(input.dims);
    let over_bricking = current.layout != Layout::Whole && current.peak_bytes > limit;
    let mut limits = Vec::new();
    if over_budget || !over_bricking {
        limits.push(format!(
            "does not fit the memory budget of {} bytes",
            input.budget
        ));
    }
    if over_bricking {
        let why = if input.dims.iter().any(|&d| d > input.max_image_dimension_3d) {
            format!(
                "exceeds the device's 3D image limit of {} whole, ",
                input.max_image_dimension_3d
            )
        } else {
            String::new()
        };
        limits.push(format!(
            "{why}cannot be bricked within {limit} bytes ({BRICKING_MAX_RATIO}x its R16 size plus \
             {} MiB: a volume thinner than a {STORAGE_BRICK}-voxel brick leaves most of every \
             {}^3 slot empty)",
            BRICKING_SLACK >> 20,
            STORAGE_BRICK + 2 * STORAGE_HALO
        ));
    }
    DoesNotFit {
        dims: input.dims,
        volume_bytes: 2 * voxels(input.dims),
        budget: input.budget,
        limit: limits.join(" and "),
        smallest_plan: format!(
            "{:?}, {}, {:?} gradients",
            current.normalized_format,
            match current.layout {
                Layout::Whole => "whole volume".to_string(),
                Layout::Bricked { resident, .. } => format!("{resident} resident bricks"),
            },
            current.effects.gradient_source
        ),
        smallest_bytes: current.peak_bytes,
        image: None,
    }
}
