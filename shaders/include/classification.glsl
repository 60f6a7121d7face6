// Tissue classification: smooth windows, opacity-weighted colour (src/scene/classification.rs
// documents the function; its f64 twin is Classification::classify).
#ifndef MORPHRAY_CLASSIFICATION_GLSL
#define MORPHRAY_CLASSIFICATION_GLSL

float window_weight(float v, vec4 window) {
    // window = (lo, hi, edge, visible); edge >= 1e-4 (smoothstep needs edge0 < edge1).
    return window.w * smoothstep(window.x - window.z, window.x + window.z, v)
                    * (1.0 - smoothstep(window.y - window.z, window.y + window.z, v));
}

// The tissues' and (when drawn) the vessel channel's opacity-weighted colour sums. `brain` is
// the brain mask at the sample (1 without one): the tissues weigh `brain`, the head layer
// (params.head_window / head_colour, opacity 0 when hidden) `1 - brain` (twin:
// Classification::classify_masked).
// One half of the transfer-function table at v (CLASSIFY_TABLE): half 0 the tissues' sums,
// half 1 the head layer's, linearly interpolated between entries (twin: TransferTable::lookup).
const uint TABLE_ENTRIES = 4096u;

// Entry i of the table, through the binding TEXEL_LOOKUPS picks (raymarch.comp).
vec4 table_entry(uint i) {
    return TEXEL_LOOKUPS ? texelFetch(transfer_texels, int(i)) : transfer_table.entries[i];
}

vec4 table_sums(uint half_index, float v) {
    float x = clamp(v, 0.0, 1.0) * float(TABLE_ENTRIES - 1u);
    uint i = min(uint(x), TABLE_ENTRIES - 2u);
    uint base = half_index * TABLE_ENTRIES + i;
    return mix(table_entry(base), table_entry(base + 1u), x - float(i));
}

vec4 classify_sums(float v, float vessel_weight, float brain) {
    float total = vessel_weight;
    vec3 colour = vessel_weight * params.vessel_colour.rgb;
    if (CLASSIFY_TABLE) {
        vec4 tissue = table_sums(0u, v);
        total += brain * tissue.a;
        colour += brain * tissue.rgb;
        if (BRAIN) {
            vec4 head = table_sums(1u, v);
            total += (1.0 - brain) * head.a;
            colour += (1.0 - brain) * head.rgb;
        }
    } else {
        for (int t = 0; t < 4; t++) {
            float w = brain * window_weight(v, params.windows[t]) * params.colours[t].a;
            total += w;
            colour += w * params.colours[t].rgb;
        }
        if (BRAIN) {
            float w = (1.0 - brain) * window_weight(v, params.head_window) * params.head_colour.a;
            total += w;
            colour += w * params.head_colour.rgb;
        }
    }
    if (total <= 0.0) {
        return vec4(0.0);
    }
    return vec4(colour / total, min(total, 1.0));
}

// Returns f(v) in .a (clamped to 1) and the opacity-weighted mean colour in .rgb.
vec4 classify(float v) {
    return classify_sums(v, 0.0, 1.0);
}

// The brain mask at volume position p (BRAIN): the mask is on a working grid of whole blocks of
// voxels spanning params.brain_grid voxels, so a volume position maps to its texture by that
// extent; trilinear (or nearest) as the sampler bound for the interpolation (twin:
// reference::brain::mask_at).
float brain_weight(vec3 p) {
    return texture(brain_mask, (p + 0.5) / params.brain_grid.xyz).r;
}

// classify() inside the brain mask (BRAIN; issue 27).
vec4 classify_in_brain(float v, float vessel_weight, float brain) {
    return classify_sums(v, vessel_weight, brain);
}

// classify() with the vessel channel: one more term, its window on the vesselness (issue 15
// item 3; twin: Classification::classify_with_vessels).
vec4 classify_with_vessels(float v, float vesselness) {
    return classify_sums(v, window_weight(vesselness, params.vessel_window) * params.vessel_colour.a, 1.0);
}

// Curvature weight w(k) = 1 + s * tanh(|k| / k_ref): thin, sharply bent structures (the cortical
// ribbon, sulcal walls, vessels) have large |k| and gain up to (1 + s) times the opacity of smooth
// transitions. tanh written with exp for GLSL 450 portability of large arguments.
float curvature_weight(float k) {
    float x = min(abs(k) * params.curvature.y, 20.0);
    float e = exp(-2.0 * x);
    return 1.0 + params.curvature.x * (1.0 - e) / (1.0 + e);
}

#endif
