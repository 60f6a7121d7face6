#version 450
// The morphologically modulated front-to-back raymarch (paper eqs. 4-6), one invocation per
// pixel in 8x8 tiles, writing a storage image.
//
// Per DVR sample: v = I_norm (interpolated per INTERPOLATION); f(v), C_s(v) from the tissue
// windows; opacity
//   a = clamp(f(v) * |grad I| / |grad I|max * w(k), 0, 1)       (eq. 4)
// corrected for the step length, then C += (1 - A) C_s a, A += (1 - A) a (eqs. 5, 6) in f32,
// stopping once A exceeds the early-termination threshold. MIP and MinIP track the extreme
// I_norm instead. What a scene does not use is compiled out: every choice below is a
// specialization constant, so no sample branches on it.
//
// Empty-space skipping (SKIP_EMPTY): the volume is cut into 8^3-voxel bricks; a bit per brick
// says whether any visible tissue window can be non-zero in the brick's intensity range (brick
// min/max over the brick plus a 2-voxel halo, the footprint of every interpolation; classified
// by the brick-bounds pass when the windows change). From the bits, the distance map
// (brick_distance.comp) gives each empty brick its Chebyshev distance d to the nearest occupied
// brick. A sample in an empty brick jumps to the last sample of the same lattice before the exit
// of the cube of bricks within d - 1 of it, all empty (issue 33 item 3), so the samples taken are
// exactly those taken without skipping minus samples of zero opacity: the image is unchanged.
//
// Long steps (LONG_STEPS, with SKIP_EMPTY; issue 17 item 2): the occupancy buffer also holds
// each brick's upper bound of f(v) (shaders/brick_bounds.comp). In an occupied brick whose bound
// is below a threshold, a sample stands for up to k lattice samples (never past the brick's
// last lattice sample), composited with the opacity of that length (exponent k r), and the
// march goes on k samples later. An approximation, measured by the accuracy study; the f64 twin
// does the same (ReferenceRaymarch::with_brick_bounds).
//
// Bricking (BRICKED): for volumes over the memory budget or the 3D image limit, the textures hold
// only resident bricks (with halos) in atlases, and every fetch goes through the brick table
// (sampling.glsl).
//
// Classification table (CLASSIFY_TABLE; issue 33 item 1): the tissue and head windows come
// from one linear lookup each in a 4096-entry table of their opacity-weighted sums, built on the
// host when the classification changes, instead of two smoothsteps per window per sample; the
// brain mask, vessels and the division stay per sample (classification.glsl). An approximation
// of the windows (<= 1.1e-4 of f at a 0.01 edge), measured by the accuracy study; twin:
// scene::transfer_table.
//
// Vessels (VESSELS): the vessel channel is one more classification term, its window on the
// multi-scale vesselness sampled like the derived volumes (classification.glsl); the f64 twin
// takes the same vesselness volume (ReferenceRaymarch::with_vesselness).
//
// Labels (LABELS): a label overlay's samples are composited after the tissue's at the same
// position, nearest voxel, colour and opacity per mm from a lookup table (labels.glsl); bricks
// holding a label are occupied for skipping, so skipping stays lossless.
//
// Layers (LAYERS; issue 31 item 4): up to two intensity volumes on their own grids, sampled
// through the composed affines, coloured by their thresholds and maps and composited before the
// tissue and the label at each sample (layers.glsl); bricks they may draw in are occupied.
//
// Lighting (LIGHTING, DEPTH_CUES; issue 34 item 2): the studio model, the matcap and the surface
// cues of lighting.glsl. Cut faces (CAPPING by uniform, issue 34 item 3): where a ray enters through a
// crop face or clip plane, the samples within params.cap.x mm of that face take the window
// opacity f(v) instead of the gradient-modulated one, so a cut shows its tissues as solid
// colours (cortex over white matter, the ventricles) instead of the see-through interior that
// eq. 4 gives a flat region; the f64 twin does the same.
//
// Classified volume (CLASSIFIED; issue 33 item 1, the lean sample): MODE 3 classifies every
// voxel once into an RGBA8 volume (classified_out) when the classification changes: the
// opacity of eq. 4 at the voxel (window, |g|, curvature weight, brain mask and vessels included)
// already corrected for the step, and its colour premultiplied by it. A DVR sample of a
// CLASSIFIED variant is then one trilinear fetch of that volume (pre-classification: the
// voxels' opacities are interpolated instead of classifying the interpolated value), its colour
// the interpolated sum divided by the interpolated opacity, and the normal fetch for lighting.
// What it costs in accuracy is measured by the accuracy study; twin:
// reference/raymarch/classified.rs. Cut faces (capping) need f(v) per sample, so the engine
// uses the exact variant for a scene with a cut.
//
// Depth picking (PICK; issue 31 item 2): one invocation marches the ray of view pixel
// params.pick.yz exactly as the picture does and writes, instead of a colour, the ray parameter
// (mm from the ray's origin) of the first sample at which the accumulated opacity reaches
// params.pick.x (DVR) or of the first sample holding the extreme (MIP/MinIP), -1 for none, to
// texel (0, 0); the host turns it into a world point. Twin: ReferenceRaymarch::pick.
//
// Geometry: rays start in world space (mm) and are marched in index space with the parameter
// in mm (geometry.glsl); the interval is cut to the crop box and clip planes (clip.glsl) before
// any sample is placed; ray starts are jittered per pixel against wood-grain banding.
// The f64 twin of this whole shader is src/reference/raymarch.rs.
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require

// The workgroup size is specializable (spec ids 100-102) for profiling variants (`--wg`); the
// numbers here are the defaults.
layout(local_size_x_id = 100, local_size_y_id = 101, local_size_z_id = 102) in;
layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

layout(constant_id = 0) const uint MODE = 0u;             // 0 DVR, 1 MIP, 2 MinIP, 3 classify voxels
layout(constant_id = 1) const uint CURVATURE_MODE = 0u;   // 0 off, 1 stored k, 2 k on the fly
layout(constant_id = 2) const bool SHADING = false;       // Phong with gradient normals
layout(constant_id = 3) const uint GRADIENT_MODE = 0u;    // 0 stored, 1 central on the fly, 2 Sobel on the fly
layout(constant_id = 4) const bool COUNT_SAMPLES = false; // benchmark counters (off: no cost)
layout(constant_id = 5) const uint INTERPOLATION = 1u;    // 0 nearest, 1 trilinear, 2 tricubic B-spline
layout(constant_id = 6) const bool NAIVE_OPACITY = false; // 1-(1-a)^r in f32 (accuracy study only)
layout(constant_id = 7) const bool SKIP_EMPTY = false;    // empty-space skipping over 8^3 bricks
layout(constant_id = 8) const bool BRICKED = false;       // textures are brick atlases (sampling.glsl)
layout(constant_id = 9) const bool LABELS = false;        // a label overlay drawn in 3D (labels.glsl)
layout(constant_id = 10) const bool VESSELS = false;      // the vessel channel (classification.glsl)
layout(constant_id = 11) const bool LONG_STEPS = false;   // longer steps in bricks of low opacity bound
layout(constant_id = 12) const bool BRAIN = false;        // tissues inside the brain mask, the head layer outside
layout(constant_id = 13) const bool CLASSIFY_TABLE = false; // tissue windows from the transfer-function table
layout(constant_id = 14) const uint LIGHTING = 0u;        // 0 headlight Phong, 1 studio, 2 matcap (lighting.glsl)
layout(constant_id = 15) const bool DEPTH_CUES = false;   // occlusion and shadow at the surface (lighting.glsl)
layout(constant_id = 16) const bool PICK = false;         // one view pixel's first visible sample (depth picking)
layout(constant_id = 17) const uint LAYERS = 0u;          // intensity layers drawn, 0..2 (layers.glsl)
layout(constant_id = 18) const bool CLASSIFIED = false;   // DVR samples the classified volume (MODE 3 builds it)
layout(constant_id = 19) const bool TEXEL_LOOKUPS = false; // occupancy and table read as texel buffers

layout(set = 0, binding = 0) uniform sampler3D volume;          // I_norm, trilinear
layout(set = 0, binding = 1) uniform sampler3D gradient_volume; // .r |g|, .g k (scaled, see derived_scale)
layout(set = 0, binding = 2) uniform sampler3D normal_volume;   // .xyz unit world gradient
layout(set = 0, binding = 3) uniform writeonly image2D target;  // RGBA8 (or RGBA32F for studies)
layout(set = 0, binding = 10) uniform sampler3D vesselness_volume; // VESSELS: multi-scale vesselness
layout(set = 0, binding = 11) uniform sampler3D brain_mask;        // BRAIN: 1 inside the brain (R8, trilinear)

layout(set = 0, binding = 4, std140) uniform Params {
    mat4 world_to_index;
    vec4 camera_origin;     // w: 1 = orthographic
    vec4 camera_right;      // w: half extent
    vec4 camera_up;         // w: half extent
    vec4 camera_forward;
    vec4 dims;              // w: step length (mm)
    vec4 march;             // x: opacity exponent r (step mm / 1 mm), y: ERT threshold, z: jitter on, w: 1/|g|max
    vec4 curvature;         // x: strength s, y: 1/k_ref, z: tau
    vec4 background;
    vec4 windows[4];        // lo, hi, edge, visible
    vec4 colours[4];        // rgb, opacity
    vec4 intensity;         // x, y: MIP/MinIP display window; z: MinIP floor
    vec4 gradient_to_world[3];
    uvec4 image;            // width, height, jitter seed, max steps
    vec4 derived_scale;     // x: stored |g| -> per mm, y: stored k -> per mm^2, z: long-step threshold, w: k
    uvec4 bricks;           // xyz: brick grid, w: brick side in voxels
    vec4 atlas;             // BRICKED: xyz atlas dims in texels, w storage brick side
    uvec4 brick_grid;       // BRICKED: xyz storage brick grid, w halo
    uvec4 atlas_slots;      // BRICKED: xyz slots per atlas row and layer; w (SKIP_EMPTY): farthest empty-space jump in bricks
    // Helper "clip" (issue 16 items 2 and 4): crop box, clip planes, colour map.
    vec4 crop_lo;           // xyz index-space crop box corner; w: clip planes in use
    vec4 crop_hi;           // xyz the opposite corner; w: 1 = colours from the colour map
    vec4 clip_planes[4];    // index space: unit normal xyz, w offset; keeps dot(n, p) + w >= 0
    vec4 colormap[16];      // rgb control points at i / 15
    // Vessel channel (issue 15 item 3).
    vec4 vessel_window;     // lo, hi, edge on the vesselness, 1
    vec4 vessel_colour;     // rgb, opacity
    // Brain extraction (issue 27): the head layer outside the brain mask.
    vec4 head_window;       // lo, hi, edge on I_norm, visible
    vec4 head_colour;       // rgb, opacity (0 when hidden)
    vec4 brain_grid;        // xyz: the extent in voxels the brain mask's texture spans
    // Lighting and cut faces (issue 34).
    vec4 key_light;         // xyz: unit world direction toward the key light; w: silhouette strength
    vec4 cues;              // x: occlusion strength, y: shadow strength, z: occlusion reach mm, w: shadow reach mm
    vec4 cap;               // x: depth in mm behind a cut face that is drawn solid (0: off); y: cue unit mm
    // Depth picking (issue 31 item 2).
    vec4 pick;              // PICK: x the accumulated opacity that counts as visible, yz the view pixel
    // Intensity layers (issue 31 item 4; LAYERS > 0): per layer base index -> texture coordinates,
    mat4 layer_to_texture[2];
    vec4 layer_window[2];   // lo, hi, threshold, opacity per mm
    vec4 layer_decode[2];   // value of code 0, value span of the codes, negative side drawn, 0
    uvec4 layer_bricks;     // xyz: brick grid of the layer bits, w: brick side
} params;

// Benchmark counters (COUNT_SAMPLES only): samples marched and samples that passed
// classification (each of those fetches the derived volumes too), summed per subgroup and spread
// over 512 slot pairs by workgroup so no 32-bit slot overflows; the host adds them in u64.
const uint COUNTER_SLOTS = 512u;
layout(set = 0, binding = 5, std430) buffer Counters { uint slots[]; } counters;

// One bit per brick, set where a visible tissue can have non-zero opacity (SKIP_EMPTY only),
// then (LONG_STEPS) one f32 opacity bound per brick (brick_bounds.comp's layout). Read per
// sample: with TEXEL_LOOKUPS (CPU devices) through the same buffer's R32_UINT texel view, since
// there a storage-buffer read at a per-lane index is a loop over the lanes and a texel fetch one
// vectorized gather (llvmpipe); GPUs keep the storage buffer (Intel's compiler schedules it in
// fewer cycles than a sampler message). Both are bound; the constant picks one.
layout(set = 0, binding = 6, std430) readonly buffer Occupancy { uint bits[]; } occupancy;
layout(set = 0, binding = 20) uniform usamplerBuffer occupancy_texels;

// Slot + 1 of each storage brick in the atlases, 0 when not resident (BRICKED only).
layout(set = 0, binding = 7, std430) readonly buffer BrickTable { uint slots[]; } brick_table;

// Labels of the volume's voxels, two u16 per word, and each label's RGBA8 colour and opacity
// per mm (LABELS only; labels.glsl).
layout(set = 0, binding = 8, std430) readonly buffer LabelValues { uint words[]; } label_values;
layout(set = 0, binding = 9, std430) readonly buffer LabelColours { uint rgba[]; } label_colours;

// The transfer-function table (CLASSIFY_TABLE only; src/scene/transfer_table.rs): 4096 entries
// of the tissues' opacity-weighted sums (rgb: colour sum, a: weight sum) at v = i / 4095, then
// 4096 of the head layer's; with TEXEL_LOOKUPS read through the same buffer's RGBA32F texel view
// (as the occupancy above).
layout(set = 0, binding = 12, std430) readonly buffer TransferTable { vec4 entries[]; } transfer_table;
layout(set = 0, binding = 21) uniform samplerBuffer transfer_texels;

// The matcap (LIGHTING == 2 only; src/scene/matcap.rs): MATCAP_SIDE^2 RGBA8 texels, row 0 on top.
layout(set = 0, binding = 13, std430) readonly buffer Matcap { uint texels[]; } matcap;

// Intensity layers (LAYERS > 0; layers.glsl): 16-bit codes on each layer's own grid, trilinear,
// and per layer 256 RGBA8 entries of the positive map, then 256 of the negative map.
layout(set = 0, binding = 14) uniform sampler3D layer_volume_0;
layout(set = 0, binding = 15) uniform sampler3D layer_volume_1;
layout(set = 0, binding = 16, std430) readonly buffer LayerColours { uint rgba[]; } layer_colours;
// One bit per brick where a layer may draw (engine/layers.rs): elsewhere no layer is read.
layout(set = 0, binding = 17, std430) readonly buffer LayerBricks { uint bits[]; } layer_bricks;

// The classified volume (CLASSIFIED reads it; MODE 3 writes it): premultiplied colour and the
// step-corrected opacity per voxel.
layout(set = 0, binding = 18) uniform sampler3D classified_volume;
layout(set = 0, binding = 19, rgba8) uniform writeonly image3D classified_out;

#include "geometry.glsl"
#include "clip.glsl"
#include "colormap.glsl"
#include "jitter.glsl"
#include "classification.glsl"
#include "compositing.glsl"
#include "sampling.glsl"
#include "gradients.glsl"
#include "labels.glsl"

// The classification of the sample at p with I_norm v, as the march sees it: the brain mask and
// the vessel channel when their variants are on.
vec4 classify_at(vec3 p, float v) {
    if (BRAIN) {
        float vessel_weight = VESSELS ? window_weight(fetch_volume(vesselness_volume, p).r, params.vessel_window) * params.vessel_colour.a : 0.0;
        return classify_in_brain(v, vessel_weight, brain_weight(p));
    }
    return VESSELS ? classify_with_vessels(v, fetch_volume(vesselness_volume, p).r) : classify(v);
}

// The depth cues' occluder density at index position p: f(v), 0 where nothing is kept.
float cue_density(vec3 p) {
    if (!kept(p)) {
        return 0.0;
    }
    return classify_at(p, sample_volume(p)).a;
}

#include "lighting.glsl"

const uint MODE_DVR = 0u;
const uint MODE_MIP = 1u;
const uint MODE_MINIP = 2u;

// Headlight Phong: ambient + diffuse on |n . l| (two-sided) + a white highlight, clamped to 1 so
// a sample never emits more than white (early termination then changes no pixel by more than
// 1 - threshold). Without a reliable normal (|n| tiny: flat regions) the sample keeps its colour.
// Lean (issue 33 item 1): ndl^24 by four squarings and one product instead of pow() (which
// drivers expand to exp2(24 log2 ndl): two transcendental polynomials on a CPU device), and one
// inversesqrt instead of length() and a vector division; the same function to f32 rounding.
vec3 shade(vec3 colour, vec3 normal, vec3 view_direction) {
    float len2 = dot(normal, normal);
    if (len2 < 1e-6) {
        return colour;
    }
    float ndl = abs(dot(normal, view_direction)) * inversesqrt(len2);
    float n2 = ndl * ndl;
    float n4 = n2 * n2;
    float n8 = n4 * n4;
    float n24 = n8 * n8 * n8;
    return min(colour * (0.35 + 0.65 * ndl) + vec3(0.25 * n24), vec3(1.0));
}

// The scene's lighting model (LIGHTING).
vec3 lit(vec3 colour, vec3 normal, vec3 view_direction) {
    if (LIGHTING == 1u) {
        return shade_studio(colour, normal, view_direction);
    }
    if (LIGHTING == 2u) {
        return shade_matcap(colour, normal, view_direction);
    }
    return shade(colour, normal, view_direction);
}

// After lit(): a layer sample is lit as the tissue is.
#include "layers.glsl"

void count_samples(uint marched, uint classified) {
    uint subgroup_marched = subgroupAdd(marched);
    uint subgroup_classified = subgroupAdd(classified);
    if (subgroupElect()) {
        uint slot = (gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x) % COUNTER_SLOTS;
        atomicAdd(counters.slots[2u * slot], subgroup_marched);
        atomicAdd(counters.slots[2u * slot + 1u], subgroup_classified);
    }
}

// The brick holding p (clamped to the grid).
ivec3 brick_at(vec3 p) {
    float side = float(params.bricks.w);
    return clamp(ivec3(floor((p + 0.5) / side)), ivec3(0), ivec3(params.bricks.xyz) - 1);
}

uint brick_index(ivec3 brick) {
    return uint(brick.x) + params.bricks.x * (uint(brick.y) + params.bricks.y * uint(brick.z));
}

// The ray parameter at which the ray leaves the box of bricks `first` .. `last` (inclusive).
float bricks_exit(ivec3 first, ivec3 last, vec3 origin, vec3 direction) {
    float side = float(params.bricks.w);
    vec3 lo = vec3(first) * side - 0.5;
    vec3 hi = vec3(last + 1) * side - 0.5;
    float t_exit = 3.0e38;
    for (int a = 0; a < 3; a++) {
        if (abs(direction[a]) >= MIN_DIRECTION) {
            float face = direction[a] > 0.0 ? hi[a] : lo[a];
            t_exit = min(t_exit, (face - origin[a]) / direction[a]);
        }
    }
    return t_exit;
}

// Word i of the occupancy buffer, through the binding TEXEL_LOOKUPS picks.
uint occupancy_word(uint i) {
    return TEXEL_LOOKUPS ? texelFetch(occupancy_texels, int(i)).r : occupancy.bits[i];
}

// The empty-space distance of brick b (brick_distance.comp, after the brick-bounds pass's
// count word): 0 when occupied, else the Chebyshev distance in bricks to the nearest occupied
// brick (at most 255).
uint brick_distance(uint b) {
    uint count = params.bricks.x * params.bricks.y * params.bricks.z;
    uint words = max((count + 31u) / 32u, 1u);
    uint base = 2u * words + 5u * count + 1u;
    return (occupancy_word(base + (b >> 2u)) >> (8u * (b & 3u))) & 0xffu;
}

// The opacity bound of brick b, after the bits (brick_bounds.comp's layout).
float brick_bound(uint b) {
    uint count = params.bricks.x * params.bricks.y * params.bricks.z;
    uint words = max((count + 31u) / 32u, 1u);
    return uintBitsToFloat(occupancy_word(words + b));
}

// One classified tissue sample's colour (rgb, shaded with SHADING) and step-corrected opacity
// (a): the gradient-magnitude term, the curvature weight and the colour of eqs. 4-6.
// `solid`: the sample lies in a cut face's cap (opacity f(v)). `normal_out`: the shading normal
// (0 without one), for the surface cues.
vec4 tissue_sample(vec3 p, float v, vec4 cls, vec3 direction_world, float r, bool solid, out vec3 normal_out) {
    float magnitude;
    float k = 0.0;
    vec3 normal = vec3(0.0);
    vec3 g = vec3(0.0);
    if (GRADIENT_MODE == 0u) {
        vec2 gk = fetch_volume(gradient_volume, p).rg * params.derived_scale.xy;
        magnitude = gk.x;
        if (CURVATURE_MODE == 1u) {
            k = gk.y;
        }
        if (SHADING) {
            normal = fetch_volume(normal_volume, p).xyz;
        }
    } else {
        g = GRADIENT_MODE == 1u ? gradient_central(p) : gradient_sobel(p);
        magnitude = length(g);
        if (SHADING) {
            normal = magnitude > params.curvature.z ? g / magnitude : vec3(0.0);
        }
    }
    if (CURVATURE_MODE == 2u) {
        vec3 g_central = GRADIENT_MODE == 1u ? g : gradient_central(p);
        k = curvature_on_the_fly(p, v, g_central);
    }
    float a = clamp(cls.a * magnitude * params.march.w, 0.0, 1.0);
    if (CURVATURE_MODE != 0u) {
        a = min(a * curvature_weight(k), 1.0);
    }
    if (solid) {
        // A cut face: the window's opacity, its colour unshaded (the gradient of a flat interior
        // is noise, not a surface's normal).
        a = max(a, min(cls.a, 1.0));
        normal = vec3(0.0);
    }
    a = NAIVE_OPACITY ? opacity_correct_naive(a, r) : opacity_correct(a, r);
    vec3 colour = cls.rgb;
    if (params.crop_hi.w > 0.5) {
        colour = colormap_lookup(display_position(v));
    }
    if (SHADING) {
        colour = lit(colour, normal, direction_world);
    }
    normal_out = normal;
    return vec4(colour, a);
}

// A CLASSIFIED variant's tissue sample: `pre` is the classified volume at p (premultiplied
// colour, corrected opacity); its colour lit like tissue_sample's.
vec4 classified_sample(vec3 p, vec4 pre, vec3 direction_world, out vec3 normal_out) {
    vec3 colour = min(pre.rgb / pre.a, vec3(1.0));
    vec3 normal = vec3(0.0);
    if (SHADING) {
        if (GRADIENT_MODE == 0u) {
            normal = fetch_volume(normal_volume, p).xyz;
        } else {
            vec3 g = GRADIENT_MODE == 1u ? gradient_central(p) : gradient_sobel(p);
            float magnitude = length(g);
            normal = magnitude > params.curvature.z ? g / magnitude : vec3(0.0);
        }
        colour = lit(colour, normal, direction_world);
    }
    normal_out = normal;
    return vec4(colour, pre.a);
}

// MODE 3: the voxel of this invocation classified as a DVR sample at its centre (the variant
// has SHADING off, so the colour is the unlit one), stored premultiplied.
void classify_voxel() {
    ivec3 voxel = ivec3(gl_GlobalInvocationID.xyz);
    if (any(greaterThanEqual(voxel, ivec3(params.dims.xyz)))) {
        return;
    }
    vec3 p = vec3(voxel);
    float v = sample_volume(p);
    vec4 cls = classify_at(p, v);
    vec4 stored = vec4(0.0);
    if (cls.a > 0.0) {
        vec3 unused_normal;
        vec4 tissue = tissue_sample(p, v, cls, vec3(0.0, 0.0, 1.0), params.march.x, false, unused_normal);
        stored = vec4(tissue.rgb * tissue.a, tissue.a);
    }
    imageStore(classified_out, voxel, stored);
}

void main() {
    if (MODE == 3u) {
        classify_voxel();
        return;
    }
    uvec2 pixel = gl_GlobalInvocationID.xy;
    if (PICK) {
        // One ray: the view pixel params.pick.yz of a params.image.xy view (its own jitter
        // included, so the pick lands on what the picture shows there), written to texel (0, 0).
        if (pixel.x != 0u || pixel.y != 0u) {
            return;
        }
        pixel = uvec2(params.pick.yz);
    }
    bool in_image = pixel.x < params.image.x && pixel.y < params.image.y;
    if (!in_image) {
        if (COUNT_SAMPLES) {
            count_samples(0u, 0u);
        }
        return;
    }
    uint marched = 0u;
    uint classified = 0u;
    vec3 origin_world;
    vec3 direction_world;
    camera_ray_world(pixel, origin_world, direction_world);
    vec3 origin = (params.world_to_index * vec4(origin_world, 1.0)).xyz;
    vec3 direction = mat3(params.world_to_index) * direction_world;   // per mm of ray length

    vec3 dims = params.dims.xyz;
    float dt = params.dims.w;
    float t_near;
    float t_far;
    bool hit = intersect_box(origin, direction, dims, t_near, t_far);
    float box_near = t_near;
    hit = hit && clip_ray(origin, direction, dims, t_near, t_far);
    // Samples before this parameter lie in a cut face's cap (none unless a cut moved the entry).
    float cap_end = (hit && t_near > box_near + 1e-4) ? t_near + params.cap.x : -1.0;
    float offset = params.march.z > 0.5 ? jitter(pixel, params.image.z) : 0.5;
    float start = t_near + offset * dt;
    // Samples at start + i * dt for i in [0, n) while inside; clamped before the conversion
    // (float -> uint of negative or huge values is undefined).
    float count = hit ? clamp(floor((t_far - start) / dt) + 1.0, 0.0, float(params.image.w)) : 0.0;
    uint steps = uint(count);

    vec4 result = vec4(params.background.rgb, 1.0);
    if (MODE == MODE_DVR) {
        vec4 acc = vec4(0.0);
        // The surface the depth cues are evaluated at (DEPTH_CUES): where acc.a first reaches 0.5.
        bool surface_found = false;
        vec3 surface_p = vec3(0.0);
        vec3 surface_normal = vec3(0.0);
        // PICK: the ray parameter (mm) of the first sample at which acc.a reaches params.pick.x.
        float pick_t = -1.0;
        for (uint i = 0u; i < steps; i++) {
            float t_sample = start + float(i) * dt;
            vec3 p = origin + direction * t_sample;
            // Opacity exponent of this sample: r, or k r for a long step.
            float r = params.march.x;
            if (SKIP_EMPTY) {
                ivec3 brick = brick_at(p);
                uint b = brick_index(brick);
                uint distance = brick_distance(b);
                bool occupied = distance == 0u;
                if (!occupied || (LONG_STEPS && brick_bound(b) < params.derived_scale.z)) {
                    // An empty brick at distance d has only empty bricks within d - 1 of it: the
                    // ray leaves that cube (at most the reach atlas_slots.w allows; 1 = this
                    // brick only) before it can meet opacity. An occupied brick with a low
                    // bound ends its long step at its own faces.
                    int reach = occupied ? 0 : int(clamp(distance, 1u, max(params.atlas_slots.w, 1u))) - 1;
                    // The last lattice sample at or before the exit: it still lies in the cube
                    // (or on its face), whose halo-covered ranges bound it (lossless).
                    float t_exit = bricks_exit(brick - reach, brick + reach, origin, direction);
                    float last = clamp(floor((t_exit - start) / dt), float(i), float(steps - 1u));
                    if (!occupied) {
                        // Nothing with opacity is skipped.
                        i = uint(last);
                        continue;
                    }
                    uint span = min(uint(params.derived_scale.w), uint(last) - i + 1u);
                    r *= float(span);
                    // The samples this one stands for are not taken (the loop adds the last 1).
                    i += span - 1u;
                }
            }
            float v = 0.0;
            vec4 cls;
            vec4 pre = vec4(0.0);
            if (CLASSIFIED) {
                pre = fetch_volume(classified_volume, p);
                cls = vec4(0.0, 0.0, 0.0, pre.a);
            } else {
                v = sample_volume(p);
                cls = classify_at(p, v);
            }
            marched++;
            uint label = 0u;
            vec4 label_colour = vec4(0.0);
            if (LABELS) {
                label = label_at(nearest_voxel(p));
                label_colour = label_style(label);
            }
            // Each layer's value and style here (one fetch each, only in bricks where a layer
            // may draw; layers.glsl), as scalars with constant layer indices: indexed arrays
            // spill to memory on a CPU device. There (lavapipe) every branch runs under a mask,
            // so the layer code costs its fetches in every sample, drawn or not (BENCHMARKS.md);
            // a GPU skips a branch no lane takes.
            // Plain branches on LAYERS (the build's reflection evaluates IEqual, not `>` on it).
            float layer_v0 = 0.0;
            float layer_v1 = 0.0;
            vec4 layer_c0 = vec4(0.0);
            vec4 layer_c1 = vec4(0.0);
            if (LAYERS == 0u) {
                layer_c0 = vec4(0.0);
            } else if (layer_brick_hit(p)) {
                if (layer_value(0u, p, layer_v0)) {
                    layer_c0 = layer_style(0u, layer_v0);
                }
                if (LAYERS == 2u && layer_value(1u, p, layer_v1)) {
                    layer_c1 = layer_style(1u, layer_v1);
                }
            }
            bool layer_drawn = layer_c0.a > 0.0 || layer_c1.a > 0.0;
            if (cls.a <= 0.0 && label_colour.a <= 0.0 && !layer_drawn) {
                continue;
            }
            vec3 normal = vec3(0.0);
            // Each layer's medium first at this position, so a map shows on the surfaces and cut
            // faces it reaches; tissue in front of it (at earlier samples) still hides it.
            bool drew = false;
            bool solid = start + float(i) * dt < cap_end;
            if (layer_c0.a > 0.0) {
                draw_layer(0u, p, layer_v0, layer_c0, r, solid, direction_world, acc, normal, drew);
            }
            if (layer_c1.a > 0.0) {
                draw_layer(1u, p, layer_v1, layer_c1, r, solid, direction_world, acc, normal, drew);
            }
            if (cls.a > 0.0) {
                classified++;
                vec4 tissue;
                if (CLASSIFIED) {
                    tissue = classified_sample(p, pre, direction_world, normal);
                } else {
                    tissue = tissue_sample(p, v, cls, direction_world, r, solid, normal);
                }
                composite(acc, tissue.rgb, tissue.a);
            }
            if (LABELS && label_colour.a > 0.0) {
                // The label's medium, after the tissue at the same position (labels.glsl).
                vec3 lc = label_colour.rgb;
                if (SHADING) {
                    vec3 label_n = label_normal(nearest_voxel(p), label);
                    lc = lit(lc, label_n, direction_world);
                    normal = cls.a > 0.0 ? normal : label_n;
                }
                composite(acc, lc, opacity_correct(label_colour.a, r));
            }

            if (DEPTH_CUES && !surface_found && acc.a >= CUE_SURFACE_ALPHA) {
                surface_found = true;
                surface_p = p;
                surface_normal = normal;
            }
            if (PICK && pick_t < 0.0 && acc.a >= params.pick.x) {
                pick_t = t_sample;
            }
            if (acc.a > params.march.y) {
                break;
            }
        }
        if (DEPTH_CUES && surface_found) {
            acc.rgb *= surface_cues(surface_p, surface_normal, direction_world);
        }
        result = vec4(acc.rgb + (1.0 - acc.a) * params.background.rgb, 1.0);
        if (PICK) {
            result = vec4(pick_t, acc.a, 0.0, 1.0);
        }
    } else {
        bool found = false;
        // Plain assignments, not `?:` on MODE: glslang would emit an OpSpecConstantOp Select that
        // the build's reflection cannot evaluate.
        float extreme = 1.0;
        if (MODE == MODE_MIP) {
            extreme = 0.0;
        }
        marched = steps;
        // PICK: the ray parameter (mm) of the first sample holding the extreme.
        float extreme_t = -1.0;
        for (uint i = 0u; i < steps; i++) {
            float t = start + float(i) * dt;
            float v = sample_volume(origin + direction * t);
            if (MODE == MODE_MIP) {
                if (PICK && v > extreme) {
                    extreme_t = t;
                }
                extreme = max(extreme, v);
                found = true;
            } else if (v >= params.intensity.z) {
                if (PICK && v < extreme) {
                    extreme_t = t;
                }
                extreme = min(extreme, v);
                found = true;
            }
        }
        if (found) {
            float grey = clamp((extreme - params.intensity.x) / max(params.intensity.y - params.intensity.x, 1e-6), 0.0, 1.0);
            result = vec4(params.crop_hi.w > 0.5 ? colormap_lookup(grey) : vec3(grey), 1.0);
        }
        if (PICK) {
            result = vec4(extreme_t, found ? 1.0 : 0.0, 0.0, 1.0);
        }
    }
    if (PICK) {
        imageStore(target, ivec2(0), result);
    } else {
        imageStore(target, ivec2(pixel), result);
    }
    if (COUNT_SAMPLES) {
        count_samples(marched, classified);
    }
}
