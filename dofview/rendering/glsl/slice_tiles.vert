#version 430
// A pass of the sliced mode over the runs of tiles slice_tiles.comp listed: an instance a run,
// four vertices (a triangle strip) at its corners in the target, whose texels a tile spans u_tile
// of (the tile's side over the target's scale). The pass's scissor keeps it within its box.
layout(std430, binding = 5) readonly buffer Runs { uvec4 runs[]; };  // (x0, y, x1, -) tiles
uniform float u_tile;
uniform vec2 u_target;  // the target's size, texels

void main() {
    uvec4 run = runs[gl_InstanceID];
    vec2 p = vec2((gl_VertexID & 1) == 0 ? run.x : run.z, (gl_VertexID & 2) == 0 ? run.y : run.y + 1u) * u_tile;
    gl_Position = vec4(2.0 * p / u_target - 1.0, 0.0, 1.0);
}
