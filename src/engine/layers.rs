//! Intensity layers in the 3D raymarch (issue 31 item 4): each layer's voxels on its own grid
//! in a 3D image, the per-frame colour tables and uniforms, and the bricks they may draw in
//! (`shaders/include/layers.glsl`; the f64 twin is `reference/raymarch/layers.rs`).
//!
//! Decisions:
//! - **Resampled on the GPU, per sample**: the layer keeps its grid (R16_UNORM codes,
//!   `scene::layer_grid`), and the raymarch maps each sample's base index position through one
//!   matrix (base index -> layer texture coordinates, both affines composed in f64 here) and
//!   filters it trilinearly. A 2 mm z-map on a 1 mm T1 costs its own 2 bytes a voxel, not the
//!   T1's grid, and a window or threshold change is a uniform write.
//! - **Composited per sample, by depth**: a layer's sample is a medium of its own just before
//!   the tissue's (and a label's) at the same position, so a blob inside the brain shows through
//!   translucent tissue, hides behind opaque cortex in front of it, and colours the surface and
//!   the cut faces it reaches (intermixing, not painting on top).
//! - **Skipping stays lossless**: a base brick counts as occupied when any drawn layer voxel's
//!   trilinear footprint (its neighbours up to one voxel away) maps into it; computed on the
//!   host per style change over 4^3 blocks of the layer, ORed with the label bits.
//! - Attached to a render target like labels (`RenderTarget::set_layers`), bound to the whole
//!   volume it was uploaded for; the colour tables are one host buffer per frame slot, rewritten
//!   when the styles change (`host_slots.rs`).

use super::Engine;
use super::host_slots::HostSlots;
use super::prepare::{PreparedVolume, VolumeLayout};
use super::render::RenderTarget;
use crate::gpu::{Access, Buffer, BufferDesc, GpuError, GpuResult, Image, ImageDesc, Recording};
use crate::passes::occupancy::BRICK_SIDE;
use crate::scene::layer::{LAYER_LUT_ENTRIES, LayerStyle, MAX_LAYERS};
use crate::scene::layer_grid::{LayerCodes, LayerGrid};
use ash::vk;
use glam::{DMat4, DVec3, DVec4};
use std::sync::Arc;

/// A layer on the GPU, for one base volume.
pub struct LayerVolume {
    pub(super) image: Arc<Image>,
    /// The layer's voxels (as drawn: clusters removed) and their codes, for the brick bits.
    pub grid: Arc<LayerGrid>,
    pub(super) codes: Arc<LayerCodes>,
    /// Base index position -> layer index position.
    pub index_map: DMat4,
    /// The base volume's dimensions.
    pub base_dims: [u32; 3],
}

/// The layers drawn in a render target, with their styles.
#[derive(Default)]
pub(super) struct AttachedLayers {
    pub(super) layers: Vec<(Arc<LayerVolume>, LayerStyle)>,
    // Grows with every change, so colour tables and brick bits are remade once per change.
    pub(super) generation: u64,
    // The layers' own brick bits of a generation (the raymarch's gate on the layer fetch).
    pub(super) own_bits: Option<(u64, Arc<Vec<u32>>)>,
    // The brick bits of a generation, with the label bits they were merged with.
    pub(super) bits: Option<MergedBits>,
    pub(super) colours: HostSlots<u64>,
    pub(super) brick_buffers: HostSlots<u64>,
}

/// Brick bits of the layers of one generation ORed with the label bits (the second field).
pub(super) type MergedBits = (u64, Option<Arc<Vec<u32>>>, Arc<Vec<u32>>);

/// The plan's description of one frame slot's layer brick bits for a base volume of `dims`.
pub fn layer_bricks_desc(dims: [u32; 3]) -> BufferDesc {
    let [x, y, z, _] = brick_grid(dims);
    let words = (x as u64 * y as u64 * z as u64).div_ceil(32).max(4);
    BufferDesc::host_storage("layer bricks", 4 * words)
}

/// The brick grid of a base volume of `dims` (the occupancy grid's) and the brick side.
fn brick_grid(dims: [u32; 3]) -> [u32; 4] {
    let [x, y, z] = dims.map(|d| d.div_ceil(BRICK_SIDE).max(1));
    [x, y, z, BRICK_SIDE]
}

/// The plan's description of one frame slot's layer colour tables.
pub fn layer_colours_desc() -> BufferDesc {
    BufferDesc::host_storage(
        "layer colours",
        (MAX_LAYERS * 2 * LAYER_LUT_ENTRIES * 4) as u64,
    )
}

/// The layer uniforms of one frame (`Params` in raymarch.comp): per layer the base index ->
/// texture coordinate matrix, the window (lo, hi, threshold, opacity) and the decode (value of
/// code 0, scale, negative side 1/0).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LayerUniforms {
    /// Column-major matrices.
    pub to_texture: [[[f32; 4]; 4]; MAX_LAYERS],
    /// lo, hi, threshold, opacity.
    pub window: [[f32; 4]; MAX_LAYERS],
    /// Value of code 0, value span of the codes, negative side drawn, 0.
    pub decode: [[f32; 4]; MAX_LAYERS],
    /// The base volume's brick grid (xyz) and brick side (w) of the layer brick bits.
    pub bricks: [u32; 4],
}

/// What the raymarch binds for layers this frame.
pub(super) struct LayerInputs {
    pub(super) count: u32,
    pub(super) images: [Arc<Image>; MAX_LAYERS],
    pub(super) colours: Arc<Buffer>,
    /// One bit per base brick where a layer may draw (`layer_brick_bits`).
    pub(super) bricks: Arc<Buffer>,
    pub(super) uniforms: LayerUniforms,
}

impl Engine {
    /// Uploads `grid` (its values as they are drawn: clusters already removed) for drawing over
    /// `prepared` (a whole volume).
    pub fn upload_layer(
        &mut self,
        prepared: &PreparedVolume,
        grid: LayerGrid,
    ) -> GpuResult<LayerVolume> {
        if matches!(prepared.layout, VolumeLayout::Bricked(_)) {
            return Err(GpuError::InvalidRequest(
                "a layer is drawn in 3D over whole volumes only; this one is bricked (run without --bricked or with a larger --memory-budget)".into(),
            ));
        }
        let codes = grid.codes();
        let extent = grid.dims.map(|d| d as u32);
        let desc = ImageDesc::volume(
            &format!("layer {}", grid.name),
            extent,
            vk::Format::R16_UNORM,
        );
        let image = Image::new(&self.device, desc)?;
        let bytes: &[u8] = bytemuck::cast_slice(&codes.codes);
        let staging = Buffer::new(
            &self.device,
            BufferDesc::staging("layer upload", bytes.len() as u64),
        )?;
        staging.write(0, bytes)?;
        let mut rec = Recording::new(&self.device, "layer upload")?;
        // A fresh image: moves it to TRANSFER_DST for the copy.
        rec.barriers(&[], &[(&image, Access::Nothing, Access::TransferWrite)]);
        rec.copy_buffer_to_image(&staging, &image);
        // Orders the copy before every raymarch that samples the layer.
        rec.barriers(
            &[],
            &[(&image, Access::TransferWrite, Access::ComputeSampled)],
        );
        rec.submit()?.wait()?;
        Ok(LayerVolume {
            image,
            index_map: grid.index_map(&prepared.affine),
            grid: Arc::new(grid),
            codes: Arc::new(codes),
            base_dims: prepared.dims,
        })
    }

    /// The layer bindings and uniforms of the frame recorded into `target`'s `frame_slot`
    /// (placeholders and a count of 0 without layers or outside DVR).
    pub(super) fn layer_inputs(
        &self,
        target: &mut RenderTarget,
        prepared: &PreparedVolume,
        dvr: bool,
        frame_slot: usize,
    ) -> GpuResult<LayerInputs> {
        let placeholder = self.placeholders.gradient.clone();
        let attached = &mut target.layers;
        if !dvr || attached.layers.is_empty() {
            return Ok(LayerInputs {
                count: 0,
                images: [placeholder.clone(), placeholder],
                colours: self.placeholders.occupancy.clone(),
                bricks: self.placeholders.occupancy.clone(),
                uniforms: LayerUniforms::default(),
            });
        }
        if let Some((layer, _)) = attached
            .layers
            .iter()
            .find(|(l, _)| l.base_dims != prepared.dims)
        {
            return Err(GpuError::InvalidRequest(format!(
                "the layer {} was uploaded for a {:?} volume; this one is {:?}",
                layer.grid.name, layer.base_dims, prepared.dims
            )));
        }
        let generation = attached.generation;
        let words = colour_words(&attached.layers);
        let colours = attached.colours.current(
            &self.device,
            frame_slot,
            layer_colours_desc,
            |held| *held == generation,
            generation,
            |buffer| buffer.write(0, bytemuck::cast_slice(&words)),
        )?;
        let bits = attached.own_bits(prepared.dims);
        let bricks = attached.brick_buffers.current(
            &self.device,
            frame_slot,
            || layer_bricks_desc(prepared.dims),
            |held| *held == generation,
            generation,
            |buffer| buffer.write(0, bytemuck::cast_slice(&bits)),
        )?;
        let mut images = [placeholder.clone(), placeholder];
        for (slot, (layer, _)) in attached.layers.iter().enumerate() {
            images[slot] = layer.image.clone();
        }
        let mut uniforms = layer_uniforms(&attached.layers);
        uniforms.bricks = brick_grid(prepared.dims);
        Ok(LayerInputs {
            count: attached.layers.len() as u32,
            images,
            colours,
            bricks,
            uniforms,
        })
    }
}

/// Both colour tables of every layer, layer after layer (positive, then negative).
fn colour_words(layers: &[(Arc<LayerVolume>, LayerStyle)]) -> Vec<u32> {
    let mut words = vec![0u32; MAX_LAYERS * 2 * LAYER_LUT_ENTRIES];
    for (slot, (_, style)) in layers.iter().enumerate() {
        let tables = style.tables();
        let at = slot * 2 * LAYER_LUT_ENTRIES;
        words[at..at + LAYER_LUT_ENTRIES].copy_from_slice(&tables.positive);
        words[at + LAYER_LUT_ENTRIES..at + 2 * LAYER_LUT_ENTRIES].copy_from_slice(&tables.negative);
    }
    words
}

/// The uniforms of `layers` (module decisions).
pub fn layer_uniforms(layers: &[(Arc<LayerVolume>, LayerStyle)]) -> LayerUniforms {
    let mut u = LayerUniforms::default();
    for (slot, (layer, style)) in layers.iter().enumerate().take(MAX_LAYERS) {
        let dims = DVec3::from_array(layer.grid.dims.map(|d| d as f64));
        // Layer index q -> texture coordinate (q + 0.5) / dims.
        let to_unit = DMat4::from_scale(dims.recip()) * DMat4::from_translation(DVec3::splat(0.5));
        u.to_texture[slot] = (to_unit * layer.index_map).as_mat4().to_cols_array_2d();
        u.window[slot] = [
            style.lo as f32,
            style.hi as f32,
            style.threshold as f32,
            style.opacity as f32,
        ];
        u.decode[slot] = [
            layer.codes.lo as f32,
            layer.codes.scale as f32,
            f32::from(u8::from(style.negative.is_some())),
            0.0,
        ];
    }
    u
}

/// One bit per base brick (the occupancy grid's order) where a drawn voxel of any layer can
/// reach a sample (module decisions), for a base volume of `dims`.
pub fn layer_brick_bits(layers: &[(Arc<LayerVolume>, LayerStyle)], dims: [u32; 3]) -> Vec<u32> {
    let side = f64::from(BRICK_SIDE);
    let grid = dims.map(|d| d.div_ceil(BRICK_SIDE).max(1) as usize);
    let mut bits = vec![0u32; (grid[0] * grid[1] * grid[2]).div_ceil(32)];
    for (layer, style) in layers {
        let to_base = layer.index_map.inverse();
        for (lo, hi) in drawn_blocks(&layer.grid, style) {
            let (mut min, mut max) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
            for corner in 0..8 {
                let c = DVec3::new(
                    if corner & 1 == 0 { lo.x } else { hi.x },
                    if corner & 2 == 0 { lo.y } else { hi.y },
                    if corner & 4 == 0 { lo.z } else { hi.z },
                );
                let p = (to_base * DVec4::from((c, 1.0))).truncate();
                min = min.min(p);
                max = max.max(p);
            }
            let first = ((min + 0.5) / side).floor();
            let last = ((max + 0.5) / side).floor();
            if (0..3).any(|a| last[a] < 0.0 || first[a] > (grid[a] - 1) as f64) {
                continue;
            }
            let range = |a: usize| {
                (first[a].max(0.0) as usize)..=(last[a].min((grid[a] - 1) as f64) as usize)
            };
            for k in range(2) {
                for j in range(1) {
                    for i in range(0) {
                        let b = i + grid[0] * (j + grid[1] * k);
                        bits[b >> 5] |= 1 << (b & 31);
                    }
                }
            }
        }
    }
    bits
}

/// The layer index boxes (lo, hi corners) of the 4^3 blocks holding a drawn voxel, grown by the
/// one voxel a trilinear sample reaches.
fn drawn_blocks(grid: &LayerGrid, style: &LayerStyle) -> Vec<(DVec3, DVec3)> {
    const BLOCK: usize = 4;
    let [nx, ny, _] = grid.dims;
    let blocks = grid.dims.map(|d| d.div_ceil(BLOCK));
    let mut marked = vec![false; blocks[0] * blocks[1] * blocks[2]];
    let negative = style.negative.is_some();
    for (index, &v) in grid.values.iter().enumerate() {
        let v = f64::from(v);
        if v >= style.threshold || (negative && v <= -style.threshold) {
            let (i, j, k) = (index % nx, (index / nx) % ny, index / (nx * ny));
            marked[i / BLOCK + blocks[0] * (j / BLOCK + blocks[1] * (k / BLOCK))] = true;
        }
    }
    let mut boxes = Vec::new();
    for (b, _) in marked.iter().enumerate().filter(|(_, m)| **m) {
        let (i, j, k) = (
            b % blocks[0],
            (b / blocks[0]) % blocks[1],
            b / (blocks[0] * blocks[1]),
        );
        let lo = DVec3::new((i * BLOCK) as f64, (j * BLOCK) as f64, (k * BLOCK) as f64) - 1.0;
        boxes.push((lo, lo + (BLOCK as f64 + 1.0)));
    }
    boxes
}

impl AttachedLayers {
    /// The layers' own brick bits for a base volume of `dims`, computed once per generation.
    fn own_bits(&mut self, dims: [u32; 3]) -> Arc<Vec<u32>> {
        match &self.own_bits {
            Some((g, bits)) if *g == self.generation => bits.clone(),
            _ => {
                let bits = Arc::new(layer_brick_bits(&self.layers, dims));
                self.own_bits = Some((self.generation, bits.clone()));
                bits
            }
        }
    }
}

impl RenderTarget {
    /// Draws `layers` (at most [`MAX_LAYERS`], each with its style) in this target's DVR frames
    /// from the next recording on; an empty list stops drawing them. Nothing changes (and
    /// nothing is rewritten) when the list is the one attached.
    pub fn set_layers(&mut self, layers: Vec<(Arc<LayerVolume>, LayerStyle)>) -> GpuResult<()> {
        if layers.len() > MAX_LAYERS {
            return Err(GpuError::InvalidRequest(format!(
                "{} layers: at most {MAX_LAYERS} are drawn over a volume",
                layers.len()
            )));
        }
        let same = layers.len() == self.layers.layers.len()
            && layers
                .iter()
                .zip(&self.layers.layers)
                .all(|((a, s), (b, t))| Arc::ptr_eq(a, b) && s == t);
        if !same {
            self.layers.layers = layers;
            self.layers.generation += 1;
        }
        Ok(())
    }

    /// Whether layers are attached.
    pub fn has_layers(&self) -> bool {
        !self.layers.layers.is_empty()
    }

    /// The brick bits of the labels (`label_bits`) and the attached layers together, the same
    /// `Arc` while neither changes (the brick-bounds pass reruns on a new one).
    pub(super) fn extra_brick_bits(
        &mut self,
        label_bits: Option<Arc<Vec<u32>>>,
        dims: [u32; 3],
        layers_drawn: bool,
    ) -> Option<Arc<Vec<u32>>> {
        if !layers_drawn || self.layers.layers.is_empty() {
            return label_bits;
        }
        let generation = self.layers.generation;
        if let Some((g, labels, bits)) = &self.layers.bits
            && *g == generation
            && match (labels, &label_bits) {
                (None, None) => true,
                (Some(a), Some(b)) => Arc::ptr_eq(a, b),
                _ => false,
            }
        {
            return Some(bits.clone());
        }
        let mut bits = self.layers.own_bits(dims).to_vec();
        if let Some(l) = &label_bits {
            for (w, &extra) in bits.iter_mut().zip(l.iter()) {
                *w |= extra;
            }
        }
        let bits = Arc::new(bits);
        self.layers.bits = Some((generation, label_bits, bits.clone()));
        Some(bits)
    }
}
