#version 430
// The quad backend's deep image, step 1 (an A-buffer): the fragments quads.frag would blend (the
// same alpha and tau cut), recorded instead of blended, for the image rows of the band the
// scissor lets through (u_row0 its first, from the top). With COUNT #defined, each pixel's
// fragments are counted; otherwise each is stored at the next slot of its pixel's segment
// (segments[p] on): its rank in the front-to-back order (the sort key), the slot itself (the
// sort value), its alpha and its pixel; and its splat's colour and depth by rank. Bindings start
// at 5: quads.vert's buffers take 0 to 4.

flat in vec2 v_centre;
flat in vec2 v_axis1;
flat in vec2 v_axis2;
flat in float v_opacity;
flat in vec3 v_colour;
flat in float v_depth;
flat in float v_shape;
flat in uint v_place;  // the instance's place in the back-to-front order

uniform float u_tau;
uniform uint u_n;        // Gaussians in the order
uniform ivec2 u_size;    // image width, height
uniform int u_row0;

#include "lens.glsl"

layout(std430, binding = 5) buffer Counts { uint counts[]; };  // COUNT: per pixel; else the slots taken
#ifndef COUNT
layout(std430, binding = 6) readonly buffer Segments { uint segments[]; };
layout(std430, binding = 7) writeonly buffer Ranks { uint ranks[]; };
layout(std430, binding = 8) writeonly buffer Slots { uint slots[]; };
layout(std430, binding = 9) writeonly buffer Alphas { float alphas[]; };
layout(std430, binding = 10) writeonly buffer Pixels { uint pixels[]; };
layout(std430, binding = 11) writeonly buffer SplatInfo { vec4 splat_info[]; };  // colour, depth by rank
#endif

void main() {
    float alpha = splat_alpha(gl_FragCoord.xy - v_centre, v_axis1, v_axis2, v_opacity, u_tau, v_shape);
    if (!(alpha > 0.0)) discard;
    int row = u_size.y - 1 - int(gl_FragCoord.y) - u_row0;
    uint p = uint(row * u_size.x + int(gl_FragCoord.x));
#ifdef COUNT
    atomicAdd(counts[p], 1u);
#else
    uint slot = segments[p] + atomicAdd(counts[p], 1u);
    uint rank = u_n - 1u - v_place;
    ranks[slot] = rank;
    slots[slot] = slot;
    alphas[slot] = alpha;
    pixels[slot] = p;
    splat_info[rank] = vec4(v_colour, v_depth);
#endif
}
