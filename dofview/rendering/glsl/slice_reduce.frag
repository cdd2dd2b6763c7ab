#version 430
// Sliced depth of field, per reduced layer (slices.reduce2 is the twin): a level of the layer's
// colour and depth sums (with its visible coverage, slice_visible.comp) averaged 2 × 2 into the
// next, or with u_factor 4 twice at once (the level between is not written). One bilinear fetch
// at the corner the four texels share is their exact average (weights ½·½); where the block
// sticks out of the level, clamping to the edge makes it the average of the texels inside. With
// u_factor 4 the four such averages of a texel's block are averaged in turn, over those inside
// the level between, as two passes would (one pass costs llvmpipe a fragment per texel written,
// and the first of the two passes wrote four times as many: docs/BENCHMARKS.md, "Cost in rooms").
// The samplers filter linearly, clamped to the edge.

uniform sampler2D u_colour;
uniform sampler2D u_depth;
uniform int u_factor;  // 2 or 4

layout(location = 0) out vec4 out_colour;
layout(location = 1) out vec4 out_depth;

void main() {
    ivec2 n = textureSize(u_colour, 0);
    ivec2 between = (n + 1) / 2;  // the size of the next level (for u_factor 4 the one between)
    int sub = u_factor / 2;       // 2 × 2 averages a side
    vec4 colour = vec4(0.0), depth = vec4(0.0);
    float count = 0.0;
    for (int j = 0; j < sub; ++j) {
        for (int i = 0; i < sub; ++i) {
            ivec2 q = sub * ivec2(gl_FragCoord.xy) + ivec2(i, j);  // (the first always lies inside)
            if (q.x >= between.x || q.y >= between.y) continue;
            vec2 corner = (2.0 * vec2(q) + 1.0) / vec2(n);
            colour += textureLod(u_colour, corner, 0.0);
            depth += textureLod(u_depth, corner, 0.0);
            count += 1.0;
        }
    }
    out_colour = colour / count;
    out_depth = depth / count;
}
