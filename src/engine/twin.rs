//! A digital twin: a prepared volume with exactly the derived volumes its current scene needs.
//!
//! Decisions:
//! - The scene's effects decide the derived volumes (`Effects::derivative_outputs`); tissues,
//!   windows, camera and background are uniforms and never touch them. [`Engine::update_twin`]
//!   compares what the twin holds with what the effects need and does the least that makes them
//!   equal: nothing; or drop the normals image (shading turned off: the gradient image is
//!   unchanged); or drop every derived volume (MIP / MinIP); or recompute.
//! - Recomputing frees the old derived volumes first, so a change of plan never holds both sets
//!   (the peak stays the larger plan's, which the budget already covered). The derivative pipeline
//!   of each variant stays cached in the engine, so switching back costs one dispatch, not a
//!   compile.
//! - The twin reports what each update did ([`TwinUpdate`]) so integrators and tests can check it.
//! - The rule itself is [`twin_step`], a pure function, so a client that computes derived volumes
//!   elsewhere (the viewer, on its loader thread) follows the same rule: it applies the steps
//!   that need no GPU work at once ([`Twin::apply`]) and installs a recomputation's result when
//!   it arrives ([`Twin::install`]). The prepared volume is shared (`Arc`) for that.

use super::Engine;
use super::derive::Derived;
use super::prepare::PreparedVolume;
use super::render::{Frame, RenderTarget};
use crate::gpu::GpuResult;
use crate::passes::derivatives::DerivativeOutputs;
use crate::scene::{Effects, Scene};
use std::sync::Arc;

/// A prepared volume and the derived volumes of its current effects.
pub struct Twin {
    /// The normalized volume with its histogram (shared with a thread that derives from it).
    pub prepared: Arc<PreparedVolume>,
    derived: Option<Derived>,
}

/// What [`Engine::update_twin`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TwinUpdate {
    /// A derivative pass ran (new outputs, precision or first use).
    pub recomputed: bool,
    /// Derived images were freed.
    pub freed: bool,
}

impl Twin {
    /// A twin of `prepared` with no derived volumes yet.
    pub fn new(prepared: impl Into<Arc<PreparedVolume>>) -> Twin {
        Twin {
            prepared: prepared.into(),
            derived: None,
        }
    }

    /// The derived volumes held now (None before the first update, or for MIP / MinIP).
    pub fn derived(&self) -> Option<&Derived> {
        self.derived.as_ref()
    }

    /// The derived outputs held now.
    pub fn outputs(&self) -> Option<DerivativeOutputs> {
        self.derived.as_ref().map(|d| d.volumes.outputs)
    }
}

/// What the update rule does to bring held derived volumes in line with wanted ones.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TwinStep {
    /// They are equal already (or neither exists).
    Keep,
    /// Free every derived volume (MIP / MinIP need none).
    FreeAll,
    /// Free the normals image only (shading turned off).
    DropNormals,
    /// Compute these outputs (after freeing what is held).
    Recompute(DerivativeOutputs),
}

/// The twin's update rule (module decisions): the least that makes `held` equal `wanted`.
pub fn twin_step(held: Option<DerivativeOutputs>, wanted: Option<DerivativeOutputs>) -> TwinStep {
    match (held, wanted) {
        (h, w) if h == w => TwinStep::Keep,
        (Some(_), None) => TwinStep::FreeAll,
        (Some(h), Some(w)) if only_normals_dropped(h, w) => TwinStep::DropNormals,
        (_, Some(w)) => TwinStep::Recompute(w),
        (None, None) => TwinStep::Keep,
    }
}

/// True when `held` can serve `wanted` by dropping the normals image only.
fn only_normals_dropped(held: DerivativeOutputs, wanted: DerivativeOutputs) -> bool {
    held.normal
        && !wanted.normal
        && held.magnitude == wanted.magnitude
        && held.curvature == wanted.curvature
        && held.precision == wanted.precision
        && held.vesselness == wanted.vesselness
}

impl Twin {
    /// Applies a step that needs no GPU work (`Keep`, `FreeAll`, `DropNormals`); a
    /// `Recompute` frees what is held (the result comes with [`Twin::install`]).
    pub fn apply(&mut self, step: TwinStep) -> TwinUpdate {
        let held = self.derived.is_some();
        match step {
            TwinStep::Keep => TwinUpdate::default(),
            TwinStep::FreeAll | TwinStep::Recompute(_) => {
                self.derived = None;
                TwinUpdate {
                    recomputed: false,
                    freed: held,
                }
            }
            TwinStep::DropNormals => {
                if let Some(d) = &mut self.derived {
                    d.volumes.normal = None;
                    d.volumes.outputs.normal = false;
                }
                TwinUpdate {
                    recomputed: false,
                    freed: held,
                }
            }
        }
    }

    /// Installs derived volumes of this twin's prepared volume computed elsewhere (the result
    /// of a `Recompute` step), replacing what was held.
    pub fn install(&mut self, derived: Derived) {
        self.derived = None;
        self.derived = Some(derived);
    }

    /// True when the held derived volumes can render `effects` as they are: the raymarch
    /// reads only what the effects use, so a superset of the same precision serves.
    pub fn serves(&self, effects: &Effects) -> bool {
        let Some(need) = effects.derivative_outputs() else {
            return true;
        };
        self.outputs().is_some_and(|have| {
            have.precision == need.precision
                && (have.magnitude || !need.magnitude)
                && (have.curvature || !need.curvature)
                && (have.normal || !need.normal)
                && (have.vesselness || !need.vesselness)
        })
    }
}

impl Engine {
    /// Brings `twin`'s derived volumes in line with `effects`: computes what is missing and frees
    /// what is no longer needed (see the module's decisions).
    pub fn update_twin(&mut self, twin: &mut Twin, effects: &Effects) -> GpuResult<TwinUpdate> {
        let held = twin.outputs();
        match twin_step(held, effects.derivative_outputs()) {
            TwinStep::Recompute(w) => {
                // Free first: the old and new derived volumes are never held together.
                twin.apply(TwinStep::FreeAll);
                twin.derived = Some(self.derive(&twin.prepared, w)?);
                Ok(TwinUpdate {
                    recomputed: true,
                    freed: held.is_some(),
                })
            }
            step => Ok(twin.apply(step)),
        }
    }

    /// Updates `twin` for `scene`'s effects, then renders the scene into `target`.
    pub fn render_twin(
        &mut self,
        target: &mut RenderTarget,
        twin: &mut Twin,
        scene: &Scene,
    ) -> GpuResult<Frame> {
        self.update_twin(twin, &scene.effects)?;
        self.render(target, &twin.prepared, twin.derived.as_ref(), scene)
    }

    /// [`Engine::render_twin`] with the pixels copied into `out`, a buffer the caller owns (see
    /// [`Engine::render_into`]).
    pub fn render_twin_into(
        &mut self,
        target: &mut RenderTarget,
        twin: &mut Twin,
        scene: &Scene,
        out: &mut [u8],
    ) -> GpuResult<Frame> {
        self.update_twin(twin, &scene.effects)?;
        self.render_into(target, &twin.prepared, twin.derived.as_ref(), scene, out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::DerivedPrecision;

    fn o(magnitude: bool, curvature: bool, normal: bool) -> DerivativeOutputs {
        DerivativeOutputs {
            magnitude,
            curvature,
            normal,
            precision: DerivedPrecision::Snorm8,
            vesselness: false,
            brain: crate::passes::brain::BrainSwitch::Off,
        }
    }

    #[test]
    fn the_rule_does_the_least_that_makes_held_equal_wanted() {
        let all = o(true, true, true);
        assert_eq!(twin_step(Some(all), Some(all)), TwinStep::Keep);
        assert_eq!(twin_step(None, None), TwinStep::Keep);
        assert_eq!(twin_step(Some(all), None), TwinStep::FreeAll);
        assert_eq!(
            twin_step(Some(all), Some(o(true, true, false))),
            TwinStep::DropNormals
        );
        // Curvature off frees its memory by recomputing the smaller set (never both held).
        let magnitude = o(true, false, false);
        assert_eq!(
            twin_step(Some(o(true, true, false)), Some(magnitude)),
            TwinStep::Recompute(magnitude)
        );
        assert_eq!(
            twin_step(None, Some(magnitude)),
            TwinStep::Recompute(magnitude)
        );
        let f16 = DerivativeOutputs {
            precision: DerivedPrecision::F16,
            ..all
        };
        assert_eq!(twin_step(Some(all), Some(f16)), TwinStep::Recompute(f16));
    }
}
