#version 430
// Sliced depth of field: one highlight's sprite (slice_sprite.vert), w(d, ρ)/N(ρ) of its light at
// offset d, added (ONE, ONE) into the sprite targets, which slice_upsample.frag adds to its layer's
// gathered image when that is composited into the frame.

#include "slice_kernel.glsl"

flat in vec4 v_colour;
flat in vec4 v_place;

layout(location = 0) out vec4 out_colour;
layout(location = 1) out vec4 out_visible;

void main() {
    vec2 d = floor(gl_FragCoord.xy) - v_place.xy;
    float w = kernel_weight(d, v_place.z);
    if (w <= 0.0) discard;
    out_colour = w * v_colour;
    out_visible = vec4(w * v_place.w, 0.0, 0.0, 0.0);
}
