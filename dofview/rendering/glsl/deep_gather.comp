#version 430
// The quad backend's deep image, step 2, between its two sorts: the fragments sorted by rank
// (their slots in slots[]) get their pixels as the keys of the second, stable sort, and their
// place in the rank order as its values, so that the second sort leaves each pixel's fragments
// together, front to back.
layout(local_size_x = 256) in;

#include "dispatch.glsl"

layout(std430, binding = 0) readonly buffer Slots { uint slots[]; };
layout(std430, binding = 1) readonly buffer Pixels { uint pixels[]; };
layout(std430, binding = 2) writeonly buffer Keys { uint keys[]; };
layout(std430, binding = 3) writeonly buffer Places { uint places[]; };
uniform uint u_n;

void main() {
    uint i = group_index() * 256u + gl_LocalInvocationID.x;
    if (i >= u_n) return;
    keys[i] = pixels[slots[i]];
    places[i] = i;
}
