#version 430
// Sliced depth of field, per layer, at its level 1/u_scale (the last step of slices.prepare): each
// texel's signed blur ρ is the CoC c of its mean inverse depth (Σw/z over Σw), shrunk by what the
// level's own down- and upsampling spread (|ρ| = sqrt(c² − u_shrink) / u_scale level px, at most
// u_rmax); its colour and visible coverage (slice_visible.comp) are divided by the kernel's
// N(ρ) = Σ_taps w(d, ρ) (slice_kernel.glsl), so that the gather keeps every pixel's light,
// interpolated in tables of it: summing the taps per texel cost half of what the gather costs.

uniform sampler2D u_colour;
uniform sampler2D u_depth;

uniform int u_scale;
uniform bool u_blur;       // false: a layer drawn blurred already (radius 0)
uniform float u_aperture;  // A at the frame's size, px·scene unit
uniform float u_inv_focus;
uniform float u_shrink;    // 4β(s² − 1), px²
uniform float u_rmax;      // the layer's largest radius, level px
uniform sampler2D u_norm;  // N(ρ) (LensCell.norms), rows: fine in front, fine behind, whole range in front, behind
uniform float u_norm_range;  // |ρ| of the whole range's last sample

layout(location = 0) out vec4 out_a;  // colour / N(ρ)
layout(location = 1) out vec2 out_b;  // (ρ, visible coverage / N(ρ))

// N(ρ), interpolated linearly in its tables (texels fetched, not filtered: exact weights).
float kernel_norm(float rho) {
    bool fine = abs(rho) <= NORM_FINE;
    float x = abs(rho) / (fine ? NORM_FINE : u_norm_range) * float(NORM_SAMPLES - 1);
    int i = min(int(x), NORM_SAMPLES - 2);
    int row = (fine ? 0 : 2) + (rho < 0.0 ? 1 : 0);
    return mix(texelFetch(u_norm, ivec2(i, row), 0).r, texelFetch(u_norm, ivec2(i + 1, row), 0).r, x - float(i));
}

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 colour = texelFetch(u_colour, p, 0);
    vec4 depth = colour.a > 0.0 ? texelFetch(u_depth, p, 0) : vec4(0.0);
    float rho = 0.0;
    if (u_blur && depth.w > 0.0) {
        float c = 0.5 * u_aperture * (depth.y / depth.w - u_inv_focus);
        rho = sign(c) * min(sqrt(max(c * c - u_shrink, 0.0)) / float(u_scale), u_rmax);
    }
    float norm = kernel_norm(rho);
    out_a = colour / norm;
    out_b = vec2(rho, depth.z / norm);
}
