#version 430
// Sliced depth of field, per reduced layer (slices.reduce2 is the twin): a level of the layer's
// colour and depth sums (with its visible coverage, slice_visible.comp) averaged 2 × 2 into the
// next. One bilinear fetch at the corner the four texels share is their exact average (weights ½·½);
// where the block sticks out of the level, clamping to the edge makes it the average of the texels
// inside. The samplers filter linearly, clamped to the edge.

uniform sampler2D u_colour;
uniform sampler2D u_depth;

layout(location = 0) out vec4 out_colour;
layout(location = 1) out vec4 out_depth;

void main() {
    vec2 size = vec2(textureSize(u_colour, 0));
    vec2 corner = 2.0 * floor(gl_FragCoord.xy) + 1.0;
    out_colour = textureLod(u_colour, corner / size, 0.0);
    out_depth = textureLod(u_depth, corner / size, 0.0);
}
