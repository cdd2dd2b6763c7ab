#version 430
// Sliced depth of field, per layer, at full resolution (the first step of slices.prepare), in the
// tiles its blend marked (slice_tiles.comp lists them: elsewhere the layer is empty): the layer's
// depth sums are added to the frame's (u_acc: the layers in front composited unblurred, so that
// the frame gets the pinhole's depth) under their transmittance T, and the layer's visible coverage
// V·α is kept in the unused third component of its depth sums, to be averaged with them; V, the
// transmittance of the layers in front, is accumulated in the third component of u_acc.
// With PREPARE (a layer gathered at full resolution), the texel is also made ready for its gather
// (slice_blur.glsl) into u_a and u_b, and the slice target emptied for the next layer's blend: one
// pass instead of three, each of which read the layer again.
// One workgroup a listed tile, dispatched indirectly (dispatch.glsl's 2D grid).
layout(local_size_x = TILE, local_size_y = TILE) in;

layout(rgba32f, binding = 0) uniform image2D u_acc;
layout(rgba32f, binding = 1) uniform image2D u_colour;
layout(rgba32f, binding = 2) uniform image2D u_depth;
layout(std430, binding = 4) readonly buffer Tiles { uvec2 tiles[]; };
layout(std430, binding = 6) readonly buffer Commands { uvec4 draw; uvec4 dispatch; };  // dispatch.w: tiles
uniform ivec4 u_box;  // (x0, y0, x1, y1) pixels, GL rows

#include "dispatch.glsl"

#ifdef PREPARE
#include "slice_blur.glsl"
layout(rgba32f, binding = 3) uniform writeonly image2D u_a;  // colour / N(ρ)
layout(rg32f, binding = 5) uniform writeonly image2D u_b;    // (ρ, visible coverage / N(ρ))
#endif

void main() {
    uint index = group_index();
    if (index >= dispatch.w) return;  // the grid's last row runs past the list
    ivec2 q = ivec2(tiles[index]) * TILE + ivec2(gl_LocalInvocationID.xy);
    if (any(lessThan(q, u_box.xy)) || q.x >= u_box.z || q.y >= u_box.w) return;
    vec4 c = imageLoad(u_colour, q);
    vec4 d = vec4(0.0);
    if (c.a > 0.0) {  // else nothing was drawn here (the depth sums are 0 too)
        d = imageLoad(u_depth, q);
        vec4 acc = imageLoad(u_acc, q);
        float visible = (1.0 - acc.z) * c.a;  // under the layers in front
        vec4 add = (1.0 - acc.a) * d;
        add.z = visible;
        imageStore(u_acc, q, acc + add);
        d.z = visible;
#ifdef PREPARE
        imageStore(u_colour, q, vec4(0.0));
        imageStore(u_depth, q, vec4(0.0));
#else
        imageStore(u_depth, q, d);
#endif
    }
#ifdef PREPARE
    vec4 a;
    vec2 b;
    prepare_texel(c, d, a, b);
    imageStore(u_a, q, a);
    imageStore(u_b, q, vec4(b, 0.0, 0.0));
#endif
}
