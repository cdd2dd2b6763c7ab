#version 430
// Sliced depth of field: a run of layers composited at 1/u_scale resolution, upsampled bilinearly
// by the texture unit (the samplers filter linearly, clamped to the edge: pixel centres aligned,
// slices.upsample is the twin; one filtered fetch cost llvmpipe less than four texel fetches and
// their weights: docs/BENCHMARKS.md, "Cost in rooms"), with the run's sprites added at full
// resolution (slice_sprite.frag), and blended behind what the frame's accumulators hold
// (ONE_MINUS_DST_ALPHA, ONE): "over" for the colour, a sum for the visible coverage (its alpha
// stays 0). The weights (k + ½)/u_scale need log2(u_scale) + 1 fractional bits: a GPU that
// filters with 8 (NVIDIA) rounds them at the levels 1/256 and 1/512 only, by at most 1/512 of the
// difference between neighbouring texels.

uniform sampler2D u_over;
uniform sampler2D u_visible;
uniform sampler2D u_sprites;         // the run's sprites: colour
uniform sampler2D u_sprite_visible;  // and visible coverage
uniform int u_scale;

layout(location = 0) out vec4 out_colour;
layout(location = 1) out vec4 out_visible;

void main() {
    vec2 uv = gl_FragCoord.xy / (float(u_scale) * vec2(textureSize(u_over, 0)));
    ivec2 p = ivec2(gl_FragCoord.xy);
    out_colour = textureLod(u_over, uv, 0.0) + texelFetch(u_sprites, p, 0);
    out_visible = vec4(textureLod(u_visible, uv, 0.0).r + texelFetch(u_sprite_visible, p, 0).r, 0.0, 0.0, 0.0);
}
