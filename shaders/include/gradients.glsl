// On-the-fly derivatives of I_norm at an index-space position, from trilinear fetches one voxel
// apart: the same stencils as shaders/derivatives.comp at voxel centres, without the border
// rules (clamp-to-edge sampling takes their place). World units via params.gradient_to_world.
#ifndef MORPHRAY_GRADIENTS_GLSL
#define MORPHRAY_GRADIENTS_GLSL

float sample_volume(vec3 p) {
    return textureLod(volume, index_to_texture(p, params.dims.xyz), 0.0).r;
}

mat3 gradient_to_world_matrix() {
    // Columns of the GLSL mat3 are rows of M: this is M^T.
    return mat3(params.gradient_to_world[0].xyz, params.gradient_to_world[1].xyz, params.gradient_to_world[2].xyz);
}

// World gradient (6 fetches).
vec3 gradient_on_the_fly(vec3 p) {
    vec3 g;
    g.x = 0.5 * (sample_volume(p + vec3(1, 0, 0)) - sample_volume(p - vec3(1, 0, 0)));
    g.y = 0.5 * (sample_volume(p + vec3(0, 1, 0)) - sample_volume(p - vec3(0, 1, 0)));
    g.z = 0.5 * (sample_volume(p + vec3(0, 0, 1)) - sample_volume(p - vec3(0, 0, 1)));
    return transpose(gradient_to_world_matrix()) * g;
}

// Directional curvature k = g_hat^T H g_hat in world units (13 more fetches).
float curvature_on_the_fly(vec3 p, float center, vec3 g_world) {
    float m = length(g_world);
    if (m <= params.curvature.z) {
        return 0.0;
    }
    float hxx = sample_volume(p + vec3(1, 0, 0)) - 2.0 * center + sample_volume(p - vec3(1, 0, 0));
    float hyy = sample_volume(p + vec3(0, 1, 0)) - 2.0 * center + sample_volume(p - vec3(0, 1, 0));
    float hzz = sample_volume(p + vec3(0, 0, 1)) - 2.0 * center + sample_volume(p - vec3(0, 0, 1));
    float hxy = 0.25 * (sample_volume(p + vec3(1, 1, 0)) - sample_volume(p + vec3(1, -1, 0))
                      - sample_volume(p + vec3(-1, 1, 0)) + sample_volume(p + vec3(-1, -1, 0)));
    float hxz = 0.25 * (sample_volume(p + vec3(1, 0, 1)) - sample_volume(p + vec3(1, 0, -1))
                      - sample_volume(p + vec3(-1, 0, 1)) + sample_volume(p + vec3(-1, 0, -1)));
    float hyz = 0.25 * (sample_volume(p + vec3(0, 1, 1)) - sample_volume(p + vec3(0, 1, -1))
                      - sample_volume(p + vec3(0, -1, 1)) + sample_volume(p + vec3(0, -1, -1)));
    mat3 h = mat3(hxx, hxy, hxz, hxy, hyy, hyz, hxz, hyz, hzz);
    vec3 v = gradient_to_world_matrix() * (g_world / m);
    return dot(v, h * v);
}

#endif
