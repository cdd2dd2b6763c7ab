#version 430
// Sliced depth of field: a run of layers composited at 1/u_scale resolution, upsampled bilinearly
// (pixel centres aligned, clamped at the borders: slices.upsample) with the run's sprites added at
// full resolution (slice_sprite.frag), and blended behind what the frame's accumulators hold
// (ONE_MINUS_DST_ALPHA, ONE): "over" for the colour, a sum for the visible coverage (its alpha
// stays 0).

uniform sampler2D u_over;
uniform sampler2D u_visible;
uniform sampler2D u_sprites;         // the run's sprites: colour
uniform sampler2D u_sprite_visible;  // and visible coverage
uniform int u_scale;

layout(location = 0) out vec4 out_colour;
layout(location = 1) out vec4 out_visible;

void main() {
    ivec2 n = textureSize(u_over, 0);
    vec2 pos = clamp((gl_FragCoord.xy) / float(u_scale) - 0.5, vec2(0.0), vec2(n - 1));
    ivec2 i0 = ivec2(floor(pos));
    ivec2 i1 = min(i0 + 1, n - 1);
    vec2 f = pos - vec2(i0);
    vec4 lower = mix(texelFetch(u_over, i0, 0), texelFetch(u_over, ivec2(i1.x, i0.y), 0), f.x);
    vec4 upper = mix(texelFetch(u_over, ivec2(i0.x, i1.y), 0), texelFetch(u_over, i1, 0), f.x);
    ivec2 p = ivec2(gl_FragCoord.xy);
    out_colour = mix(lower, upper, f.y) + texelFetch(u_sprites, p, 0);
    float vl = mix(texelFetch(u_visible, i0, 0).r, texelFetch(u_visible, ivec2(i1.x, i0.y), 0).r, f.x);
    float vu = mix(texelFetch(u_visible, ivec2(i0.x, i1.y), 0).r, texelFetch(u_visible, i1, 0).r, f.x);
    out_visible = vec4(mix(vl, vu, f.y) + texelFetch(u_sprite_visible, p, 0).r, 0.0, 0.0, 0.0);
}
