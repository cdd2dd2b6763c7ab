#version 430
// Per-pixel Gaussian alpha with the minimum-alpha cut tau, premultiplied for back-to-front
// blending (ONE, ONE_MINUS_SRC_ALPHA); the second target accumulates alpha-weighted depth.

in vec2 v_offset;
flat in vec3 v_conic;
flat in float v_opacity;
flat in vec3 v_colour;
flat in float v_depth;

uniform float u_tau;

layout(location = 0) out vec4 out_colour;
layout(location = 1) out vec4 out_depth;

void main() {
    vec2 d = v_offset;
    float q = v_conic.x * d.x * d.x + 2.0 * v_conic.y * d.x * d.y + v_conic.z * d.y * d.y;
    if (u_tau == 0.0 && q > 9.0) discard;
    float alpha = min(0.99, v_opacity * exp(-0.5 * q));
    if (alpha < u_tau || !(alpha > 0.0)) discard;
    out_colour = vec4(v_colour * alpha, alpha);
    out_depth = vec4(v_depth * alpha, 0.0, 0.0, alpha);
}
