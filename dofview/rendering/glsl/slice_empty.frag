#version 430
// Sliced depth of field: the slice target emptied where a layer was (its listed tiles,
// slice_tiles.vert), for the next layer's blend.
layout(location = 0) out vec4 out_colour;
layout(location = 1) out vec4 out_depth;

void main() {
    out_colour = vec4(0.0);
    out_depth = vec4(0.0);
}
