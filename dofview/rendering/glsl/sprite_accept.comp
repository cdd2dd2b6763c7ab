#version 430
// Whether a layer's highlights, appended by slice_prepare.frag as if they fit, fit in what is left
// of the frame's cap of sprites: then all of them are drawn; else none (the layer's draw of them is
// emptied) and the prepare is drawn again without highlights, so that they stay in the layer's
// gather. The frame so does not depend on the order in which the GPU ran the prepare's fragments.
layout(local_size_x = 1) in;

uniform uint u_cap;  // sprites a frame

layout(std430, binding = 0) buffer Sprites {
    uint taken;  // sprites of the layers accepted so far this frame
    uint pad[3];
};
layout(std430, binding = 1) buffer Draw {  // the layer's indirect draw of its sprites
    uint vertices;
    uint instances;  // its highlights, all counted (those beyond the cap not kept)
    uint first;
    uint base;
};
layout(std430, binding = 2) buffer Again {  // the indirect draw of the prepare without highlights
    uint count;
    uint again;  // 1: the layer was refused
    uint start;
    uint base_instance;
};

void main() {
    bool fits = instances <= u_cap && taken <= u_cap - instances;
    if (fits) {
        taken += instances;
    } else {
        instances = 0u;
    }
    again = fits ? 0u : 1u;
}
