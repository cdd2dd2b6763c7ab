// Sliced depth of field: a texel of a layer at its level 1/u_scale made ready for the gather (the
// last step of slices.prepare; slice_prepare.frag, and slice_visible.comp at full resolution). Its
// signed blur ρ is the CoC c of its mean inverse depth (Σw/z over Σw), shrunk by what the level's
// own down- and upsampling spread (|ρ| = sqrt(c² − u_shrink) / u_scale level px, at most u_rmax);
// its colour and visible coverage are divided by the kernel's N(ρ) = Σ_taps w(d, ρ)
// (slice_kernel.glsl), so that the gather keeps every pixel's light, interpolated in tables of it:
// summing the taps per texel cost half of what the gather costs.

uniform int u_scale;
uniform bool u_blur;       // false: a layer drawn blurred already (radius 0)
uniform float u_aperture;  // A at the frame's size, px·scene unit
uniform float u_inv_focus;
uniform float u_shrink;    // 4β(s² − 1), px²
uniform float u_rmax;      // the layer's largest radius, level px
// N(ρ) (LensCell.norms), rows: fine in front, fine behind, whole range in front, behind; loaded
// through an image unit (cheaper than a sampler's fetch on llvmpipe)
layout(r32f, binding = 7) uniform readonly image2D u_norm;
uniform float u_norm_range;  // |ρ| of the whole range's last sample

// N(ρ), interpolated linearly in its tables (texels loaded, not filtered: exact weights).
float kernel_norm(float rho) {
    bool fine = abs(rho) <= NORM_FINE;
    float x = abs(rho) / (fine ? NORM_FINE : u_norm_range) * float(NORM_SAMPLES - 1);
    int i = min(int(x), NORM_SAMPLES - 2);
    int row = (fine ? 0 : 2) + (rho < 0.0 ? 1 : 0);
    return mix(imageLoad(u_norm, ivec2(i, row)).r, imageLoad(u_norm, ivec2(i + 1, row)).r, x - float(i));
}

// The texel of colour and depth sums (visible coverage third) as the gather reads it:
// a = colour / N(ρ), b = (ρ, visible coverage / N(ρ)).
void prepare_texel(vec4 colour, vec4 depth, out vec4 a, out vec2 b) {
    float rho = 0.0;
    if (u_blur && depth.w > 0.0) {
        float c = 0.5 * u_aperture * (depth.y / depth.w - u_inv_focus);
        rho = sign(c) * min(sqrt(max(c * c - u_shrink, 0.0)) / float(u_scale), u_rmax);
    }
    float norm = kernel_norm(rho);
    a = colour / norm;
    b = vec2(rho, depth.z / norm);
}
