// Intensity layers in the 3D raymarch (LAYERS > 0; issue 31 item 4). The f64 twin is
// src/reference/raymarch/layers.rs; the rule a value is drawn by is src/scene/layer.rs.
//
// Each layer keeps its own grid: a sample's base index position p maps to the layer's texture
// coordinates through one matrix (both affines composed on the host, engine/layers.rs) and is
// filtered trilinearly from 16-bit codes (value = decode.x + decode.y * code). Off the layer's
// grid nothing is drawn. A value >= threshold takes the positive table at (v - lo) / (hi - lo),
// with a negative side a value <= -threshold the negative table at (-v - lo) / (hi - lo) (256
// RGBA8 entries each, nearest entry); its opacity per mm is the layer's. A drawn sample is
// composited before the tissue's and a label's at the same position (intermixed by depth:
// tissue at earlier samples hides it; it shows on the surfaces and cut faces it reaches). With
// SHADING its normal is the central difference of the layer's value over one base voxel along
// each axis, signed by the side, mapped to world as the tissue's gradient is.
#ifndef MORPHRAY_LAYERS_GLSL
#define MORPHRAY_LAYERS_GLSL

// Whether a layer may draw in the brick of base index position p (a fetch costs about a
// volume sample; a map covers few bricks, so most samples skip it).
bool layer_brick_hit(vec3 p) {
    float side = float(params.layer_bricks.w);
    uvec3 grid = params.layer_bricks.xyz;
    uvec3 b = uvec3(clamp(ivec3(floor((p + 0.5) / side)), ivec3(0), ivec3(grid) - 1));
    uint i = b.x + grid.x * (b.y + grid.y * b.z);
    return (layer_bricks.bits[i >> 5u] & (1u << (i & 31u))) != 0u;
}

// Layer l's value at base index position p; false (and 0) off its grid.
bool layer_value(uint l, vec3 p, out float v) {
    vec3 tc = (params.layer_to_texture[l] * vec4(p, 1.0)).xyz;
    v = 0.0;
    if (any(lessThan(tc, vec3(0.0))) || any(greaterThan(tc, vec3(1.0)))) {
        return false;
    }
    // One layer: the second texture is never sampled (LAYERS folds the choice away).
    float code = (LAYERS == 1u || l == 0u) ? textureLod(layer_volume_0, tc, 0.0).r : textureLod(layer_volume_1, tc, 0.0).r;
    v = params.layer_decode[l].x + params.layer_decode[l].y * code;
    return true;
}

// Colour (rgb) and opacity per mm (a) layer l draws value v with; a = 0 where it draws nothing.
vec4 layer_style(uint l, float v) {
    vec4 w = params.layer_window[l];
    float x;
    uint side;
    if (v >= w.z) {
        x = (v - w.x) / (w.y - w.x);
        side = 0u;
    } else if (params.layer_decode[l].z > 0.5 && v <= -w.z) {
        x = (-v - w.x) / (w.y - w.x);
        side = 1u;
    } else {
        return vec4(0.0);
    }
    uint entry = uint(floor(clamp(x, 0.0, 1.0) * 255.0 + 0.5));
    return vec4(unpackUnorm4x8(layer_colours.rgba[(2u * l + side) * 256u + entry]).rgb, w.w);
}

// World-space normal of layer l at p (not normalized), pointing into what it draws: the side
// (1 positive, -1 negative) times the central difference of its value (0 off the grid).
vec3 layer_normal(uint l, vec3 p, float side) {
    vec3 d;
    for (int a = 0; a < 3; a++) {
        vec3 e = vec3(0.0);
        e[a] = 1.0;
        float up;
        float down;
        layer_value(l, p + e, up);
        layer_value(l, p - e, down);
        d[a] = up - down;
    }
    return transpose(gradient_to_world_matrix()) * (0.5 * side * d);
}

// Composites layer l's sample (value v, style c) at p into acc: lit by its own normal with
// SHADING (unshaded on a cut face, as the tissue there); its normal is the surface's when
// nothing at this position drew before it.
void draw_layer(uint l, vec3 p, float v, vec4 c, float r, bool solid, vec3 view_direction,
                inout vec4 acc, inout vec3 normal, inout bool drew) {
    vec3 colour = c.rgb;
    if (SHADING) {
        vec3 n = solid ? vec3(0.0) : layer_normal(l, p, v >= 0.0 ? 1.0 : -1.0);
        colour = lit(colour, n, view_direction);
        normal = drew ? normal : n;
    }
    composite(acc, colour, opacity_correct(c.a, r));
    drew = true;
}

#endif
