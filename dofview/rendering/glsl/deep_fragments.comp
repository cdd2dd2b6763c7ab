#version 430
// The quad backend's deep image, step 3: one thread per pixel of the band walks its fragments front
// to back (segments[p] to segments[p + 1] of the twice-sorted list: places[] points into the rank
// order, whose ranks and slots the first sort left in ranks[] and slots[]) into deep samples
// (deep_walk.glsl). A pass walks at most u_take fragments from the u_skip-th on (llvmpipe's loop limit).
layout(local_size_x = 8, local_size_y = 8) in;

#include "deep_walk.glsl"

layout(std430, binding = 0) readonly buffer Places { uint places[]; };
layout(std430, binding = 1) readonly buffer Ranks { uint ranks[]; };
layout(std430, binding = 2) readonly buffer Slots { uint slots[]; };
layout(std430, binding = 3) readonly buffer Alphas { float alphas[]; };
layout(std430, binding = 4) readonly buffer SplatInfo { vec4 splat_info[]; };
layout(std430, binding = 5) readonly buffer Segments { uint segments[]; };
uniform ivec2 u_band;  // width, rows of the band
uniform uint u_skip;
uniform uint u_take;

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (px.x >= u_band.x || px.y >= u_band.y) return;
    uint p = uint(px.y * u_band.x + px.x);
    DeepState s = deep_begin(p);
    uint first = min(segments[p + 1u], segments[p] + u_skip);
    uint end = first + min(segments[p + 1u] - first, u_take);
    for (uint j = first; j < end && deep_live(s); ++j) {
        uint i = places[j];
        vec4 info = splat_info[ranks[i]];
        deep_step(s, p, alphas[slots[i]], info.rgb, info.w);
    }
    deep_finish(s, p);
}
