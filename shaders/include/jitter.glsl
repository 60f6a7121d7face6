// Per-pixel ray-start jitter in [0, 1): a PCG hash of (x, y, frame). Integer arithmetic only, so
// the f64 reference (src/reference/raymarch.rs, `jitter`) reproduces it exactly.
#ifndef MORPHRAY_JITTER_GLSL
#define MORPHRAY_JITTER_GLSL

uint pcg_hash(uint v) {
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

float jitter(uvec2 pixel, uint frame) {
    uint h = pcg_hash(pixel.x ^ pcg_hash(pixel.y ^ pcg_hash(frame)));
    return float(h >> 8) * (1.0 / 16777216.0);
}

#endif
