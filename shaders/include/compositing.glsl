// Opacity correction and front-to-back emission-absorption compositing (paper eqs. 5, 6).
// Twin: src/reference/raymarch.rs (`opacity_correct`, `composite`).
#ifndef MORPHRAY_COMPOSITING_GLSL
#define MORPHRAY_COMPOSITING_GLSL

// 1 - (1 - a)^r without f32 cancellation (NUMERICS.md: the naive form loses 100 % at a = 1e-9).
// GPU log/exp are only accurate to about 2^-21 absolute near 1, so Kahan's log1p/expm1 tricks do
// not help here; instead a 4-term binomial series for a < 0.01 (truncation error < 1e-7
// relative for r <= 8) and pow for larger a, where 1 - a is exact enough.
float opacity_correct(float a, float r) {
    if (a <= 0.0) {
        return 0.0;
    }
    if (a >= 1.0) {
        return 1.0;
    }
    if (a < 0.01) {
        return r * a * (1.0 + (1.0 - r) * 0.5 * a * (1.0 + (2.0 - r) / 3.0 * a * (1.0 + (3.0 - r) * 0.25 * a)));
    }
    return 1.0 - pow(1.0 - a, r);
}

// C += (1 - A) a C_s ; A += (1 - A) a   (f32 accumulators, never f16: NUMERICS.md).
void composite(inout vec4 acc, vec3 colour, float a) {
    float w = (1.0 - acc.a) * a;
    acc.rgb += w * colour;
    acc.a += w;
}

#endif
