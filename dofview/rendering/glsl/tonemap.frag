#version 430
// Display pass (Eq. 7 with an operator): composite the background in the blend's own space, take
// the result to linear light, expose, tone map with the operator file named by the OPERATOR define
// (tonemap_<name>.glsl, defining vec3 tone_map(vec3)), gamma-encode. Mirrors tonemap/base.py:display.

in vec2 v_uv;
#include "tonemap_input.glsl"
uniform float u_gamma;
uniform bool u_focus_aid;     // tint the in-focus band
uniform sampler2D u_depth;    // alpha-weighted depth (r) and alpha (a)
uniform float u_aperture;
uniform float u_inv_focus;

out vec4 out_colour;

#include OPERATOR

void main() {
    vec3 lin = exposed_linear(texture(u_colour, v_uv));
    vec3 outc = pow(clamp(tone_map(lin), 0.0, 1.0), vec3(1.0 / u_gamma));
    if (u_focus_aid) {
        vec4 d = texture(u_depth, v_uv);
        if (d.a > 0.5) {
            float z = d.r / d.a;
            float R = 0.5 * u_aperture * abs(1.0 / z - u_inv_focus);
            if (R < 1.0) outc = mix(outc, vec3(0.1, 1.0, 0.3), 0.35);
        }
    }
    out_colour = vec4(outc, 1.0);
}
