#version 430
// One step of the progressive thin lens (rendering/progressive.py): copy a pair of float targets
// (colour, depth sums) scaled by u_scale, the colour first decoded from the display encoding
// (max(c, 0)^2.2, as tonemap.decode) when u_decode is set. Drawn with additive blending it adds a
// pass to the accumulation in linear light; without, it saves or resolves an image.

in vec2 v_uv;

uniform sampler2D u_colour;
uniform sampler2D u_depth;
uniform bool u_decode;
uniform float u_scale;

layout(location = 0) out vec4 out_colour;
layout(location = 1) out vec4 out_depth;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 c = texelFetch(u_colour, p, 0);
    if (u_decode) c.rgb = pow(max(c.rgb, 0.0), vec3(2.2));
    out_colour = c * u_scale;
    out_depth = texelFetch(u_depth, p, 0) * u_scale;
}
