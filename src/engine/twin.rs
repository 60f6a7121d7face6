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

use super::Engine;
use super::derive::Derived;
use super::prepare::PreparedVolume;
use super::render::{Frame, RenderTarget};
use crate::gpu::GpuResult;
use crate::passes::derivatives::DerivativeOutputs;
use crate::scene::{Effects, Scene};

/// A prepared volume and the derived volumes of its current effects.
pub struct Twin {
    /// The normalized volume with its histogram.
    pub prepared: PreparedVolume,
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
    pub fn new(prepared: PreparedVolume) -> Twin {
        Twin {
            prepared,
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

/// True when `held` can serve `wanted` by dropping the normals image only.
fn only_normals_dropped(held: DerivativeOutputs, wanted: DerivativeOutputs) -> bool {
    held.normal
        && !wanted.normal
        && held.magnitude == wanted.magnitude
        && held.curvature == wanted.curvature
        && held.precision == wanted.precision
}

impl Engine {
    /// Brings `twin`'s derived volumes in line with `effects`: computes what is missing and frees
    /// what is no longer needed (see the module's decisions).
    pub fn update_twin(&mut self, twin: &mut Twin, effects: &Effects) -> GpuResult<TwinUpdate> {
        let wanted = effects.derivative_outputs();
        let held = twin.outputs();
        match (held, wanted) {
            (h, w) if h == w => Ok(TwinUpdate::default()),
            (Some(_), None) => {
                twin.derived = None;
                Ok(TwinUpdate {
                    recomputed: false,
                    freed: true,
                })
            }
            (Some(h), Some(w)) if only_normals_dropped(h, w) => {
                if let Some(d) = &mut twin.derived {
                    d.volumes.normal = None;
                    d.volumes.outputs.normal = false;
                }
                Ok(TwinUpdate {
                    recomputed: false,
                    freed: true,
                })
            }
            (h, Some(w)) => {
                // Free first: the old and new derived volumes are never held together.
                twin.derived = None;
                twin.derived = Some(self.derive(&twin.prepared, w)?);
                Ok(TwinUpdate {
                    recomputed: true,
                    freed: h.is_some(),
                })
            }
            (None, None) => Ok(TwinUpdate::default()),
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
