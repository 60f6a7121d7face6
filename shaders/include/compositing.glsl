// Opacity correction and front-to-back emission-absorption compositing (paper eqs. 5, 6).
// Twin: src/reference/raymarch.rs (`opacity_correct`, `composite`).
#ifndef MORPHRAY_COMPOSITING_GLSL
#define MORPHRAY_COMPOSITING_GLSL

// log(1 - a) for a in (0, 1): a 5-term series below 0.05 (truncation < 1e-8 relative), log()
// above, where GPU log's absolute error of about 2^-21 near 1 is below 1e-5 of the result.
float log_one_minus(float a) {
    if (a < 0.05) {
        return -a * (1.0 + a * (0.5 + a * (1.0 / 3.0 + a * (0.25 + a * 0.2))));
    }
    return log(1.0 - a);
}

// exp(y) - 1 for y <= 0: a 5-term series above -0.05 (truncation < 1e-9 relative), exp() below.
float exp_minus_one(float y) {
    if (y > -0.05) {
        return y * (1.0 + y * (0.5 + y * (1.0 / 6.0 + y * (1.0 / 24.0 + y / 120.0))));
    }
    return exp(y) - 1.0;
}

// Opacity correction 1 - (1 - a)^r = -expm1(r * log1p(-a)) without f32 cancellation
// (NUMERICS.md: the naive form loses 100 % at a = 1e-9). GPU log/exp are accurate only to about
// 2^-21 absolute near 1, so Kahan's log1p/expm1 tricks would not help; the series above keep
// every step ratio r (1/8 .. 160) within about 2e-5 relative of the f64 value.
float opacity_correct(float a, float r) {
    if (a <= 0.0) {
        return 0.0;
    }
    if (a >= 1.0) {
        return 1.0;
    }
    return -exp_minus_one(r * log_one_minus(a));
}

// The naive f32 form, kept only as the accuracy study's "before" (NAIVE_OPACITY): it loses all
// precision for tiny a (1 - a rounds to 1).
float opacity_correct_naive(float a, float r) {
    return 1.0 - pow(1.0 - clamp(a, 0.0, 1.0), r);
}

// C += (1 - A) a C_s ; A += (1 - A) a   (f32 accumulators, never f16: NUMERICS.md).
void composite(inout vec4 acc, vec3 colour, float a) {
    float w = (1.0 - acc.a) * a;
    acc.rgb += w * colour;
    acc.a += w;
}

#endif
