//! Label overlays in the 3D raymarch (issue 16 item 3): a label map on the volume's grid on the
//! GPU, and the colours the raymarch draws its labels with (`shaders/include/labels.glsl`).
//!
//! Decisions:
//! - The labels are a storage buffer of u16 (two a word), not a 3D image: a sample reads its
//!   nearest voxel's label with one load, integer formats cannot be filtered anyway, and no
//!   sampler or image placeholder is needed (the engine's 16-byte buffer stands in). 2 bytes a
//!   voxel, uploaded once per overlay and volume like the samples (staged, or written straight
//!   into host-visible memory on unified-memory devices).
//! - Whole volumes only: a bricked volume's textures are atlases the label buffer does not
//!   follow, so [`Engine::upload_labels`] refuses it with a typed error naming the way out.
//! - Colours are a lookup table of one RGBA8 word per label value up to the largest label
//!   present (alpha = the label's opacity per mm times the overlay's opacity; 0 for hidden
//!   labels), at most 256 KiB. A client changes it as often as it likes
//!   ([`RenderTarget::set_label_colours`]); the target writes it into the buffer of the frame
//!   slot being recorded only when it changed, as it does with the occupancy bits, so a frame in
//!   flight never reads a table being rewritten.
//! - Empty-space skipping stays lossless: every 8^3 brick holding any non-zero label counts as
//!   occupied (computed once, here, on the CPU), whatever the tissue windows say.

use super::Engine;
use super::prepare::{PreparedVolume, VolumeLayout};
use super::render::RenderTarget;
use super::upload::upload_samples;
use crate::gpu::{Buffer, GpuError, GpuResult, Recording};
use crate::passes::occupancy::BRICK_SIDE;
use crate::scene::overlay::{LabelTable, Labels};
use crate::volume::Samples;
use std::collections::BTreeSet;
use std::sync::Arc;

/// A label map on the GPU, on the grid of the volume it was resampled onto.
pub struct LabelVolume {
    pub(super) values: Arc<Buffer>,
    /// The volume's dimensions.
    pub dims: [usize; 3],
    /// One bit per 8^3 brick (the occupancy grid's order), set where any voxel has a label.
    pub(super) brick_bits: Arc<Vec<u32>>,
    /// The distinct non-zero labels present, ascending.
    pub present: Vec<u16>,
}

/// A label overlay attached to a render target: the labels and their colour table.
pub(super) struct AttachedLabels {
    pub(super) volume: Arc<LabelVolume>,
    pub(super) colours: Vec<u32>,
    // Grows with every new table, so each frame slot's buffer is rewritten once per change.
    pub(super) generation: u64,
}

/// One bit per `BRICK_SIDE`^3 brick of a `dims` grid (x fastest), set where a label is non-zero.
pub fn label_brick_bits(labels: &Labels) -> Vec<u32> {
    let grid = labels.dims.map(|d| d.div_ceil(BRICK_SIDE as usize).max(1));
    let mut bits = vec![0u32; (grid[0] * grid[1] * grid[2]).div_ceil(32)];
    let [nx, ny, _] = labels.dims;
    for (index, &label) in labels.values.iter().enumerate() {
        if label == 0 {
            continue;
        }
        let (i, j, k) = (index % nx, (index / nx) % ny, index / (nx * ny));
        let side = BRICK_SIDE as usize;
        let b = i / side + grid[0] * (j / side + grid[1] * (k / side));
        bits[b >> 5] |= 1 << (b & 31);
    }
    bits
}

/// The colour table of an overlay: RGBA8 per label value 0..=max present label (little-endian
/// words as GLSL's `unpackUnorm4x8` reads them), alpha = the label's opacity times `opacity`,
/// 0 for label 0 and for `hidden` labels.
pub fn label_colours(
    table: &LabelTable,
    present: &[u16],
    opacity: f64,
    hidden: &BTreeSet<u16>,
) -> Vec<u32> {
    let len = present.last().map_or(1, |&max| usize::from(max) + 1);
    let mut words = vec![0u32; len];
    for &label in present {
        if hidden.contains(&label) {
            continue;
        }
        let style = table.style(label);
        let alpha = ((style.opacity * opacity).clamp(0.0, 1.0) * 255.0).round() as u32;
        let [r, g, b] = style.rgb.map(u32::from);
        words[usize::from(label)] = r | (g << 8) | (b << 16) | (alpha << 24);
    }
    words
}

impl Engine {
    /// Uploads `labels` (resampled onto `prepared`'s grid) for drawing in the 3D raymarch.
    pub fn upload_labels(
        &mut self,
        prepared: &PreparedVolume,
        labels: &Labels,
    ) -> GpuResult<LabelVolume> {
        if matches!(prepared.layout, VolumeLayout::Bricked(_)) {
            return Err(GpuError::InvalidRequest(
                "a label overlay is drawn in 3D on whole volumes only; this one is bricked (run without --bricked or with a larger --memory-budget)".into(),
            ));
        }
        let dims = prepared.dims.map(|d| d as usize);
        if labels.dims != dims || labels.values.len() != dims.iter().product::<usize>() {
            return Err(GpuError::InvalidRequest(format!(
                "the labels are on a {:?} grid, the volume on {dims:?}; resample them onto the volume first",
                labels.dims
            )));
        }
        let mut rec = Recording::new(&self.device, "labels")?;
        let (values, _) =
            upload_samples(&self.device, &mut rec, &Samples::from_u16(&labels.values))?;
        rec.submit()?.wait()?;
        Ok(LabelVolume {
            values,
            dims,
            brick_bits: Arc::new(label_brick_bits(labels)),
            present: labels.present(),
        })
    }
}

/// What the raymarch binds for labels: their values, this frame slot's colour table, and the
/// bricks they occupy (None when no labels are drawn: placeholders are bound).
type LabelInputs = (Arc<Buffer>, Arc<Buffer>, Option<Arc<Vec<u32>>>);

impl Engine {
    /// The label bindings of the frame recorded into `target`'s `frame_slot`: the attached
    /// labels in a DVR frame (the colour table written into the slot's buffer if it changed
    /// since the slot last held one), placeholders otherwise.
    pub(super) fn label_inputs(
        &self,
        target: &mut RenderTarget,
        prepared: &PreparedVolume,
        scene: &crate::scene::Scene,
        frame_slot: usize,
    ) -> GpuResult<LabelInputs> {
        let placeholder = self.placeholders.occupancy.clone();
        let dvr = scene.effects.mode == crate::scene::RenderMode::Dvr;
        let Some(attached) = target.labels.as_ref().filter(|_| dvr) else {
            return Ok((placeholder.clone(), placeholder, None));
        };
        let dims = prepared.dims.map(|d| d as usize);
        if attached.volume.dims != dims || matches!(prepared.layout, VolumeLayout::Bricked(_)) {
            return Err(GpuError::InvalidRequest(format!(
                "the label overlay was uploaded for a whole {:?} volume; this one is {dims:?}{}",
                attached.volume.dims,
                if matches!(prepared.layout, VolumeLayout::Bricked(_)) {
                    ", bricked"
                } else {
                    ""
                }
            )));
        }
        let bytes: &[u8] = bytemuck::cast_slice(&attached.colours);
        let buffer = match &target.label_colour_buffers[frame_slot] {
            Some(b) if b.size() >= bytes.len() as u64 => b.clone(),
            _ => {
                let desc = crate::gpu::BufferDesc::host_storage(
                    "label colours",
                    (bytes.len() as u64).max(16),
                );
                let b = Buffer::new(&self.device, desc)?;
                target.label_colour_buffers[frame_slot] = Some(b.clone());
                target.label_colours_written[frame_slot] = 0;
                b
            }
        };
        // Host writes before the submission that reads them; the other frame slot's buffer,
        // which a frame in flight may read, is untouched.
        if target.label_colours_written[frame_slot] != attached.generation {
            buffer.write(0, bytes)?;
            target.label_colours_written[frame_slot] = attached.generation;
        }
        Ok((
            attached.volume.values.clone(),
            buffer,
            Some(attached.volume.brick_bits.clone()),
        ))
    }
}

impl RenderTarget {
    /// Draws `labels` with `colours` (see [`label_colours`]) in this target's DVR frames from
    /// the next recording on; None stops drawing them.
    pub fn set_labels(&mut self, labels: Option<(Arc<LabelVolume>, Vec<u32>)>) {
        let generation = self.labels.as_ref().map_or(0, |l| l.generation) + 1;
        self.labels = labels.map(|(volume, colours)| AttachedLabels {
            volume,
            colours,
            generation,
        });
    }

    /// Replaces the colour table of the attached labels (a label shown or hidden, another
    /// opacity); nothing without labels.
    pub fn set_label_colours(&mut self, colours: Vec<u32>) {
        if let Some(attached) = &mut self.labels
            && attached.colours != colours
        {
            attached.colours = colours;
            attached.generation += 1;
        }
    }

    /// Draws `labels` with `colours`, or nothing (None): [`RenderTarget::set_labels`] for other
    /// labels, [`RenderTarget::set_label_colours`] for the attached ones, so a client may call it
    /// every frame and the table is written only when it changes.
    pub fn show_labels(&mut self, labels: Option<(&Arc<LabelVolume>, Vec<u32>)>) {
        match (labels, &self.labels) {
            (Some((volume, colours)), Some(attached)) if Arc::ptr_eq(volume, &attached.volume) => {
                self.set_label_colours(colours)
            }
            (Some((volume, colours)), _) => self.set_labels(Some((volume.clone(), colours))),
            (None, _) => self.labels = None,
        }
    }

    /// Whether a label overlay is attached.
    pub fn has_labels(&self) -> bool {
        self.labels.is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bricks_with_any_label_are_marked_and_colours_pack_as_glsl_reads_them() {
        // 10x9x3: bricks 2x2x1; a label at voxel (9, 8, 2) lies in brick (1, 1, 0) = bit 3.
        let mut values = vec![0u16; 10 * 9 * 3];
        values[9 + 10 * (8 + 9 * 2)] = 7;
        let labels = Labels {
            dims: [10, 9, 3],
            values,
        };
        assert_eq!(label_brick_bits(&labels), vec![0b1000]);
        let mut table = LabelTable::default();
        let style = crate::scene::overlay::LabelStyle {
            rgb: [255, 128, 1],
            opacity: 0.5,
        };
        table.entries.insert(7, ("x".into(), style));
        let words = label_colours(&table, &[3, 7], 1.0, &BTreeSet::from([3]));
        assert_eq!(words.len(), 8);
        assert_eq!(words[3], 0, "hidden");
        assert_eq!(words[0], 0, "background");
        assert_eq!(words[7], 255 | (128 << 8) | (1 << 16) | (128 << 24));
    }
}
