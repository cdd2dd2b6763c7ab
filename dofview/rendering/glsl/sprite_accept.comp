#version 430
// Whether a layer's highlights, counted by slice_prepare.frag's u_count pass, fit in what is left of
// the frame's cap of sprites: all of them are drawn, or none (they stay in the layer's gather), so
// the frame does not depend on the order in which the GPU ran the prepare's fragments.
layout(local_size_x = 1) in;

uniform uint u_cap;  // sprites a frame

layout(std430, binding = 0) buffer Sprites {
    uint taken;     // sprites of the layers accepted so far this frame
    uint asked;     // this layer's highlights (left at 0 for the next layer's count)
    uint accepted;  // out: whether they are drawn
    uint pad;
};

void main() {
    accepted = (asked <= u_cap && taken <= u_cap - asked) ? 1u : 0u;
    if (accepted == 1u) taken += asked;
    asked = 0u;
}
