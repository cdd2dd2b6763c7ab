#version 430
// Per-pixel splat alpha (lens.glsl: the kernel, its support and tau cuts), premultiplied for back-to-front
// blending (ONE, ONE_MINUS_SRC_ALPHA); the second target accumulates alpha-weighted depth (r) and
// alpha-weighted inverse depth (g, for click-to-focus: see Frame.focus_depth).

flat in vec2 v_centre;
flat in vec2 v_axis1;
flat in vec2 v_axis2;
flat in float v_opacity;
flat in vec3 v_colour;
flat in float v_depth;
flat in float v_shape;

uniform float u_tau;

layout(location = 0) out vec4 out_colour;
layout(location = 1) out vec4 out_depth;

#include "lens.glsl"

void main() {
    float alpha = splat_alpha(gl_FragCoord.xy - v_centre, v_axis1, v_axis2, v_opacity, u_tau, v_shape);
    if (!(alpha > 0.0)) discard;
    out_colour = vec4(v_colour * alpha, alpha);
    out_depth = vec4(v_depth * alpha, alpha / v_depth, 0.0, alpha);
}
