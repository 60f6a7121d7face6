//! The twin of the raymarch's LONG_STEPS (issue 17 item 2): in a brick whose opacity bound is
//! below the threshold, one sample stands for up to `factor` lattice samples, never past the
//! brick's last lattice sample; the sample's opacity exponent is `span * r`.
//!
//! Decision: the twin takes no empty-space skipping of its own (skipping is lossless: the samples
//! it drops have zero opacity), so it applies the span in every brick below the threshold,
//! empty ones included; there every sample has zero opacity, so the image is the same as the
//! shader's, which jumps over empty bricks. Brick and exit are computed as in the shader
//! (`brick_at`, `brick_exit`), in f64.

use super::RayPlan;
use crate::scene::geometry::MIN_DIRECTION;

/// Per-brick opacity bounds and the long-step setting, for [`super::ReferenceRaymarch`].
#[derive(Clone, Copy, Debug)]
pub struct ReferenceLongSteps<'a> {
    /// Brick grid.
    pub grid: [u32; 3],
    /// Brick side in voxels.
    pub side: u32,
    /// Opacity bound per brick, x fastest (`BrickRanges::reference_bounds`).
    pub bounds: &'a [f64],
    /// Lattice samples one long step stands for.
    pub factor: u32,
    /// Bound per mm below which a brick takes long steps.
    pub threshold: f64,
}

impl ReferenceLongSteps<'_> {
    /// How many lattice samples sample `i` of `plan` stands for (1 outside low bricks).
    pub fn span(&self, plan: &RayPlan, i: u32) -> u32 {
        let p = plan.position(i);
        let side = f64::from(self.side);
        let brick: [u32; 3] = std::array::from_fn(|a| {
            let b = ((p[a] + 0.5) / side).floor();
            b.clamp(0.0, f64::from(self.grid[a].max(1) - 1)) as u32
        });
        let index = brick[0] + self.grid[0] * (brick[1] + self.grid[1] * brick[2]);
        let bound = self
            .bounds
            .get(index as usize)
            .copied()
            .unwrap_or(f64::INFINITY);
        if bound >= self.threshold {
            return 1;
        }
        let mut t_exit = f64::MAX;
        for (a, &b) in brick.iter().enumerate() {
            let d = plan.direction[a];
            if d.abs() >= MIN_DIRECTION {
                let lo = f64::from(b) * side - 0.5;
                let face = if d > 0.0 { lo + side } else { lo };
                t_exit = t_exit.min((face - plan.origin[a]) / d);
            }
        }
        let last = ((t_exit - plan.start) / plan.step_mm).floor().clamp(
            f64::from(i),
            f64::from(plan.count.saturating_sub(1)).max(f64::from(i)),
        ) as u32;
        self.factor.max(1).min(last - i + 1)
    }
}
