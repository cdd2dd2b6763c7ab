#version 430
// Sliced depth of field, per layer, at full resolution (the first step of slices.prepare): the
// layer's depth sums are added to the frame's (u_acc: the layers in front composited unblurred, so
// that the frame gets the pinhole's depth) under their transmittance T, and the layer's visible
// coverage V·α is kept in the unused third component of its depth sums, to be averaged with them;
// V, the transmittance of the layers in front, is accumulated in the third component of u_acc.
layout(local_size_x = 8, local_size_y = 8) in;

layout(rgba32f, binding = 0) uniform image2D u_acc;
layout(rgba32f, binding = 1) uniform image2D u_colour;
layout(rgba32f, binding = 2) uniform image2D u_depth;
uniform ivec4 u_box;  // (x0, y0, x1, y1) pixels, GL rows

void main() {
    ivec2 q = u_box.xy + ivec2(gl_GlobalInvocationID.xy);
    if (q.x >= u_box.z || q.y >= u_box.w) return;
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
