#version 430
// Sliced depth of field, "hybrid" composite (slices.sliced_image): the "over" composite, and where
// its coverage falls short of the sum of the blurred visible parts (capped at 1), that sum scaled
// to make up the deficit. A surface cut by slice boundaries stays whole (the visible parts add up);
// a blurred foreground edge still reveals what it hid ("over").

uniform sampler2D u_over;
uniform sampler2D u_visible;

out vec4 out_colour;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 o = texelFetch(u_over, p, 0);
    vec4 v = texelFetch(u_visible, p, 0);
    float deficit = max(min(v.a, 1.0) - o.a, 0.0);
    out_colour = o + (v.a > 0.0 ? v * (deficit / max(v.a, 1e-12)) : vec4(0.0));
}
