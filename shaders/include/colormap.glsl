// Colour maps (issue 16 item 4): 16 control points at positions i / 15, linear in between. The
// f64 twin is src/scene/colormap.rs (lookup_points); the table reaches the shader in the uniform
// block. R, G and B go through the same operations, so the gray map gives R = G = B exactly.
#ifndef MORPHRAY_COLORMAP_GLSL
#define MORPHRAY_COLORMAP_GLSL

vec3 colormap_lookup(float x) {
    float scaled = clamp(x, 0.0, 1.0) * 15.0;
    int i = min(int(floor(scaled)), 14);
    float f = scaled - float(i);
    vec3 a = params.colormap[i].rgb;
    vec3 b = params.colormap[i + 1].rgb;
    return a + (b - a) * f;
}

// The display window's position of I_norm v: what the map is indexed by.
float display_position(float v) {
    return clamp((v - params.intensity.x) / max(params.intensity.y - params.intensity.x, 1e-6), 0.0, 1.0);
}

#endif
