#version 430
// Sliced depth of field, per layer, at full resolution (the first step of slices.prepare), in the
// tiles its blend marked (slice_tiles.comp lists them: elsewhere the layer is empty): the layer's
// depth sums are added to the frame's (u_acc: the layers in front composited unblurred, so that
// the frame gets the pinhole's depth) under their transmittance T, and the layer's visible coverage
// V·α is kept in the unused third component of its depth sums, to be averaged with them; V, the
// transmittance of the layers in front, is accumulated in the third component of u_acc.
// One workgroup a listed tile, dispatched indirectly (dispatch.glsl's 2D grid).
layout(local_size_x = TILE, local_size_y = TILE) in;

layout(rgba32f, binding = 0) uniform image2D u_acc;
layout(rgba32f, binding = 1) uniform image2D u_colour;
layout(rgba32f, binding = 2) uniform image2D u_depth;
layout(std430, binding = 4) readonly buffer Tiles { uvec2 tiles[]; };
layout(std430, binding = 6) readonly buffer Commands { uvec4 draw; uvec4 dispatch; };  // dispatch.w: tiles
uniform ivec4 u_box;  // (x0, y0, x1, y1) pixels, GL rows

#include "dispatch.glsl"

void main() {
    uint index = group_index();
    if (index >= dispatch.w) return;  // the grid's last row runs past the list
    ivec2 q = ivec2(tiles[index]) * TILE + ivec2(gl_LocalInvocationID.xy);
    if (any(lessThan(q, u_box.xy)) || q.x >= u_box.z || q.y >= u_box.w) return;
    vec4 c = imageLoad(u_colour, q);
    if (c.a <= 0.0) return;  // nothing drawn here (the depth sums are 0 too)
    vec4 d = imageLoad(u_depth, q);
    vec4 acc = imageLoad(u_acc, q);
    float visible = (1.0 - acc.z) * c.a;  // under the layers in front
    vec4 add = (1.0 - acc.a) * d;
    add.z = visible;
    imageStore(u_acc, q, acc + add);
    imageStore(u_depth, q, vec4(d.xy, visible, d.w));
}
