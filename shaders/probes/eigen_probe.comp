#version 450
// Test probe for shaders/include/eigen3.glsl: runs the vesselness pass's own `sym3_eigenvalues`
// on host-chosen symmetric matrices, so tests can measure it against its f64 twin
// (src/reference/eigen.rs) on the hard cases of NUMERICS.md (repeated and nearly repeated
// eigenvalues, zero, rank 1 and 2, huge and tiny magnitudes, NaN/Inf), which a volume cannot
// reach. Each item also gets the naive closed form (Smith's trigonometric formula, unscaled) in
// f32, so a test can show that the bound it asserts would catch the technique being removed.
//
// Item i: inputs[2i] = (a00, a11, a22, a01), inputs[2i+1] = (a02, a12, -, -);
// outputs[2i] = (Jacobi eigenvalues ascending, 0), outputs[2i+1] = (naive ascending, 0).
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64, local_size_y = 1, local_size_z = 1) in;

layout(set = 0, binding = 0, std430) readonly buffer ProbeInputs { vec4 items[]; } inputs;
layout(set = 0, binding = 1, std430) writeonly buffer ProbeOutputs { vec4 items[]; } outputs;

layout(push_constant) uniform Params {
    uint count;   // matrices
} params;

#include "eigen3.glsl"

// Smith (1961), as commonly written: no scaling, eigenvalue 2 from the trace.
vec3 naive_eigenvalues(float a00, float a11, float a22, float a01, float a02, float a12) {
    float q = (a00 + a11 + a22) / 3.0;
    float p1 = a01 * a01 + a02 * a02 + a12 * a12;
    float p2 = (a00 - q) * (a00 - q) + (a11 - q) * (a11 - q) + (a22 - q) * (a22 - q) + 2.0 * p1;
    float p = sqrt(p2 / 6.0);
    if (p == 0.0) {
        return vec3(q);
    }
    mat3 b = (mat3(a00, a01, a02, a01, a11, a12, a02, a12, a22) - q * mat3(1.0)) / p;
    float r = clamp(determinant(b) / 2.0, -1.0, 1.0);
    float phi = acos(r) / 3.0;
    float e1 = q + 2.0 * p * cos(phi);
    float e3 = q + 2.0 * p * cos(phi + 2.0943951);
    float e2 = 3.0 * q - e1 - e3;
    return vec3(e3, e2, e1);
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= params.count) {
        return;
    }
    vec4 a = inputs.items[2u * i];
    vec4 b = inputs.items[2u * i + 1u];
    outputs.items[2u * i] = vec4(sym3_eigenvalues(a.x, a.y, a.z, a.w, b.x, b.y), 0.0);
    outputs.items[2u * i + 1u] = vec4(naive_eigenvalues(a.x, a.y, a.z, a.w, b.x, b.y), 0.0);
}
