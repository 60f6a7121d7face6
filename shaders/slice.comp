#version 450
// One plane of I_norm as a window/level greyscale RGBA8 image (the slices of the viewer and of
// `morphray slice`). It samples the SAME normalized volume the raymarch reads; the plane comes in
// index space (pixel (x, y) at origin + x du + y dv), mapped from world millimetres through the
// affine in f64 on the CPU, so oblique volumes are resliced here. Trilinear from eight
// texelFetch reads weighted in f32, not the sampler's filter (8-bit weights on many GPUs), so the
// f64 twin (src/reference/slice.rs) agrees to rounding. Outside the box [-0.5, dim - 0.5]: black.
// Alpha is 1 inside the volume and 0 outside, so a composition can tell them apart.

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

layout(set = 0, binding = 0) uniform sampler3D volume;
layout(set = 0, binding = 1, rgba8) uniform writeonly image2D target;

layout(push_constant) uniform Params {
    vec4 origin;   // xyz: index position of pixel (0, 0)'s centre
    vec4 du;       // xyz: index step per column
    vec4 dv;       // xyz: index step per row
    ivec4 dims;    // xyz: volume dimensions
    vec4 window;   // x: I_norm at black, y: 1 / (white - black)
    ivec4 size;    // xy: image size in pixels
} params;

float voxel(ivec3 p) {
    return texelFetch(volume, clamp(p, ivec3(0), params.dims.xyz - 1), 0).r;
}

void main() {
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (pixel.x >= params.size.x || pixel.y >= params.size.y) {
        return;
    }
    vec3 p = params.origin.xyz + float(pixel.x) * params.du.xyz + float(pixel.y) * params.dv.xyz;
    vec3 hi = vec3(params.dims.xyz) - 0.5;
    vec4 colour = vec4(0.0);
    if (all(greaterThanEqual(p, vec3(-0.5))) && all(lessThanEqual(p, hi))) {
        vec3 base = floor(p);
        vec3 t = p - base;
        ivec3 i = ivec3(base);
        float x00 = mix(voxel(i), voxel(i + ivec3(1, 0, 0)), t.x);
        float x10 = mix(voxel(i + ivec3(0, 1, 0)), voxel(i + ivec3(1, 1, 0)), t.x);
        float x01 = mix(voxel(i + ivec3(0, 0, 1)), voxel(i + ivec3(1, 0, 1)), t.x);
        float x11 = mix(voxel(i + ivec3(0, 1, 1)), voxel(i + ivec3(1, 1, 1)), t.x);
        float v = mix(mix(x00, x10, t.y), mix(x01, x11, t.y), t.z);
        float grey = clamp((v - params.window.x) * params.window.y, 0.0, 1.0);
        colour = vec4(grey, grey, grey, 1.0);
    }
    imageStore(target, pixel, colour);
}
