#version 430
// Sliced depth of field: a reduced layer's highlights (slice_prepare.frag appended them), each an
// instanced quad over its kernel at full resolution, drawn indirectly from the count the GPU wrote
// (slices.draw_sprites is the twin). The kernel is the gather's (slice_kernel.glsl: the aperture
// or a lens cell, anti-aliased) at the pixel's own signed CoC, normalised by its exact sum N(ρ)
// over every offset, so that each sprite keeps its pixel's light.

#include "slice_kernel.glsl"

layout(std430, binding = 0) readonly buffer Sprites {
    uint header[4];  // slice_prepare.frag's counts
    vec4 sprite[];  // per sprite: colour (blend space, premultiplied), then (x, y, ρ, visible)
};

uniform vec2 u_size;  // the target's pixels

flat out vec4 v_colour;  // colour / N(ρ)
flat out vec4 v_place;   // (x, y, ρ, visible / N(ρ))

void main() {
    vec4 colour = sprite[2 * gl_InstanceID];
    vec4 place = sprite[2 * gl_InstanceID + 1];
    float norm = kernel_sum(place.z);
    v_colour = colour / norm;
    v_place = vec4(place.xyz, place.w / norm);
    vec2 corner = vec2(gl_VertexID & 1, gl_VertexID >> 1) * 2.0 - 1.0;  // a triangle strip
    vec2 at = place.xy + 0.5 + corner * (abs(place.z) * u_reach + 1.5);
    gl_Position = vec4(at / u_size * 2.0 - 1.0, 0.0, 1.0);
}
