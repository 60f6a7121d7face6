// On-the-fly derivatives of I_norm at an index-space position, from volume fetches one voxel
// apart (with the scene's interpolation, sampling.glsl): the stencils of shaders/derivatives.comp
// at voxel centres, without the border rules (clamp-to-edge sampling takes their place). World
// units via params.gradient_to_world. The f64 twins are in src/reference/raymarch.rs.
#ifndef MORPHRAY_GRADIENTS_GLSL
#define MORPHRAY_GRADIENTS_GLSL

mat3 gradient_to_world_matrix() {
    // Columns of the GLSL mat3 are rows of M: this is M^T.
    return mat3(params.gradient_to_world[0].xyz, params.gradient_to_world[1].xyz, params.gradient_to_world[2].xyz);
}

// World gradient by central differences (6 fetches).
vec3 gradient_central(vec3 p) {
    vec3 g;
    g.x = 0.5 * (sample_volume(p + vec3(1, 0, 0)) - sample_volume(p - vec3(1, 0, 0)));
    g.y = 0.5 * (sample_volume(p + vec3(0, 1, 0)) - sample_volume(p - vec3(0, 1, 0)));
    g.z = 0.5 * (sample_volume(p + vec3(0, 0, 1)) - sample_volume(p - vec3(0, 0, 1)));
    return transpose(gradient_to_world_matrix()) * g;
}

// World gradient by a smoothed (Sobel-like) difference: the central difference along an axis,
// averaged over the four positions at +-0.5 voxel across it (24 fetches). At voxel centres with
// trilinear sampling this is exactly the separable 3D Sobel filter [1 2 1] x [1 2 1] x [-1 0 1]
// normalized to a derivative; it trades resolution for noise suppression.
vec3 gradient_sobel(vec3 p) {
    vec3 g = vec3(0.0);
    for (int a = 0; a < 3; a++) {
        int b = (a + 1) % 3;
        int c = (a + 2) % 3;
        for (int s = 0; s < 4; s++) {
            vec3 o = vec3(0.0);
            o[b] = (s & 1) == 0 ? -0.5 : 0.5;
            o[c] = (s & 2) == 0 ? -0.5 : 0.5;
            vec3 e = vec3(0.0);
            e[a] = 1.0;
            g[a] += sample_volume(p + o + e) - sample_volume(p + o - e);
        }
    }
    return transpose(gradient_to_world_matrix()) * (g * 0.125);
}

// Directional curvature k = g_hat^T H g_hat in world units (13 fetches beyond the 6 of the
// central gradient; `center` is the sample at p).
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
