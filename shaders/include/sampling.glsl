// Volume fetches at an index-space position p (voxel centres at integers) with the scene's
// interpolation, a specialization constant (INTERPOLATION): 0 nearest, 1 trilinear (hardware),
// 2 tricubic B-spline from 8 trilinear fetches (Sigg & Hadwiger, GPU Gems 2, ch. 20: per axis the
// four B-spline weights collapse into two linear fetches at offsets h0, h1 with weights g0, g1).
// The B-spline approximates rather than interpolates: it smooths, which the accuracy study
// measures. The f64 twin is src/reference/raymarch.rs (`fetch`).
#ifndef MORPHRAY_SAMPLING_GLSL
#define MORPHRAY_SAMPLING_GLSL

const uint INTERPOLATION_NEAREST = 0u;
const uint INTERPOLATION_TRILINEAR = 1u;
const uint INTERPOLATION_TRICUBIC = 2u;

vec4 fetch_linear(sampler3D tex, vec3 p, vec3 dims) {
    return textureLod(tex, (p + 0.5) / dims, 0.0);
}

vec4 fetch(sampler3D tex, vec3 p, vec3 dims) {
    if (INTERPOLATION == INTERPOLATION_NEAREST) {
        ivec3 q = clamp(ivec3(floor(p + 0.5)), ivec3(0), ivec3(dims) - 1);
        return texelFetch(tex, q, 0);
    } else if (INTERPOLATION == INTERPOLATION_TRICUBIC) {
        vec3 i = floor(p);
        vec3 t = p - i;
        vec3 t2 = t * t;
        vec3 t3 = t2 * t;
        vec3 w0 = (1.0 - 3.0 * t + 3.0 * t2 - t3) / 6.0;
        vec3 w1 = (4.0 - 6.0 * t2 + 3.0 * t3) / 6.0;
        vec3 w2 = (1.0 + 3.0 * t + 3.0 * t2 - 3.0 * t3) / 6.0;
        vec3 w3 = t3 / 6.0;
        vec3 g0 = w0 + w1;
        vec3 g1 = w2 + w3;
        vec3 p0 = i - 1.0 + w1 / g0;   // fetch positions in index space
        vec3 p1 = i + 1.0 + w3 / g1;
        vec4 r = vec4(0.0);
        r += g0.x * g0.y * g0.z * fetch_linear(tex, vec3(p0.x, p0.y, p0.z), dims);
        r += g1.x * g0.y * g0.z * fetch_linear(tex, vec3(p1.x, p0.y, p0.z), dims);
        r += g0.x * g1.y * g0.z * fetch_linear(tex, vec3(p0.x, p1.y, p0.z), dims);
        r += g1.x * g1.y * g0.z * fetch_linear(tex, vec3(p1.x, p1.y, p0.z), dims);
        r += g0.x * g0.y * g1.z * fetch_linear(tex, vec3(p0.x, p0.y, p1.z), dims);
        r += g1.x * g0.y * g1.z * fetch_linear(tex, vec3(p1.x, p0.y, p1.z), dims);
        r += g0.x * g1.y * g1.z * fetch_linear(tex, vec3(p0.x, p1.y, p1.z), dims);
        r += g1.x * g1.y * g1.z * fetch_linear(tex, vec3(p1.x, p1.y, p1.z), dims);
        return r;
    }
    return fetch_linear(tex, p, dims);
}

// Bricked volumes (BRICKED): the textures are atlases of resident bricks. A volume position p
// maps to its brick (side params.atlas.w, halo params.brick_grid.w), the brick table gives the
// brick's slot (0 = not resident: nothing a visible tissue can occupy there), and the position
// inside the slot is p relative to the brick plus the halo. The halo holds the neighbouring
// voxels (clamped at the volume's border, like clamp-to-edge), so every interpolation's taps
// stay inside the slot. Returns false for a brick that is not resident.
bool brick_to_atlas(vec3 p, out vec3 q) {
    float side = params.atlas.w;
    ivec3 grid = ivec3(params.brick_grid.xyz);
    ivec3 b = clamp(ivec3(floor((p + 0.5) / side)), ivec3(0), grid - 1);
    uint slot = brick_table.slots[uint(b.x) + uint(grid.x) * (uint(b.y) + uint(grid.y) * uint(b.z))];
    if (slot == 0u) {
        return false;
    }
    slot -= 1u;
    float halo = float(params.brick_grid.w);
    uvec2 slots = params.atlas_slots.xy;
    vec3 s = vec3(float(slot % slots.x), float((slot / slots.x) % slots.y), float(slot / (slots.x * slots.y)));
    q = s * (side + 2.0 * halo) + halo + (p - vec3(b) * side);
    return true;
}

bool volume_to_atlas(vec3 p, out vec3 q) {
    q = p;
    // `if (BRICKED)` around the body, not `if (!BRICKED) return`: glslang folds `!` of a
    // specialization constant into an OpSpecConstantOp the build's reflection cannot evaluate.
    if (BRICKED) {
        return brick_to_atlas(p, q);
    }
    return true;
}

// Dimensions of the sampled textures: the atlas when bricked, else the volume.
vec3 texture_dims() {
    vec3 d = params.dims.xyz;
    if (BRICKED) {
        d = params.atlas.xyz;
    }
    return d;
}

// A fetch of any volume-shaped texture at volume position p (0 where a brick is not resident).
vec4 fetch_volume(sampler3D tex, vec3 p) {
    vec3 q;
    if (!volume_to_atlas(p, q)) {
        return vec4(0.0);
    }
    return fetch(tex, q, texture_dims());
}

float sample_volume(vec3 p) {
    return fetch_volume(volume, p).r;
}

#endif
