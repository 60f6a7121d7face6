// Label overlays in the 3D raymarch (LABELS only; issue 16 item 3). The f64 twin is
// src/reference/raymarch/labels.rs.
//
// A label map resampled onto the volume's grid (scene::overlay::resample) is a storage buffer of
// u16 labels, two per word, x fastest; a sample takes the label of its nearest voxel (labels are
// categories: interpolating them means nothing). Each label's colour and opacity per millimetre
// are one RGBA8 word of a lookup table (alpha 0 for hidden labels and labels missing from it);
// a labelled sample is composited as a medium of its own right after the tissue's sample at the
// same position, so a structure shows through tissues of low opacity and hides behind opaque
// ones. With SHADING its normal is the central difference of the label's indicator function
// (1 inside the label, 0 outside) over the six neighbouring voxels, so a segmentation reads as a
// shaded surface rather than a flat silhouette.
#ifndef MORPHRAY_LABELS_GLSL
#define MORPHRAY_LABELS_GLSL

// The voxel whose centre is nearest to index position p (voxel centres are at integers).
ivec3 nearest_voxel(vec3 p) {
    return ivec3(floor(p + 0.5));
}

// The label of voxel q, 0 outside the grid.
uint label_at(ivec3 q) {
    ivec3 d = ivec3(params.dims.xyz);
    if (any(lessThan(q, ivec3(0))) || any(greaterThanEqual(q, d))) {
        return 0u;
    }
    uint index = uint(q.x) + uint(d.x) * (uint(q.y) + uint(d.y) * uint(q.z));
    return bitfieldExtract(label_values.words[index >> 1u], int((index & 1u) * 16u), 16);
}

// Colour (rgb) and opacity per mm (a) of a label; 0 for label 0 and labels past the table.
vec4 label_style(uint label) {
    if (label == 0u || label >= uint(label_colours.rgba.length())) {
        return vec4(0.0);
    }
    return unpackUnorm4x8(label_colours.rgba[label]);
}

// World-space normal of the label's surface at voxel q (not normalized; shade() normalizes and
// keeps the colour where it is tiny: inside a label, away from its surface).
vec3 label_normal(ivec3 q, uint label) {
    vec3 d;
    for (int a = 0; a < 3; a++) {
        ivec3 e = ivec3(0);
        e[a] = 1;
        d[a] = float(label_at(q + e) == label) - float(label_at(q - e) == label);
    }
    return transpose(gradient_to_world_matrix()) * (0.5 * d);
}

#endif
