#version 430
// Per-pixel Gaussian alpha with the minimum-alpha cut tau, premultiplied for back-to-front
// blending (ONE, ONE_MINUS_SRC_ALPHA); the second target accumulates alpha-weighted depth (r) and
// alpha-weighted inverse depth (g, for click-to-focus: see Renderer.focus_depth_at).

flat in vec2 v_centre;
flat in vec2 v_axis1;
flat in vec2 v_axis2;
flat in float v_opacity;
flat in vec3 v_colour;
flat in float v_depth;

uniform float u_tau;

layout(location = 0) out vec4 out_colour;
layout(location = 1) out vec4 out_depth;

void main() {
    vec2 d = gl_FragCoord.xy - v_centre;
    vec2 u = vec2(dot(d, v_axis1), dot(d, v_axis2));  // offset in std-devs along the axes
    float q = dot(u, u);  // d^T Sigma^-1 d
    if (q > 9.0) discard;  // 3 sigma, whatever tau (see splat.vert)
    float alpha = min(0.99, v_opacity * exp(-0.5 * q));
    if (alpha < u_tau || !(alpha > 0.0)) discard;
    out_colour = vec4(v_colour * alpha, alpha);
    out_depth = vec4(v_depth * alpha, alpha / v_depth, 0.0, alpha);
}
