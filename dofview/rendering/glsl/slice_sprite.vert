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

// The tiles each quad covers are marked (tile_marks.TileMarks), within the draw's box: the run's
// upsampling reads the sprites there.
layout(std430, binding = MARKS_BINDING) buffer Marks { uint marks[]; };
uniform int u_columns;  // the marks' tiles a row
uniform ivec4 u_box;    // the draw's scissor (x0, y0, x1, y1), pixels, GL rows

flat out vec4 v_colour;  // colour / N(ρ)
flat out vec4 v_place;   // (x, y, ρ, visible / N(ρ))

void main() {
    vec4 colour = sprite[2 * gl_InstanceID];
    vec4 place = sprite[2 * gl_InstanceID + 1];
    float norm = kernel_sum(place.z);
    v_colour = colour / norm;
    v_place = vec4(place.xyz, place.w / norm);
    vec2 corner = vec2(gl_VertexID & 1, gl_VertexID >> 1) * 2.0 - 1.0;  // a triangle strip
    float half_size = abs(place.z) * u_reach + 1.5;
    vec2 at = place.xy + 0.5 + corner * half_size;
    gl_Position = vec4(at / u_size * 2.0 - 1.0, 0.0, 1.0);
    if (gl_VertexID == 0) {  // a pixel wider: every pixel centre the quad covers is in a marked tile
        ivec2 first = ivec2(max(floor(place.xy + 0.5 - half_size - 1.0), vec2(u_box.xy))) / TILE;
        ivec2 end = (ivec2(min(ceil(place.xy + 0.5 + half_size + 1.0), vec2(u_box.zw))) + TILE - 1) / TILE;
        for (int y = first.y; y < end.y; ++y)
            for (int x = first.x; x < end.x; ++x) marks[y * u_columns + x] = 1u;
    }
}
