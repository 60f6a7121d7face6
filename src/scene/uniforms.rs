//! The raymarch's uniform block (`Params` in shaders/raymarch.comp), std140.
//!
//! Decision: every field is a vec4 or mat4 so std140 adds no hidden padding and the Rust struct
//! is the block byte for byte (checked against the reflected block size in a test). Everything a
//! user changes interactively lives here, so an interaction is one buffer write.

use super::Scene;
use super::camera::CameraRays;
use super::classification::MIN_EDGE;
use super::clip::MAX_CLIP_PLANES;
use super::colormap::COLORMAP_POINTS;
use super::geometry::VolumeGeometry;

/// Sample cap per ray: protects against absurd step sizes; 2^16 steps of 0.125 voxel cross an
/// 8192-voxel diagonal.
pub const MAX_STEPS: u32 = 1 << 16;

/// The uniform block.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct RaymarchUniforms {
    /// World mm to index space (column-major).
    pub world_to_index: [[f32; 4]; 4],
    /// Camera origin (world); w = 1 for orthographic.
    pub camera_origin: [f32; 4],
    /// Image-right unit vector; w = half extent along it.
    pub camera_right: [f32; 4],
    /// Image-up unit vector; w = half extent along it.
    pub camera_up: [f32; 4],
    /// Viewing direction; w unused.
    pub camera_forward: [f32; 4],
    /// xyz = dims; w = step length in mm.
    pub dims: [f32; 4],
    /// x = opacity-correction exponent r (step length / 1 mm), y = early-termination threshold,
    /// z = jitter on (1) / off (0), w = 1 / |grad I|max.
    pub march: [f32; 4],
    /// x = curvature strength s, y = 1 / k_ref, z = tau (zero-gradient threshold), w unused.
    pub curvature: [f32; 4],
    /// Background RGB; w unused.
    pub background: [f32; 4],
    /// Per tissue: lo, hi, edge, visible (1 / 0).
    pub windows: [[f32; 4]; 4],
    /// Per tissue: RGB, opacity.
    pub colours: [[f32; 4]; 4],
    /// x, y = MIP/MinIP display window; z = MinIP floor; w unused.
    pub intensity: [f32; 4],
    /// Rows of A^-T (index-space gradient to world), xyz; w unused.
    pub gradient_to_world: [[f32; 4]; 3],
    /// x = width, y = height, z = jitter seed (frame), w = maximum steps per ray.
    pub image: [u32; 4],
    /// x multiplies stored |g| back to per mm, y stored k to per mm^2 (8-bit storage is scaled);
    /// z, w: the long-step threshold (opacity bound per mm) and factor (LONG_STEPS only).
    pub derived_scale: [f32; 4],
    /// xyz = brick grid of the occupancy bits, w = brick side in voxels.
    pub bricks: [u32; 4],
    /// Bricked volumes: xyz atlas dims in texels, w storage brick side.
    pub atlas: [f32; 4],
    /// Bricked volumes: xyz storage brick grid, w halo.
    pub brick_grid: [u32; 4],
    /// Bricked volumes: xyz slots per atlas row and layer; w (empty-space skipping, set by the
    /// engine): the farthest jump in bricks (1: the brick itself).
    pub atlas_slots: [u32; 4],
    // Helper "clip" (issue 16 items 2 and 4): crop box, clip planes, colour map.
    /// Crop box, index space: xyz smallest corner; w = clip planes in use.
    pub crop_lo: [f32; 4],
    /// Crop box, index space: xyz largest corner; w = 1 when colours come from `colormap`.
    pub crop_hi: [f32; 4],
    /// Clip planes in index space: unit normal xyz, w offset; keeps `n . p + w >= 0`.
    pub clip_planes: [[f32; 4]; MAX_CLIP_PLANES],
    /// Colour map control points (rgb, w unused) at positions i / 15.
    pub colormap: [[f32; 4]; COLORMAP_POINTS],
    /// Vessel channel (issue 15 item 3): window on the vesselness (lo, hi, edge, 1).
    pub vessel_window: [f32; 4],
    /// Vessel channel: rgb, opacity.
    pub vessel_colour: [f32; 4],
    /// Head layer (issue 27): window on I_norm (lo, hi, edge, visible).
    pub head_window: [f32; 4],
    /// Head layer: rgb, opacity (0 when hidden).
    pub head_colour: [f32; 4],
    /// Brain mask: xyz the extent in voxels its texture spans (w unused).
    pub brain_grid: [f32; 4],
    /// xyz: unit world direction toward the key light; w: silhouette strength (issue 34).
    pub key_light: [f32; 4],
    /// Occlusion and shadow strengths, then their reaches in mm.
    pub cues: [f32; 4],
    /// x: depth in mm behind a cut face drawn solid; y: the depth cues' unit length in mm.
    pub cap: [f32; 4],
    /// Depth picking: x the accumulated opacity that counts as visible, yz the view pixel.
    pub pick: [f32; 4],
    /// Intensity layers (issue 31 item 4, `engine::layers`): base index position -> layer
    /// texture coordinates, column-major, per layer.
    pub layer_to_texture: [[[f32; 4]; 4]; 2],
    /// Per layer: lo, hi, threshold, opacity.
    pub layer_window: [[f32; 4]; 2],
    /// Per layer: value of code 0, value span of the codes, negative side drawn (1/0), unused.
    pub layer_decode: [[f32; 4]; 2],
    /// The layer brick bits' grid (xyz) and brick side (w): the raymarch reads a layer only in
    /// bricks where one may draw.
    pub layer_bricks: [u32; 4],
}

/// Where a bricked volume's bricks are (zeros for a whole volume).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AtlasInfo {
    /// Atlas dims in texels.
    pub dims: [u32; 3],
    /// Storage brick side.
    pub brick: u32,
    /// Halo.
    pub halo: u32,
    /// Storage brick grid.
    pub grid: [u32; 3],
    /// Slots along each atlas axis.
    pub slots: [u32; 3],
}

/// Inputs of the uniform block besides the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameInputs {
    /// max |g| and tau of the derived volumes.
    pub gradients: GradientStats,
    /// How the stored derived values were scaled (`|g| * s[0]`, `k * s[1]`).
    pub store_scale: [f32; 2],
    /// Brick grid and side of the occupancy bits.
    pub bricks: [u32; 4],
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// The atlas of a bricked volume (default for a whole volume).
    pub atlas: AtlasInfo,
    /// The extent in voxels the brain mask's texture spans (its working grid times the block
    /// edges); ones without a mask.
    pub brain_grid: [f32; 3],
    /// The one view pixel a picking frame marches (`width` x `height` is then the view's size,
    /// not the target's), None for a picture.
    pub pick: Option<PixelPick>,
}

/// One pixel of a view to pick (depth picking, issue 31 item 2): the raymarch marches that
/// pixel's ray as the picture does and reports where it first becomes visible.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelPick {
    /// The pixel, (0, 0) at the top left of the view.
    pub pixel: [u32; 2],
    /// DVR: the accumulated opacity at which the ray counts as having met what is shown.
    pub threshold: f32,
}

/// Gradient statistics of the volume the raymarch needs (from the derivative pass).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct GradientStats {
    /// Largest |grad I_norm| over the volume, per mm (paper eq. 4's normalizer).
    pub max_magnitude: f64,
    /// Zero-gradient threshold used by the derivative pass, per mm.
    pub tau: f64,
}

impl GradientStats {
    /// Reference curvature `k_ref = max|g| / (4 * voxel_mm)`: a step edge of full height blurred
    /// over about four voxels. |k| at this scale saturates the curvature weight.
    pub fn k_ref(&self, voxel_mm: f64) -> f64 {
        (self.max_magnitude / (4.0 * voxel_mm)).max(1e-12)
    }
}

fn vec4(v: glam::DVec3, w: f64) -> [f32; 4] {
    [v.x as f32, v.y as f32, v.z as f32, w as f32]
}

impl RaymarchUniforms {
    /// Builds the block for `scene` on a volume with `geometry`.
    pub fn new(scene: &Scene, geometry: &VolumeGeometry, frame: &FrameInputs) -> Self {
        let (gradients, width, height) = (&frame.gradients, frame.width, frame.height);
        let rays: CameraRays = scene.camera.rays(geometry.world_bounds(), width, height);
        let step_voxels = scene.sanitized_step_voxels();
        let step_mm = step_voxels * geometry.voxel_mm;
        let mut windows = [[0.0f32; 4]; 4];
        let mut colours = [[0.0f32; 4]; 4];
        for (i, style) in scene.classification.tissues.iter().enumerate() {
            if let Some(w) = style.window {
                windows[i] = [
                    w.lo as f32,
                    w.hi as f32,
                    w.edge.max(MIN_EDGE) as f32,
                    style.visible as u32 as f32,
                ];
            } else {
                windows[i] = [2.0, 3.0, MIN_EDGE as f32, 0.0];
            }
            colours[i] = [
                style.colour[0],
                style.colour[1],
                style.colour[2],
                style.opacity.clamp(0.0, 1.0),
            ];
        }
        let m = geometry.gradient_to_world.transpose(); // rows of M as columns of M^T
        let inv_gmax = if gradients.max_magnitude > 0.0 {
            1.0 / gradients.max_magnitude
        } else {
            0.0
        };
        let clip = scene
            .frame_clip(&rays, geometry.world_bounds())
            .to_index(geometry);
        let cues = &scene.cues;
        let colormap = scene
            .colormap
            .unwrap_or(super::Colormap::Gray)
            .points()
            .map(|[r, g, b]| [r, g, b, 0.0]);
        let vessels = &scene.classification.vessels;
        let [vr, vg, vb] = vessels.colour;
        let head = &scene.classification.head;
        let [hr, hg, hb] = head.colour;
        let head_opacity = if head.visible {
            head.opacity.clamp(0.0, 1.0)
        } else {
            0.0
        };
        let [bx, by, bz] = frame.brain_grid;
        RaymarchUniforms {
            key_light: vec4(
                super::lighting::key_light(&rays),
                f64::from(cues.sanitized().silhouette),
            ),
            cues: cues.uniform(),
            cap: [
                super::lighting::CAP_MM as f32,
                super::lighting::cue_unit_mm(geometry.voxel_mm) as f32,
                0.0,
                0.0,
            ],
            pick: frame.pick.map_or([0.0; 4], |p| {
                [p.threshold, p.pixel[0] as f32, p.pixel[1] as f32, 0.0]
            }),
            brain_grid: [bx, by, bz, 0.0],
            // Set by the engine where layers are attached to the render target.
            layer_to_texture: [[[0.0; 4]; 4]; 2],
            layer_window: [[0.0; 4]; 2],
            layer_decode: [[0.0; 4]; 2],
            layer_bricks: [1, 1, 1, 8],
            head_window: [
                head.window.lo as f32,
                head.window.hi as f32,
                head.window.edge.max(MIN_EDGE) as f32,
                head.visible as u32 as f32,
            ],
            head_colour: [hr, hg, hb, head_opacity],
            vessel_window: [
                vessels.window.lo as f32,
                vessels.window.hi as f32,
                vessels.window.edge.max(MIN_EDGE) as f32,
                1.0,
            ],
            vessel_colour: [vr, vg, vb, vessels.opacity.clamp(0.0, 1.0)],
            crop_lo: vec4(clip.lo, clip.count as f64),
            crop_hi: vec4(clip.hi, scene.colormap.is_some() as u32 as f64),
            clip_planes: clip.planes.map(|p| p.to_array().map(|v| v as f32)),
            colormap,
            world_to_index: geometry
                .world_to_index
                .to_cols_array_2d()
                .map(|c| c.map(|v| v as f32)),
            camera_origin: vec4(rays.origin, rays.orthographic as u32 as f64),
            camera_right: vec4(rays.right, rays.half_extent[0]),
            camera_up: vec4(rays.up, rays.half_extent[1]),
            camera_forward: vec4(rays.forward, 0.0),
            dims: [
                geometry.dims[0] as f32,
                geometry.dims[1] as f32,
                geometry.dims[2] as f32,
                step_mm as f32,
            ],
            march: [
                scene.opacity_exponent(geometry.voxel_mm) as f32,
                scene.early_termination,
                scene.jitter as u32 as f32,
                inv_gmax as f32,
            ],
            curvature: [
                scene.curvature_strength,
                (1.0 / gradients.k_ref(geometry.voxel_mm)) as f32,
                gradients.tau as f32,
                0.0,
            ],
            background: [
                scene.background[0],
                scene.background[1],
                scene.background[2],
                1.0,
            ],
            windows,
            colours,
            intensity: [
                scene.intensity_window[0],
                scene.intensity_window[1],
                scene.minip_floor,
                0.0,
            ],
            gradient_to_world: [
                vec4(m.col(0), 0.0),
                vec4(m.col(1), 0.0),
                vec4(m.col(2), 0.0),
            ],
            image: [width, height, scene.frame, MAX_STEPS],
            derived_scale: [
                1.0 / frame.store_scale[0].max(f32::MIN_POSITIVE),
                1.0 / frame.store_scale[1].max(f32::MIN_POSITIVE),
                scene.effects.quality.long_steps.threshold() as f32,
                scene.effects.quality.long_steps.factor.max(1) as f32,
            ],
            bricks: frame.bricks,
            atlas: [
                frame.atlas.dims[0] as f32,
                frame.atlas.dims[1] as f32,
                frame.atlas.dims[2] as f32,
                frame.atlas.brick as f32,
            ],
            brick_grid: [
                frame.atlas.grid[0],
                frame.atlas.grid[1],
                frame.atlas.grid[2],
                frame.atlas.halo,
            ],
            atlas_slots: [
                frame.atlas.slots[0],
                frame.atlas.slots[1],
                frame.atlas.slots[2],
                // The farthest empty-space jump: the distance map's cap (the engine may lower it).
                255,
            ],
        }
    }
}
